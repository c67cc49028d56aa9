//! Emulated EtherCAT slave controllers (ESCs) and the slave applications behind them.
//!
//! Status: the emulation itself is being built (issue "The slave simulator"); this crate
//! currently only reserves its place in the workspace.
