//! The core of the ecatd EtherCAT master.
//!
//! Layers, bottom up (see `docs/architecture.md`). The three lowest are crates of their own,
//! which the simulator uses without the master; they are re-exported here under their layer
//! names, so the master's code and its users write `master_core::wire::…` as before:
//! - [`wire`] (crate `ecat-wire`): the bytes on the wire — typed, zero-copy views and
//!   parse/emit representations for frames, datagrams, ESC registers, the SII and every
//!   mailbox protocol. No I/O.
//! - [`link`] (crate `ecat-link`): sending and receiving raw Ethernet frames — raw socket,
//!   in-process pair, pcap tap, fault injector.
//! - [`od`] (crate `ecat-od`): the CoE object dictionary and the SDO server answering mailbox
//!   requests against it — shared by the simulator's slaves and the master's own ETG.1510
//!   dictionary.
//!
//! This crate's own layers:
//! - [`bus`]: the one thread that owns the link — packs datagrams from every caller into
//!   frames, matches replies, retries lost frames, checks working counters, runs the cyclic
//!   frame.
//! - [`master`]: bring-up, slave addressing, AL states, topology watch, events.
//! - [`mailbox`]: one owner per slave mailbox, and the protocol clients on top.
//! - [`master_od`]: the master's own ETG.1510 object dictionary (mailbox address 0), served
//!   by the [`od`] SDO server from the master's live state.
//! - [`gateway`]: the ETG.8200 mailbox gateway — UDP in, slaves' mailboxes (through
//!   [`mailbox`]) or [`master_od`] out.

pub use ecat_link as link;
pub use ecat_od as od;
pub use ecat_wire as wire;

pub mod bus;
pub mod gateway;
mod log_limit;
pub mod mailbox;
pub mod master;
pub mod master_od;
