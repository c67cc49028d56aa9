//! How the master is to set distributed clocks up ([`DcSettings`]) and what it measured and
//! set per slave ([`DcSlave`]); the work itself is in `dc`. A leaf, so the configuration
//! and the shared context can hold them.

use std::time::Duration;

/// How the master sets distributed clocks up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DcSettings {
    /// Configure DC slaves at all (offsets, delays, the cyclic reference time). Default
    /// true.
    pub enabled: bool,
    /// Reference-time datagrams sent back to back at the scan, before any slave reaches
    /// SAFEOP, so that the clocks have converged when the cycle starts. Default 1000.
    pub static_drift_frames: u32,
    /// SYNC0 cycle for every DC slave with process data; `None`: no SYNC0. Default `None`.
    pub sync0_cycle: Option<Duration>,
    /// Shift of the first SYNC0 pulse from a multiple of the cycle. Default 0.
    pub sync0_shift: Duration,
    /// How far ahead of a slave's system time its first SYNC0 pulse is put. Default
    /// 100 ms (SOEM).
    pub sync0_start_delay: Duration,
}

impl Default for DcSettings {
    fn default() -> DcSettings {
        DcSettings {
            enabled: true,
            static_drift_frames: 1000,
            sync0_cycle: None,
            sync0_shift: Duration::ZERO,
            sync0_start_delay: Duration::from_millis(100),
        }
    }
}

/// What the master measured and set for one DC slave.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct DcSlave {
    /// Ring position.
    pub position: u16,
    /// Station address.
    pub station: u16,
    /// The reference clock (the first DC slave).
    pub reference: bool,
    /// Port receive times latched by the measurement (local time, ns).
    pub receive_times: [u32; 4],
    /// Local time of the processing unit when the measurement frame passed (0x0918).
    pub processing_unit_time: u64,
    /// Propagation delay from the reference clock, written to 0x0928 (ns).
    pub delay_ns: u32,
    /// System time offset written to 0x0920 (ns).
    pub offset: i64,
}
