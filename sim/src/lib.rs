//! Emulated EtherCAT slave controllers (ESCs) and the slave applications behind them.
//!
//! - [`esc`]: one emulated slave controller (registers, SyncManagers, FMMUs, SII, AL state
//!   machine, DL status, distributed clock).
//! - [`segment`]: slaves chained in a line or a ring (cable redundancy), processing whole
//!   frames.
//! - [`device`]: the application behind a slave's PDI (mailbox protocols, process data).
//! - [`topology`]: a segment described as data (TOML) and built into a [`segment::Segment`].
//! - [`link`]: [`link::InProcessLink`], a `ecat_link::Link` straight into a segment, and
//!   [`link::RingPort`], the two ports of a master wired to a ring.
//!
//! The simulator uses only `ecat_wire` (the codecs) from the master, never its logic,
//! so a mistake in the master cannot be mirrored by the simulator.

pub mod device;
pub mod esc;
/// Frame processing driven by arbitrary bytes, for the fuzz target `sim_segment`.
#[doc(hidden)]
pub mod fuzzing;
pub mod link;
pub mod segment;
pub mod topology;
