//! The core of the ecatd EtherCAT master.
//!
//! Layers, bottom up (see `docs/architecture.md`):
//! - [`wire`]: the bytes on the wire — typed, zero-copy views and parse/emit representations for
//!   frames, datagrams, ESC registers, the SII and every mailbox protocol. No I/O.
//! - [`link`]: sending and receiving raw Ethernet frames — raw socket, in-process pair, pcap
//!   tap, fault injector.
//!
//! The link, bus, slave, mailbox, gateway and object-dictionary layers build on `wire`.

pub mod link;
pub mod wire;
