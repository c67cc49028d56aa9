//! What a configured PDO assignment is: the PDOs (and, optionally, their mappings) each
//! process-data SyncManager of a slave is to carry, as the master keeps them until it
//! writes them (`pdo_config`). A leaf, so the shared context can hold them.

use super::layout::PdoEntryInfo;
use crate::master::access::address::SlaveAddress;
use crate::master::info::SlaveInfo;

/// One PDO to assign; with `entries`, its mapping is rewritten too.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct PdoMapping {
    /// PDO mapping object (0x1600.. for outputs, 0x1A00.. for inputs).
    pub index: u16,
    /// The entries to map, in order (`None`: keep the slave's mapping). Only
    /// `index`, `subindex` and `bit_length` are written.
    pub entries: Option<Vec<PdoEntryInfo>>,
}

/// The PDOs one process-data SyncManager is to carry (written to 0x1C10 + `sync_manager`).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct PdoAssignment {
    /// SyncManager number (2 for 0x1C12 outputs, 3 for 0x1C13 inputs).
    pub sync_manager: u8,
    /// The PDOs, in image order (empty: the SyncManager carries nothing).
    pub pdos: Vec<PdoMapping>,
}

/// The PDO configuration of one slave, as kept by the master.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct SlavePdoConfig {
    pub address: SlaveAddress,
    pub assignments: Vec<PdoAssignment>,
}

impl SlavePdoConfig {
    /// Whether this configuration names the slave of `info`.
    pub fn names(&self, info: &SlaveInfo) -> bool {
        match self.address {
            SlaveAddress::Position(p) => p == info.position,
            SlaveAddress::Station(s) => s == info.station,
            SlaveAddress::Alias(a) => a != 0 && a == info.alias,
        }
    }
}
