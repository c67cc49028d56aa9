//! The core of the ecatd EtherCAT master.
//!
//! Layers, bottom up (see `docs/architecture.md`):
//! - [`wire`]: the bytes on the wire — typed, zero-copy views and parse/emit representations for
//!   frames, datagrams, ESC registers, the SII and every mailbox protocol. No I/O.
//! - [`link`]: sending and receiving raw Ethernet frames — raw socket, in-process pair, pcap
//!   tap, fault injector.
//! - [`od`]: the CoE object dictionary and the SDO server answering mailbox requests against
//!   it — shared by the simulator's slaves and the master's own ETG.1510 dictionary.
//!
//! The bus, slave, mailbox and gateway layers build on these.

pub mod link;
pub mod od;
pub mod wire;
