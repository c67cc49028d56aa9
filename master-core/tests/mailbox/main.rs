//! Mailboxes: the engine and its poll strategies, CoE, FoE, SoE, EoE and VoE over a fake
//! segment, aborts, concurrency, one bus access per turn and release.

#[path = "../mailbox_support/mod.rs"]
mod mailbox_support;

mod aborts;
mod bus_once;
mod coe;
mod concurrency;
mod engine;
mod eoe_lost_reads;
mod eoe_turns;
mod eoe_voe;
mod foe;
mod poll_strategy;
mod release;
mod soe;
