//! The core of the ecatd EtherCAT master.
//!
//! Layers, bottom up (see `docs/architecture.md`):
//! - [`wire`]: the bytes on the wire — typed, zero-copy views and parse/emit representations for
//!   frames, datagrams, ESC registers, the SII and every mailbox protocol. No I/O.
//! - [`link`]: sending and receiving raw Ethernet frames — raw socket, in-process pair, pcap
//!   tap, fault injector.
//! - [`bus`]: the one thread that owns the link — packs datagrams from every caller into
//!   frames, matches replies, retries lost frames, checks working counters, runs the cyclic
//!   frame.
//! - [`od`]: the CoE object dictionary and the SDO server answering mailbox requests against
//!   it — shared by the simulator's slaves and the master's own ETG.1510 dictionary.
//!
//! - [`master`]: bring-up, slave addressing, AL states, topology watch, events.
//! - [`mailbox`]: one owner per slave mailbox, and the protocol clients on top.
//! - [`master_od`]: the master's own ETG.1510 object dictionary (mailbox address 0), served
//!   by the [`od`] SDO server from the master's live state.
//! - [`gateway`]: the ETG.8200 mailbox gateway — UDP in, slaves' mailboxes (through
//!   [`mailbox`]) or [`master_od`] out.

pub mod bus;
pub mod gateway;
pub mod link;
mod log_limit;
pub mod mailbox;
pub mod master;
pub mod master_od;
pub mod od;
pub mod wire;
