//! The simulator's topologies: the built-in default segment, digital I/O wiring, mailbox
//! start-up, SoE drives, ring wiring and the in-process default of `ecatd --simulate`.

#[path = "../segment_support/mod.rs"]
mod segment_support;

mod default;
mod dio_wiring;
mod inprocess_default;
mod mailbox_start;
mod ring;
mod soe;
