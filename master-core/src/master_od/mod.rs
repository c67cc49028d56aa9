//! The master's own object dictionary (ETG.1510 master diagnosis interface, spec-notes §master-od),
//! served at mailbox address 0 of the ETG.8200 gateway and usable locally.
//!
//! | objects | content |
//! |---|---|
//! | 0x1000, 0x1008, 0x1009, 0x100A, 0x1018 | the master's identity ([`MasterIdentity`]) |
//! | 0x8nnn | configuration of the slave at position n: station address, type, name, identity, mailbox sizes, link status and preset, flags, port physics, protocols |
//! | 0x9nnn | detected identity and DL status |
//! | 0xAnnn | AL status, AL control (writable: the master brings the slave to that state), last AL status code, link connection, neighbours, frame errors per port, not-present and abnormal-state counters |
//! | 0xF000 | modular device profile |
//! | 0xF002 | scan command: write `01 00` to :01, poll :02 (0 none, 1 done, 2 failed, 255 running), :03 = found (u16), failures (u16) |
//! | 0xF020.. / 0xF040.. | configured / detected station addresses (255 per object) |
//! | 0xF120 | lost cyclic and acyclic frames, frames per second, master state |
//! | 0xF200 | :10 write TRUE: reset the diagnosis counters |
//!
//! Every object has SDO Information, records answer complete access, strings longer than
//! the mailbox are segmented — all by [`crate::od::SdoServer`], the server the simulated
//! slaves use. Files: `identity`, `slaves` (0x8nnn-0xAnnn), `device` (0xFxxx),
//! `snapshot` (what the values come from), `dictionary` (building it, write hooks),
//! `diagnosis` (counters kept from the master's events), `service` (the CoE server),
//! `text`.
//!
//! Values are live: each request takes a [`MasterSnapshot`] and builds the dictionary from
//! it. Values that cost a bus access are fetched only for the object a request names (the
//! ESC error counters for an upload of 0xAnnn, the SII order code for 0x8nnn); other
//! requests show the last counters read. A segmented upload sends the value as it was at
//! its initiate.

mod device;
mod diagnosis;
mod dictionary;
/// Request handling driven by arbitrary bytes, for the fuzz target `master_od`.
#[doc(hidden)]
pub mod fuzzing;
mod identity;
mod service;
mod slaves;
mod snapshot;
mod text;

pub use device::{
    CONFIGURED_ADDRESSES, DETECTED_ADDRESSES, DIAGNOSIS_CONTROL, MASTER_DIAGNOSIS,
    RESET_DIAGNOSIS_SUBINDEX, SCAN_COMMAND, SCAN_REQUEST,
};
pub use dictionary::Action;
pub use identity::{IDENTITY_TEXT_LEN, MasterIdentity};
pub use service::{MasterDictionary, Reply};
pub use slaves::{AL_CONTROL_SUBINDEX, CONFIGURATION, DIAGNOSIS, INFORMATION, SLAVE_TEXT_LEN};
pub use snapshot::{FrameRates, MasterSnapshot, ScanStatus, SlaveDiagnosis};
