//! The master as both APIs show it (`GetMaster`, `GET /api/v1/master`): link, MAC, cycle,
//! DC reference clock, frame counters, version, readiness and the ring (cable redundancy).

use serde::Serialize;
use utoipa::ToSchema;

use super::Core;

/// The master's state.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct MasterView {
    /// ecatd's version.
    pub version: String,
    /// The network interface, or `simulate`.
    pub link: String,
    /// The source MAC address of the master's frames.
    pub mac: String,
    /// The cyclic process-data period in ns; 0 without cyclic exchange.
    pub cycle_period_ns: u64,
    /// The first scan is done and ecatd is not shutting down (as `/readyz`).
    pub ready: bool,
    /// Slaves of the last scan.
    pub slave_count: u32,
    /// Ring position of the DC reference clock; absent without DC slaves.
    pub dc_reference: Option<u32>,
    /// The reference clock's system time at the last read (ns since 2000); 0 if unknown.
    pub dc_reference_time_ns: u64,
    /// Frames sent.
    pub frames_sent: u64,
    /// Frames received back.
    pub frames_received: u64,
    /// Frames that did not come back.
    pub frames_lost: u64,
    /// Send or receive errors of the link.
    pub link_errors: u64,
    /// Cable redundancy: the ring's state (`off` on one port; docs/redundancy.md).
    pub redundancy: super::view::RedundancyView,
}

impl Core {
    /// The master's state now.
    pub fn master_view(&self) -> MasterView {
        let master = self.master();
        let stats = master.bus().stats();
        let mac = master.bus().config().source_mac;
        let reference = master.dc_slaves().into_iter().find(|s| s.reference);
        MasterView {
            version: env!("CARGO_PKG_VERSION").to_owned(),
            link: self.link(),
            mac: mac
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect::<Vec<_>>()
                .join(":"),
            cycle_period_ns: u64::try_from(master.config().cycle_period.as_nanos())
                .unwrap_or(u64::MAX),
            ready: self.ready(),
            slave_count: u32::try_from(master.slaves().len()).unwrap_or(u32::MAX),
            dc_reference: reference.map(|s| u32::from(s.position)),
            dc_reference_time_ns: master.dc_reference_time().unwrap_or(0),
            frames_sent: stats.frames_sent,
            frames_received: stats.frames_received,
            frames_lost: stats.frames_lost,
            link_errors: stats.link_errors,
            redundancy: self.redundancy(),
        }
    }
}
