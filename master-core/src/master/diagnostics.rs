//! What the APIs and the master's own dictionary show of the segment's health, without
//! handing out the bus: each slave's ESC error counters (registers 0x0300–0x0313,
//! ETG.1000.4's data-link error counters) and the bus's own counters.

use crate::bus::BusStatsSnapshot;
use crate::wire::register::address::ERROR_COUNTERS;
use crate::wire::register::error_counters::ERROR_COUNTERS_LEN;
use crate::wire::register::{ErrorCounters, ErrorCountersRepr};

use super::{Master, MasterError, SlaveAddress};

impl Master {
    /// Reads the whole error counter block of the slave at `address` with one register
    /// read (the counters are 8-bit and saturate at 255).
    pub async fn error_counters(
        &self,
        address: SlaveAddress,
    ) -> Result<ErrorCountersRepr, MasterError> {
        let bytes = self
            .read_register(address, ERROR_COUNTERS, ERROR_COUNTERS_LEN)
            .await?;
        ErrorCounters::new_checked(&bytes[..])
            .and_then(|view| ErrorCountersRepr::parse(&view))
            .map_err(|source| MasterError::Malformed {
                position: self.slave(address).map_or(0, |s| s.position),
                what: "error counters",
                source,
            })
    }

    /// Clears the error counters of the slave at `address`: a write to a counter clears
    /// it, so the whole block is written with zeros.
    pub async fn clear_error_counters(&self, address: SlaveAddress) -> Result<(), MasterError> {
        self.write_register(address, ERROR_COUNTERS, &[0; ERROR_COUNTERS_LEN])
            .await
    }

    /// The bus's counters (frames, datagrams, cycles, round trips) since it started.
    pub fn bus_stats(&self) -> BusStatsSnapshot {
        self.bus().stats()
    }
}
