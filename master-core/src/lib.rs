//! The core of the ecatd EtherCAT master.
//!
//! Layers, bottom up (see `docs/architecture.md`):
//! - [`wire`]: the bytes on the wire — typed, zero-copy views and parse/emit representations for
//!   frames, datagrams, ESC registers, the SII and every mailbox protocol. No I/O.
//!
//! The link, bus, slave, mailbox, gateway and object-dictionary layers build on `wire`.

pub mod wire;
