//! What the master's dictionary shows: a copy of the master's state taken when a request
//! arrives (the dictionary is built from it for that request, so every value is live).

use std::collections::HashMap;

use crate::master::SlaveInfo;
use crate::wire::register::ErrorCountersRepr;

/// Counters the master keeps per slave for the diagnosis objects (0xAnnn).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SlaveDiagnosis {
    /// Times the slave stopped answering (0xAnnn:0F).
    pub not_present: u32,
    /// State changes the master did not ask for, and AL errors (0xAnnn:10).
    pub abnormal_state_changes: u32,
}

/// Frames per second, as sampled over the last second (0xF120:03/04).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FrameRates {
    /// Cyclic frames per second.
    pub cyclic: u32,
    /// Acyclic frames per second.
    pub acyclic: u32,
}

/// The state of the last scan started through 0xF002.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ScanStatus {
    /// 0xF002:02: 0 none yet, 1 done, 2 failed, 255 running.
    pub status: u8,
    /// Slaves the last scan found.
    pub found: u16,
    /// Slaves of the last scan that did not reach their state.
    pub failures: u16,
}

impl ScanStatus {
    /// No scan was started through the dictionary.
    pub const IDLE: u8 = 0;
    /// The last scan finished.
    pub const DONE: u8 = 1;
    /// The last scan failed (the segment could not be counted or reset).
    pub const FAILED: u8 = 2;
    /// A scan is running.
    pub const RUNNING: u8 = 255;
}

/// Everything the dictionary's values come from.
#[derive(Debug, Clone, Default)]
pub struct MasterSnapshot {
    /// The slaves of the last scan, by position (object n is the slave at position n).
    pub slaves: Vec<SlaveInfo>,
    /// Order codes from the slaves' SII (0x8nnn:02), by position; missing ones are empty.
    pub order_codes: HashMap<u16, String>,
    /// ESC error counters read for this request (0xAnnn:0A-0D), by position.
    pub error_counters: HashMap<u16, ErrorCountersRepr>,
    /// Per-slave counters, by position.
    pub diagnosis: HashMap<u16, SlaveDiagnosis>,
    /// Cyclic frames lost (0xF120:01).
    pub cyclic_lost: u64,
    /// Acyclic frames lost (0xF120:02).
    pub acyclic_lost: u64,
    /// Frame rates.
    pub rates: FrameRates,
    /// The last scan started through 0xF002.
    pub scan: ScanStatus,
    /// Cyclic working-counter errors put down to each slave, by position (0xAnnn:0E, see
    /// [`Master::wkc_errors`](crate::master::Master::wkc_errors)).
    pub wkc_errors: Vec<u32>,
}
