//! ESC registers (spec-notes §esc.info, §al): addresses and typed views of the registers a master reads
//! and writes, and an emulated ESC provides.
//!
//! One file per register group: [`address`] names every address; [`info`] the information
//! block; [`dl`] data-link control/status; [`al`] and [`al_status_code`] the application
//! layer; [`eeprom`] the SII interface; [`sync_manager`] and [`fmmu`] the channel register
//! sets; [`dc`] distributed clocks; [`error_counters`] the 0x0300 block.

pub mod address;
pub mod al;
pub mod al_status_code;
pub mod dc;
pub mod dl;
pub mod eeprom;
pub mod error_counters;
pub mod fmmu;
pub mod info;
pub mod sync_manager;

pub use address::{fmmu as fmmu_address, sync_manager as sync_manager_address};
pub use al::{AlControl, AlState, AlStatus, AlStatusBlock, AlStatusBlockRepr};
pub use al_status_code::AlStatusCode;
pub use dl::{DlControl, DlStatus, LoopMode, PortStatus};
pub use eeprom::{EepromCommand, EepromControl, EepromRequest, EepromRequestRepr};
pub use error_counters::{ErrorCounters, ErrorCountersRepr};
pub use fmmu::{Fmmu, FmmuRepr};
pub use info::{EscFeatures, EscInfo, EscInfoRepr, PortType};
pub use sync_manager::{
    SmActivate, SmControl, SmDirection, SmMode, SmPdiControl, SmStatus, SyncManager,
    SyncManagerRepr,
};
