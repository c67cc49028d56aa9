//! The core of the ecatd EtherCAT master.
//!
//! Layers, bottom up (see `docs/architecture.md`):
//! - [`wire`]: the bytes on the wire — typed, zero-copy views and parse/emit representations for
//!   frames, datagrams, ESC registers, the SII and every mailbox protocol. No I/O.
//! - [`link`]: sending and receiving raw Ethernet frames — raw socket, in-process pair, pcap
//!   tap, fault injector.
//! - [`bus`]: the datagram loop — one thread owns the link, packs datagrams from all callers
//!   into frames, matches replies, retries lost frames, checks working counters and runs the
//!   cyclic exchange; callers await or block on the results.
//!
//! The link, bus, slave, mailbox, gateway and object-dictionary layers build on `wire`.

pub mod bus;
pub mod link;
pub mod wire;
