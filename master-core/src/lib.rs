//! The core of the ecatd EtherCAT master.
//!
//! Layers, bottom up (see `docs/architecture.md`):
//! - [`wire`]: the bytes on the wire — typed, zero-copy views and parse/emit representations for
//!   frames, datagrams, ESC registers, the SII and every mailbox protocol. No I/O.
//! - [`od`]: the CoE object dictionary and the SDO server answering mailbox requests against
//!   it — shared by the simulator's slaves and the master's own ETG.1510 dictionary.
//!
//! The link, bus, slave, mailbox and gateway layers build on `wire`.

pub mod od;
pub mod wire;
