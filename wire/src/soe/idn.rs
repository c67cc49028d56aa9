//! IDNs: the identification numbers of SoE parameters.

use core::fmt;
use core::str::FromStr;

use crate::error::{Result, WireError};

/// An IDN (identification number, spec-notes §soe): bit 15 S/P, bits 12-14 parameter set,
/// bits 0-11 data block number. Printed `S-0-0024` / `P-0-0001`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Idn(u16);

impl Idn {
    const PRODUCT: u16 = 0x8000;
    const SET_SHIFT: u32 = 12;
    const SET_MASK: u16 = 0x7;
    const BLOCK_MASK: u16 = 0x0FFF;

    /// Builds an IDN; refuses a parameter set above 7 or a block number above 4095.
    pub fn new(product: bool, parameter_set: u8, block: u16) -> Result<Self> {
        if u16::from(parameter_set) > Self::SET_MASK || block > Self::BLOCK_MASK {
            return Err(WireError::Invalid {
                what: "IDN",
                reason: "parameter set above 7 or block number above 4095",
            });
        }
        let product = if product { Self::PRODUCT } else { 0 };
        Ok(Idn(product
            | (u16::from(parameter_set) << Self::SET_SHIFT)
            | block))
    }

    /// The IDN with the given raw u16 (every value is a valid IDN).
    pub const fn from_raw(raw: u16) -> Self {
        Idn(raw)
    }

    /// The raw u16.
    pub const fn raw(self) -> u16 {
        self.0
    }

    /// Whether this is a product-specific (P) parameter rather than a standard (S) one.
    pub const fn is_product(self) -> bool {
        self.0 & Self::PRODUCT != 0
    }

    /// Parameter set, 0..=7.
    pub const fn parameter_set(self) -> u8 {
        ((self.0 >> Self::SET_SHIFT) & Self::SET_MASK) as u8
    }

    /// Data block number, 0..=4095.
    pub const fn block(self) -> u16 {
        self.0 & Self::BLOCK_MASK
    }
}

impl From<u16> for Idn {
    fn from(raw: u16) -> Self {
        Idn(raw)
    }
}

impl From<Idn> for u16 {
    fn from(idn: Idn) -> Self {
        idn.0
    }
}

impl fmt::Display for Idn {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = if self.is_product() { 'P' } else { 'S' };
        write!(f, "{kind}-{}-{:04}", self.parameter_set(), self.block())
    }
}

impl FromStr for Idn {
    type Err = WireError;

    /// Parses `S-0-0024` / `P-0-1` (case-insensitive letter, block with or without padding).
    fn from_str(s: &str) -> Result<Self> {
        const BAD: WireError = WireError::Invalid {
            what: "IDN",
            reason: "expected S-<set>-<block> or P-<set>-<block>",
        };
        let mut parts = s.split('-');
        let (Some(kind), Some(set), Some(block), None) =
            (parts.next(), parts.next(), parts.next(), parts.next())
        else {
            return Err(BAD);
        };
        let product = match kind {
            "S" | "s" => false,
            "P" | "p" => true,
            _ => return Err(BAD),
        };
        let digits = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit());
        if !digits(set) || !digits(block) {
            return Err(BAD);
        }
        let set: u8 = set.parse().map_err(|_| BAD)?;
        let block: u16 = block.parse().map_err(|_| BAD)?;
        Idn::new(product, set, block)
    }
}
