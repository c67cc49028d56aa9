//! The simulator's mailbox layer and its CoE, FoE, SoE and EoE devices.

#[path = "../mailbox_support/mod.rs"]
mod mailbox_support;

mod eoe;
mod foe;
mod layer;
mod soe;
