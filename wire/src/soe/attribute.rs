//! The attribute element of an IDN: data type, length, scaling, decimals.

use crate::error::{Result, WireError};
use crate::macros::enum_with_unknown;

enum_with_unknown! {
    /// Data type of an IDN (attribute bits 20-22, ETG.1000.6, spec-notes §soe).
    pub enum SoeDataType(u8) {
        /// Binary.
        Binary = 0,
        /// Unsigned integer.
        Unsigned = 1,
        /// Signed integer.
        Signed = 2,
        /// Hexadecimal.
        Hex = 3,
        /// Text.
        String = 4,
        /// IDN.
        Idn = 5,
        /// Floating point.
        Float = 6,
        /// Parameter.
        Parameter = 7,
    }
}

/// The attribute element of an IDN (u32, ETG.1000.6, spec-notes §soe), decoded.
///
/// Data length follows SOEM's split of bits 16-18: bits 16-17 give the (element) size
/// 0 → 1, 1 → 2, 2 → 4, 3 → 8 bytes and bit 18 marks a variable-length list of such
/// elements. Reserved bits 23 and 31 are dropped on decode and written 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SoeAttribute {
    /// Conversion (evaluation) factor, bits 0-15.
    pub conversion_factor: u16,
    /// Size in bytes of the value, or of each list element: 1, 2, 4 or 8 (bits 16-17).
    pub element_size: u8,
    /// Variable-length list (bit 18).
    pub list: bool,
    /// The IDN is a procedure command (bit 19).
    pub procedure_command: bool,
    /// Data type (bits 20-22).
    pub data_type: SoeDataType,
    /// Decimal places, 0..=15 (bits 24-27).
    pub decimal_places: u8,
    /// Write-protected in PREOP (bit 28).
    pub write_protected_preop: bool,
    /// Write-protected in SAFEOP (bit 29).
    pub write_protected_safeop: bool,
    /// Write-protected in OP (bit 30).
    pub write_protected_op: bool,
}

impl SoeAttribute {
    /// Decodes an attribute value.
    pub fn from_u32(raw: u32) -> Self {
        let bit = |n: u32| raw & (1 << n) != 0;
        SoeAttribute {
            conversion_factor: (raw & 0xFFFF) as u16,
            element_size: 1 << ((raw >> 16) & 0x3),
            list: bit(18),
            procedure_command: bit(19),
            data_type: SoeDataType::from(((raw >> 20) & 0x7) as u8),
            decimal_places: ((raw >> 24) & 0xF) as u8,
            write_protected_preop: bit(28),
            write_protected_safeop: bit(29),
            write_protected_op: bit(30),
        }
    }

    /// Encodes the attribute; refuses an element size other than 1/2/4/8, a data type above
    /// 7 or more than 15 decimal places.
    pub fn to_u32(&self) -> Result<u32> {
        let size_code = match self.element_size {
            1 => 0u32,
            2 => 1,
            4 => 2,
            8 => 3,
            _ => {
                return Err(WireError::Invalid {
                    what: "SoE attribute",
                    reason: "element size must be 1, 2, 4 or 8",
                });
            }
        };
        let data_type = u8::from(self.data_type);
        if data_type > 7 || self.decimal_places > 15 {
            return Err(WireError::Invalid {
                what: "SoE attribute",
                reason: "data type above 7 or decimal places above 15",
            });
        }
        let flag = |b: bool, n: u32| if b { 1u32 << n } else { 0 };
        Ok(u32::from(self.conversion_factor)
            | (size_code << 16)
            | flag(self.list, 18)
            | flag(self.procedure_command, 19)
            | (u32::from(data_type) << 20)
            | (u32::from(self.decimal_places) << 24)
            | flag(self.write_protected_preop, 28)
            | flag(self.write_protected_safeop, 29)
            | flag(self.write_protected_op, 30))
    }
}
