//! A snapshot of what the master knows about one slave, for the mailbox engine, the server
//! and tools.

use crate::mailbox::SlaveMailboxConfig;
use crate::wire::register::{AlState, AlStatusCode, DlStatus, EscInfoRepr};

/// Vendor, product, revision and serial number (SII words 0x08–0x0F); the same type as
/// [`od::Identity`](crate::od::Identity).
pub use crate::wire::identity::Identity;

/// A slave's share of the process image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ProcessDataInfo {
    /// Output bytes (master → slave).
    pub outputs: u16,
    /// Input bytes (slave → master).
    pub inputs: u16,
    /// Offset of the outputs in the process image (and logical address).
    pub outputs_offset: u32,
    /// Offset of the inputs in the process image (and logical address).
    pub inputs_offset: u32,
}

/// One slave as the master knows it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SlaveInfo {
    /// Ring position.
    pub position: u16,
    /// Configured station address.
    pub station: u16,
    /// Configured station alias (register 0x0012; 0 = none).
    pub alias: u16,
    /// Identity from the SII.
    pub identity: Identity,
    /// Device name from the SII (empty if it has none).
    pub name: String,
    /// The ESC's information block (type, revision, FMMUs, SyncManagers, RAM, features).
    pub esc: EscInfoRepr,
    /// Standard mailbox, if the slave has one.
    pub mailbox: Option<SlaveMailboxConfig>,
    /// Bootstrap mailbox, if the slave announces one.
    pub boot_mailbox: Option<SlaveMailboxConfig>,
    /// DL status at the last look (port links, loops, communication).
    pub dl_status: DlStatus,
    /// Current AL state at the last look.
    pub al_state: AlState,
    /// AL status error indication at the last look.
    pub al_error: bool,
    /// AL status code at the last look.
    pub al_status_code: AlStatusCode,
    /// The state the master keeps this slave in.
    pub requested_state: AlState,
    /// Process-data sizes and place in the image.
    pub process_data: ProcessDataInfo,
    /// Whether the slave answered at the last look.
    pub present: bool,
    /// CoE object 0x1000 (device type), read once in PREOP during the scan; 0 for slaves
    /// without CoE or whose read failed.
    pub device_type: u32,
}

impl SlaveInfo {
    /// Number of active ports (1 = end of line, 2 = line, 3-4 = branch).
    pub fn active_ports(&self) -> u8 {
        self.dl_status.active_ports()
    }
}
