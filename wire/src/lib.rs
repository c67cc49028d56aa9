//! Bytes on the wire: every EtherCAT structure ecatd sends or receives, and nothing else.
//!
//! # The contract (after smoltcp's `wire`)
//!
//! Each structure comes in two levels:
//!
//! - A **view** `Thing<T: AsRef<[u8]>>` over a byte buffer, with field accessors (and setters
//!   when `T: AsMut<[u8]>`). `new_unchecked` wraps without checks; `check_len` validates the
//!   fixed part *and every declared length* against the buffer; `new_checked` does both.
//!   After a successful `check_len`, no accessor can panic. Untrusted input (anything from
//!   the network, a slave, or a file) is only ever read through `new_checked`.
//! - A **representation** `ThingRepr` (plain data, possibly borrowing payload slices) with
//!   `parse(&view) -> Result<Repr>`, `buffer_len(&self) -> usize`, and
//!   `emit(&self, &mut view) -> Result<()>`. Emit into a buffer of `buffer_len()` bytes always
//!   succeeds for a representation that came out of `parse`; out-of-range field values are
//!   refused with an error, never silently truncated. Every representation also implements
//!   [`Emit`] (`to_vec()`, `emit_into(&mut [u8])`), so a caller that wants bytes does not
//!   allocate, wrap and emit by hand.
//!
//! Field offsets live in a private `mod fields` table per structure, never as magic numbers
//! in accessor bodies. Code points (commands, mailbox types, AL status codes, abort codes,
//! opcodes) are open enums with an `Unknown(raw)` variant: an unknown value is data, not a
//! parse error. Everything is little-endian except the Ethernet header.
//!
//! Every type a person might see in a log implements `Display` with a one-line summary in the
//! vocabulary of the standard (and of Wireshark's EtherCAT dissectors).
//!
//! Errors are [`WireError`]: typed, naming the structure, never a panic — any byte string
//! fed to any parser returns `Ok` or an error (checked by proptest and the fuzz targets).

pub mod emit;
pub mod error;
pub mod field;
pub(crate) mod macros;

pub mod command;
pub mod datagram;
pub mod ethernet;
pub mod frame;
pub mod identity;

pub mod register;
pub mod sii;

pub mod coe;
pub mod eoe;
pub mod foe;
pub mod gateway;
pub mod mailbox;
pub mod soe;
pub mod voe;

pub use emit::Emit;
pub use error::{Result, WireError};
