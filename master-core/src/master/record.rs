//! What the master keeps of one slave. A leaf: it depends on the public slave types only,
//! so bring-up, process data and the shared context can all use it without importing each other.

use crate::master::info::{Identity, ProcessDataInfo, SlaveInfo};
use crate::master::process_data::layout::ProcessDataLayout;
use crate::wire::register::{AlState, AlStatusCode, DlStatus, EscInfoRepr};

/// One slave: the snapshot callers see, its SII image and its process-data layout.
#[derive(Debug, Clone)]
pub(crate) struct SlaveRecord {
    pub info: SlaveInfo,
    pub sii: Vec<u8>,
    pub layout: ProcessDataLayout,
    /// Whether the configured PDO assignment was written since the slave was identified
    /// (a power cycle restores the slave's own).
    pub pdo_written: bool,
    /// A start-up command failed since the slave was identified: the watch does not retry
    /// the bring-up at every look (a power cycle or a new scan does).
    pub held: bool,
}

impl SlaveRecord {
    /// A slave that answered the scan but could not be identified (its SII unreadable):
    /// kept in its place, with no SII, for the watch to try again.
    pub fn unidentified(position: u16, station: u16, requested_state: AlState) -> SlaveRecord {
        SlaveRecord {
            info: SlaveInfo {
                position,
                station,
                alias: 0,
                identity: Identity::default(),
                name: String::new(),
                esc: EscInfoRepr::default(),
                mailbox: None,
                boot_mailbox: None,
                dl_status: DlStatus::default(),
                al_state: AlState::Init,
                al_error: false,
                al_status_code: AlStatusCode::NoError,
                requested_state,
                process_data: ProcessDataInfo::default(),
                present: false,
                device_type: 0,
            },
            sii: Vec::new(),
            layout: ProcessDataLayout::default(),
            pdo_written: false,
            held: false,
        }
    }
}

/// The slaves of the last scan, by ring position.
#[derive(Debug, Default)]
pub(crate) struct Slaves {
    pub list: Vec<SlaveRecord>,
}
