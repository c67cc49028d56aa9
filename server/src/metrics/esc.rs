//! Each slave's ESC error counters (registers 0x0300-0x0313, spec-notes §esc.errors), read from the bus
//! by a background task with one FPRD of the whole 20-byte block per slave at a modest
//! period, never on a scrape; the scrape shows the last values read.
//!
//! The counters are 8-bit, saturate at 255 and are cleared by a write, so they are exported
//! as gauges.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError, Weak};
use std::time::Duration;

use master_core::master::{Master, SlaveAddress};
use master_core::wire::register::ErrorCountersRepr;
use prometheus::proto::{MetricFamily, MetricType};
use tokio::task::JoinHandle;

use super::family::Family;

/// How often the counters are read.
pub const PERIOD: Duration = Duration::from_secs(1);

/// The ESC's ports.
const PORTS: usize = 4;

#[derive(Debug, Default)]
struct Inner {
    /// The last block read, by station address.
    last: BTreeMap<u16, ErrorCountersRepr>,
    /// Reads that failed (the last values stay).
    failed_reads: u64,
}

/// The last error counters read from every slave.
#[derive(Debug, Default)]
pub struct EscCounters {
    inner: Mutex<Inner>,
}

impl EscCounters {
    fn lock(&self) -> MutexGuard<'_, Inner> {
        // Updates replace whole entries: a poisoned lock still holds valid values.
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Starts reading the counters of every slave of `master` every [`PERIOD`]; the task
    /// ends when the handle is aborted or the master is gone.
    pub fn start(self: &Arc<Self>, master: &Arc<Master>) -> JoinHandle<()> {
        let store = Arc::clone(self);
        let master = Arc::downgrade(master);
        tokio::spawn(async move {
            let mut tick = tokio::time::interval(PERIOD);
            tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
            loop {
                tick.tick().await;
                if !store.read_all(&master).await {
                    return;
                }
            }
        })
    }

    /// One round over the slaves; false once the master is gone.
    async fn read_all(&self, master: &Weak<Master>) -> bool {
        let Some(slaves) = master.upgrade().map(|m| m.slaves()) else {
            return false;
        };
        let stations: Vec<u16> = slaves.iter().map(|s| s.station).collect();
        for slave in slaves {
            let Some(m) = master.upgrade() else {
                return false;
            };
            let read = m.error_counters(SlaveAddress::Station(slave.station)).await;
            drop(m);
            let mut inner = self.lock();
            match read {
                Ok(counters) => {
                    inner.last.insert(slave.station, counters);
                }
                Err(_) => inner.failed_reads += 1,
            }
        }
        // Slaves gone since the last scan drop out.
        self.lock()
            .last
            .retain(|station, _| stations.contains(station));
        true
    }

    /// The families.
    pub fn collect(&self) -> Vec<Option<MetricFamily>> {
        let (last, failed) = {
            let inner = self.lock();
            (inner.last.clone(), inner.failed_reads)
        };
        type PerPort = fn(&ErrorCountersRepr) -> [u8; PORTS];
        type PerSlave = fn(&ErrorCountersRepr) -> u8;
        let per_port: [(&str, &str, PerPort); 4] = [
            (
                "ecat_slave_esc_invalid_frames",
                "ESC invalid frame (CRC) counter per port, registers 0x0300 + 2n.",
                |c| c.invalid_frame,
            ),
            (
                "ecat_slave_esc_rx_errors",
                "ESC RX error (PHY) counter per port, registers 0x0301 + 2n.",
                |c| c.rx_error,
            ),
            (
                "ecat_slave_esc_forwarded_rx_errors",
                "ESC forwarded RX error counter per port, registers 0x0308 + n.",
                |c| c.forwarded_rx_error,
            ),
            (
                "ecat_slave_esc_lost_links",
                "ESC lost link counter per port, registers 0x0310 + n.",
                |c| c.lost_link,
            ),
        ];
        let per_slave: [(&str, &str, PerSlave); 2] = [
            (
                "ecat_slave_esc_processing_unit_errors",
                "ESC EtherCAT processing unit error counter, register 0x030C.",
                |c| c.processing_unit,
            ),
            (
                "ecat_slave_esc_pdi_errors",
                "ESC PDI error counter, register 0x030D.",
                |c| c.pdi,
            ),
        ];
        let mut out = Vec::new();
        for (name, help, field) in per_port {
            let mut family = Family::new(name, help, MetricType::GAUGE);
            for (station, read) in &last {
                let values = field(read);
                for (port, value) in values.iter().enumerate() {
                    let (station, port_label) = (station.to_string(), port.to_string());
                    family = family.gauge(
                        &[("station", &station), ("port", &port_label)],
                        f64::from(*value),
                    );
                }
            }
            out.push(family.done());
        }
        for (name, help, field) in per_slave {
            let mut family = Family::new(name, help, MetricType::GAUGE);
            for (station, read) in &last {
                family = family.gauge(&[("station", &station.to_string())], f64::from(field(read)));
            }
            out.push(family.done());
        }
        out.push(
            Family::new(
                "ecat_slave_esc_read_failures_total",
                "Reads of the ESC error counters that failed (the last values stay).",
                MetricType::COUNTER,
            )
            .counter(&[], failed as f64)
            .done(),
        );
        out
    }
}
