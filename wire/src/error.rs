//! The one error type of the wire layer.

use thiserror::Error;

/// Why a byte string could not be read as (or written into) a wire structure.
///
/// Every parser in [`crate`] returns this instead of panicking, whatever the input.
/// Each variant names the structure (`what`) so that a log line says where decoding stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum WireError {
    /// The buffer is shorter than the fixed part of the structure.
    #[error("{what}: truncated, {have} bytes present but at least {need} needed")]
    Truncated {
        /// The structure being read.
        what: &'static str,
        /// Bytes needed.
        need: usize,
        /// Bytes present.
        have: usize,
    },
    /// A length field inside the structure disagrees with the bytes that are present, or
    /// exceeds what the protocol allows.
    #[error("{what}: declared length {declared} but only {available} allowed or present")]
    BadLength {
        /// The structure being read.
        what: &'static str,
        /// The length the structure declares.
        declared: usize,
        /// The length that is actually available or allowed.
        available: usize,
    },
    /// Bits that the standard reserves (must be zero) are set.
    #[error("{what}: reserved bits set ({value:#x})")]
    ReservedBits {
        /// The structure being read.
        what: &'static str,
        /// The offending bits.
        value: u32,
    },
    /// A type or code field holds a value this parser cannot interpret structurally (for
    /// example a mailbox type whose payload layout is unknown where a layout is required).
    #[error("{what}: unknown type {value:#x}")]
    UnknownType {
        /// The structure being read.
        what: &'static str,
        /// The value found.
        value: u32,
    },
    /// The fields are individually well-formed but contradict each other or the standard.
    #[error("{what}: {reason}")]
    Invalid {
        /// The structure being read.
        what: &'static str,
        /// What is wrong, in words.
        reason: &'static str,
    },
    /// An emit target buffer is too small for the representation.
    #[error("{what}: output buffer of {have} bytes is too small, {need} needed")]
    BufferTooSmall {
        /// The structure being written.
        what: &'static str,
        /// Bytes needed.
        need: usize,
        /// Bytes available.
        have: usize,
    },
}

/// The result type of the wire layer.
pub type Result<T> = core::result::Result<T, WireError>;

/// Checks that `buf` holds at least `need` bytes.
pub(crate) fn need(what: &'static str, buf: &[u8], need: usize) -> Result<()> {
    if buf.len() < need {
        Err(WireError::Truncated {
            what,
            need,
            have: buf.len(),
        })
    } else {
        Ok(())
    }
}

/// Checks that an emit target holds at least `need` bytes.
pub(crate) fn room(what: &'static str, buf: &[u8], need: usize) -> Result<()> {
    if buf.len() < need {
        Err(WireError::BufferTooSmall {
            what,
            need,
            have: buf.len(),
        })
    } else {
        Ok(())
    }
}
