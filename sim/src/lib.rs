//! Emulated EtherCAT slave controllers (ESCs) and the slave applications behind them.
//!
//! - [`device`]: the application behind a slave's PDI (mailbox protocols, process data).
//!
//! The simulator uses only `master_core::wire` (the codecs) from the master, never its logic,
//! so a mistake in the master cannot be mirrored by the simulator.

pub mod device;
