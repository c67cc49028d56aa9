//! SoE — servo drive profile over EtherCAT (mailbox type 5, ETG.1000.6, spec-notes §soe).
//!
//! ```text
//! byte 0  bits 0-2 opcode, bit 3 incomplete, bit 4 error, bits 5-7 drive number
//! byte 1  element flags (data state, name, attribute, unit, min, max, value, default)
//! 2..4    u16  IDN (incomplete = 0) or fragments left (incomplete = 1)
//! 4..     element data; with the error bit, a u16 error code (see [`SoeRepr`])
//! ```
//!
//! The view covers the mailbox *data* (after the 6-byte mailbox header).
//!
//! - this file: the header's layout, [`SoeOpcode`] and [`ElementFlags`];
//! - `packet`: the message view [`SoePacket`] and [`SoeRepr`];
//! - `idn`: [`Idn`]; `error`: [`SoeError`]; `attribute`: [`SoeAttribute`];
//! - `fragment`: splitting a value into fragments ([`fragments`]).

mod attribute;
mod error;
mod fragment;
mod idn;
mod packet;
#[cfg(test)]
mod tests;

pub use attribute::{SoeAttribute, SoeDataType};
pub use error::SoeError;
pub use fragment::{SoeFragment, SoeFragments, fragments};
pub use idn::Idn;
pub use packet::{IdnOrFragments, SoePacket, SoeRepr};

use core::fmt;

use crate::field::{Field, Rest};
use crate::macros::enum_with_unknown;

mod fields {
    use super::{Field, Rest};
    pub const FLAGS: usize = 0;
    pub const ELEMENTS: usize = 1;
    pub const IDN_OR_FRAGMENTS: Field = 2..4;
    pub const PAYLOAD: Rest = 4..;

    pub const OPCODE_MASK: u8 = 0x07;
    pub const INCOMPLETE: u8 = 0x08;
    pub const ERROR: u8 = 0x10;
    pub const DRIVE_SHIFT: u32 = 5;
}

/// Size of the SoE header in bytes.
pub const HEADER_LEN: usize = fields::PAYLOAD.start;

/// Size of the error code that follows the header when the error bit is set.
pub const ERROR_CODE_LEN: usize = 2;

/// Element data per fragment for a receiver mailbox of `mailbox_size` bytes: `M − 6 − 4`
/// (ETG.1000.6, spec-notes §soe). 0 if the mailbox is too small.
pub const fn fragment_capacity(mailbox_size: usize) -> usize {
    mailbox_size.saturating_sub(crate::mailbox::HEADER_LEN + HEADER_LEN)
}

enum_with_unknown! {
    /// SoE opcode (ETG.1000.6, spec-notes §soe, 3 bits).
    pub enum SoeOpcode(u8) {
        /// Read request.
        ReadRequest = 1,
        /// Read response.
        ReadResponse = 2,
        /// Write request.
        WriteRequest = 3,
        /// Write response.
        WriteResponse = 4,
        /// Notification (slave-initiated).
        Notification = 5,
        /// Slave info / emergency (slave-initiated).
        SlaveInfo = 6,
    }
}

impl SoeOpcode {
    /// Short name for logs.
    pub fn name(self) -> &'static str {
        match self {
            SoeOpcode::ReadRequest => "read req",
            SoeOpcode::ReadResponse => "read resp",
            SoeOpcode::WriteRequest => "write req",
            SoeOpcode::WriteResponse => "write resp",
            SoeOpcode::Notification => "notification",
            SoeOpcode::SlaveInfo => "slave info",
            SoeOpcode::Unknown(_) => "opcode",
        }
    }
}

/// The element flags of byte 1: which elements of an IDN are requested or contained
/// (ETG.1000.6, spec-notes §soe). All 8 bits are defined, so every byte is a valid set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ElementFlags(u8);

impl ElementFlags {
    /// Data state (u16).
    pub const DATA_STATE: ElementFlags = ElementFlags(0x01);
    /// Name (list format).
    pub const NAME: ElementFlags = ElementFlags(0x02);
    /// Attribute (u32, see [`SoeAttribute`]).
    pub const ATTRIBUTE: ElementFlags = ElementFlags(0x04);
    /// Unit (list format).
    pub const UNIT: ElementFlags = ElementFlags(0x08);
    /// Minimum input value.
    pub const MINIMUM: ElementFlags = ElementFlags(0x10);
    /// Maximum input value.
    pub const MAXIMUM: ElementFlags = ElementFlags(0x20);
    /// Value (operation data) — what masters normally request.
    pub const VALUE: ElementFlags = ElementFlags(0x40);
    /// Default value (Wireshark calls bit 7 reserved).
    pub const DEFAULT: ElementFlags = ElementFlags(0x80);

    const NAMES: [(ElementFlags, &'static str); 8] = [
        (Self::DATA_STATE, "datastate"),
        (Self::NAME, "name"),
        (Self::ATTRIBUTE, "attribute"),
        (Self::UNIT, "unit"),
        (Self::MINIMUM, "min"),
        (Self::MAXIMUM, "max"),
        (Self::VALUE, "value"),
        (Self::DEFAULT, "default"),
    ];

    /// The empty set.
    pub const fn empty() -> Self {
        ElementFlags(0)
    }

    /// The set with the given raw bits.
    pub const fn from_bits(bits: u8) -> Self {
        ElementFlags(bits)
    }

    /// The raw bits.
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// Whether every flag of `other` is set in `self`.
    pub const fn contains(self, other: ElementFlags) -> bool {
        self.0 & other.0 == other.0
    }

    /// Whether no flag is set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// The union of two sets.
    pub const fn union(self, other: ElementFlags) -> Self {
        ElementFlags(self.0 | other.0)
    }
}

impl core::ops::BitOr for ElementFlags {
    type Output = ElementFlags;
    fn bitor(self, rhs: ElementFlags) -> ElementFlags {
        self.union(rhs)
    }
}

impl fmt::Display for ElementFlags {
    /// The set flags joined by `+` in bit order (`value`, `name+attribute`), or `none`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_empty() {
            return f.write_str("none");
        }
        let mut first = true;
        for (flag, name) in Self::NAMES {
            if self.contains(flag) {
                if !first {
                    f.write_str("+")?;
                }
                f.write_str(name)?;
                first = false;
            }
        }
        Ok(())
    }
}
