//! A simulated segment described as data: which slaves, in which order, with which identity,
//! mailbox, protocols, PDOs and objects. Read from TOML ([`Topology::from_toml`]) or taken
//! from the built-in [`Topology::default_segment`] (also in `sim/topologies/default.toml`),
//! and turned into a running [`crate::segment::Segment`] by [`build`].
//!
//! One description feeds every view a master has of a slave, so they cannot disagree: the
//! SII image (identity, mailbox areas, protocol bits, GENERAL, FMMU, SYNCM, TXPDO/RXPDO),
//! the CoE dictionary (0x1018, 0x1C00, 0x16xx/0x1Axx, 0x1C12/0x1C13) and the process data
//! the device exchanges.

mod build;
mod default;
pub mod diag_history;
mod dictionary;
mod model;
mod sii;
mod soe;

pub use build::{BuildError, Built, SlaveHandles, build, build_with_handles};
pub use default::SIM_VENDOR_ID;
pub use model::{
    Application, CoeObject, EoeSpec, EscSpec, FoeBusySpec, FoeFileSpec, IdnSpec, MailboxSpec,
    PdoEntrySpec, PdoSpec, Protocol, SlaveSpec, Topology,
};
