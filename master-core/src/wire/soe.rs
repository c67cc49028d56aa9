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

use core::fmt;
use core::ops::Range;
use core::str::FromStr;

use crate::wire::error::{Result, WireError, need, room};
use crate::wire::field::{self, Field, Rest};
use crate::wire::macros::enum_with_unknown;

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
    mailbox_size.saturating_sub(crate::wire::mailbox::HEADER_LEN + HEADER_LEN)
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

enum_with_unknown! {
    /// SoE error code (ETG.1000.6, spec-notes §soe, IgH's table).
    pub enum SoeError(u16) {
        /// No error.
        NoError = 0x0000,
        /// No IDN.
        NoIdn = 0x1001,
        /// Invalid access to element 1.
        InvalidAccessElement1 = 0x1009,
        /// No name.
        NoName = 0x2001,
        /// Name transmission too short.
        NameTooShort = 0x2002,
        /// Name transmission too long.
        NameTooLong = 0x2003,
        /// Name cannot be changed (read only).
        NameReadOnly = 0x2004,
        /// Name is write-protected at this time.
        NameWriteProtected = 0x2005,
        /// Attribute transmission too short.
        AttributeTooShort = 0x3002,
        /// Attribute transmission too long.
        AttributeTooLong = 0x3003,
        /// Attribute cannot be changed (read only).
        AttributeReadOnly = 0x3004,
        /// Attribute is write-protected at this time.
        AttributeWriteProtected = 0x3005,
        /// No unit.
        NoUnit = 0x4001,
        /// Unit transmission too short.
        UnitTooShort = 0x4002,
        /// Unit transmission too long.
        UnitTooLong = 0x4003,
        /// Unit cannot be changed (read only).
        UnitReadOnly = 0x4004,
        /// Unit is write-protected at this time.
        UnitWriteProtected = 0x4005,
        /// No minimum input value.
        NoMinimum = 0x5001,
        /// Minimum input value transmission too short.
        MinimumTooShort = 0x5002,
        /// Minimum input value transmission too long.
        MinimumTooLong = 0x5003,
        /// Minimum input value cannot be changed (read only).
        MinimumReadOnly = 0x5004,
        /// Minimum input value is write-protected at this time.
        MinimumWriteProtected = 0x5005,
        /// No maximum input value.
        NoMaximum = 0x6001,
        /// Maximum input value transmission too short.
        MaximumTooShort = 0x6002,
        /// Maximum input value transmission too long.
        MaximumTooLong = 0x6003,
        /// Maximum input value cannot be changed (read only).
        MaximumReadOnly = 0x6004,
        /// Maximum input value is write-protected at this time.
        MaximumWriteProtected = 0x6005,
        /// Operation data transmission too short.
        DataTooShort = 0x7002,
        /// Operation data transmission too long.
        DataTooLong = 0x7003,
        /// Operation data cannot be changed (read only).
        DataReadOnly = 0x7004,
        /// Operation data is write-protected at this time (state).
        DataWriteProtected = 0x7005,
        /// Operation data is smaller than the minimum input value.
        DataBelowMinimum = 0x7006,
        /// Operation data is greater than the maximum input value.
        DataAboveMaximum = 0x7007,
        /// Invalid operation data (configured IDN not supported).
        InvalidData = 0x7008,
        /// Operation data write-protected by a password.
        DataPasswordProtected = 0x7009,
        /// Operation data write-protected (configured cyclically).
        DataCyclicallyConfigured = 0x700A,
        /// Invalid indirect addressing (data container, list handling).
        InvalidIndirectAddressing = 0x700B,
        /// Operation data write-protected due to other settings.
        DataProtectedBySettings = 0x700C,
        /// Reserved (0x700D).
        Reserved700D = 0x700D,
        /// Procedure command already active.
        ProcedureAlreadyActive = 0x7010,
        /// Procedure command not interruptible.
        ProcedureNotInterruptible = 0x7011,
        /// Procedure command not executable at this time (state).
        ProcedureNotExecutableNow = 0x7012,
        /// Procedure command not executable (invalid or false parameters).
        ProcedureInvalidParameters = 0x7013,
        /// No data state.
        NoDataState = 0x7014,
        /// No default value.
        NoDefault = 0x8001,
        /// Default value transmission too long.
        DefaultTooLong = 0x8002,
        /// Default value cannot be changed (read only).
        DefaultReadOnly = 0x8004,
        /// Invalid drive number.
        InvalidDriveNumber = 0x800A,
        /// General error.
        GeneralError = 0x800B,
        /// No element addressed.
        NoElementAddressed = 0x800C,
    }
}

impl SoeError {
    /// The text of the error code (ETG.1000.6, spec-notes §soe).
    pub fn description(self) -> &'static str {
        use SoeError::*;
        match self {
            NoError => "No error",
            NoIdn => "No IDN",
            InvalidAccessElement1 => "Invalid access to element 1",
            NoName => "No name",
            NameTooShort => "Name transmission too short",
            NameTooLong => "Name transmission too long",
            NameReadOnly => "Name cannot be changed (read only)",
            NameWriteProtected => "Name is write-protected at this time",
            AttributeTooShort => "Attribute transmission too short",
            AttributeTooLong => "Attribute transmission too long",
            AttributeReadOnly => "Attribute cannot be changed (read only)",
            AttributeWriteProtected => "Attribute is write-protected at this time",
            NoUnit => "No unit",
            UnitTooShort => "Unit transmission too short",
            UnitTooLong => "Unit transmission too long",
            UnitReadOnly => "Unit cannot be changed (read only)",
            UnitWriteProtected => "Unit is write-protected at this time",
            NoMinimum => "No minimum input value",
            MinimumTooShort => "Minimum input value transmission too short",
            MinimumTooLong => "Minimum input value transmission too long",
            MinimumReadOnly => "Minimum input value cannot be changed (read only)",
            MinimumWriteProtected => "Minimum input value is write-protected at this time",
            NoMaximum => "No maximum input value",
            MaximumTooShort => "Maximum input value transmission too short",
            MaximumTooLong => "Maximum input value transmission too long",
            MaximumReadOnly => "Maximum input value cannot be changed (read only)",
            MaximumWriteProtected => "Maximum input value is write-protected at this time",
            DataTooShort => "Operation data transmission too short",
            DataTooLong => "Operation data transmission too long",
            DataReadOnly => "Operation data cannot be changed (read only)",
            DataWriteProtected => "Operation data is write-protected at this time (state)",
            DataBelowMinimum => "Operation data is smaller than the minimum input value",
            DataAboveMaximum => "Operation data is greater than the maximum input value",
            InvalidData => "Invalid operation data (configured IDN not supported)",
            DataPasswordProtected => "Operation data write-protected by a password",
            DataCyclicallyConfigured => "Operation data write-protected (configured cyclically)",
            InvalidIndirectAddressing => {
                "Invalid indirect addressing (data container, list handling)"
            }
            DataProtectedBySettings => "Operation data write-protected due to other settings",
            Reserved700D => "Reserved",
            ProcedureAlreadyActive => "Procedure command already active",
            ProcedureNotInterruptible => "Procedure command not interruptible",
            ProcedureNotExecutableNow => "Procedure command not executable at this time (state)",
            ProcedureInvalidParameters => {
                "Procedure command not executable (invalid or false parameters)"
            }
            NoDataState => "No data state",
            NoDefault => "No default value",
            DefaultTooLong => "Default value transmission too long",
            DefaultReadOnly => "Default value cannot be changed (read only)",
            InvalidDriveNumber => "Invalid drive number",
            GeneralError => "General error",
            NoElementAddressed => "No element addressed",
            Unknown(_) => "Unknown error",
        }
    }
}

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

/// One fragment of an SoE write (or read response) sequence, from [`fragments`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SoeFragment {
    /// The bytes of the whole value this fragment carries.
    pub range: Range<usize>,
    /// `Some(n)`: not the last fragment (Incomplete = 1, bytes 2-3 = n fragments still to
    /// follow); `None`: the last fragment (Incomplete = 0, bytes 2-3 = the IDN).
    pub fragments_left: Option<u16>,
}

/// Iterator over the fragments of a value, see [`fragments`].
#[derive(Debug, Clone)]
pub struct SoeFragments {
    total: usize,
    capacity: usize,
    offset: usize,
    done: bool,
}

impl Iterator for SoeFragments {
    type Item = SoeFragment;

    fn next(&mut self) -> Option<SoeFragment> {
        if self.done {
            return None;
        }
        let remaining = self.total - self.offset;
        let start = self.offset;
        if remaining <= self.capacity {
            self.done = true;
            return Some(SoeFragment {
                range: start..self.total,
                fragments_left: None,
            });
        }
        // IgH: fragments_left = ceil(remaining / capacity) − 1; checked to fit in u16 by
        // `fragments`, since it only decreases.
        let left = remaining.div_ceil(self.capacity) - 1;
        self.offset += self.capacity;
        Some(SoeFragment {
            range: start..self.offset,
            fragments_left: Some(u16::try_from(left).unwrap_or(u16::MAX)),
        })
    }
}

/// Splits a value of `total_len` bytes into fragments of at most `capacity` bytes
/// (`capacity` = [`fragment_capacity`] of the receiver's mailbox) following IgH's rule
/// (ETG.1000.6, spec-notes §soe): every fragment but the last is full, Incomplete = 1 and carries
/// `ceil(remaining / capacity) − 1`; the last carries the IDN. A value that fits (including
/// an empty one) is a single last fragment.
///
/// Refuses a zero capacity for a non-empty value and more than 65 535 fragments-left.
pub fn fragments(total_len: usize, capacity: usize) -> Result<SoeFragments> {
    if capacity == 0 && total_len > 0 {
        return Err(WireError::Invalid {
            what: "SoE fragments",
            reason: "zero fragment capacity",
        });
    }
    if total_len > capacity && total_len.div_ceil(capacity) - 1 > usize::from(u16::MAX) {
        return Err(WireError::BadLength {
            what: "SoE fragments",
            declared: total_len,
            available: capacity.saturating_mul(usize::from(u16::MAX) + 1),
        });
    }
    Ok(SoeFragments {
        total: total_len,
        capacity,
        offset: 0,
        done: false,
    })
}

/// A read/write view of an SoE message (mailbox data).
#[derive(Debug, Clone)]
pub struct SoePacket<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> SoePacket<T> {
    /// Wraps a buffer without checking it; accessors may panic until [`Self::check_len`] passed.
    pub const fn new_unchecked(buffer: T) -> Self {
        SoePacket { buffer }
    }

    /// Wraps a buffer and checks that the 4-byte header is present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let packet = Self::new_unchecked(buffer);
        packet.check_len()?;
        Ok(packet)
    }

    /// Checks that the header is present, and the error code when the error bit is set.
    pub fn check_len(&self) -> Result<()> {
        let buf = self.buffer.as_ref();
        need("SoE header", buf, HEADER_LEN)?;
        if self.error() {
            need("SoE error code", buf, HEADER_LEN + ERROR_CODE_LEN)?;
        }
        Ok(())
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Opcode (3 bits).
    pub fn opcode(&self) -> SoeOpcode {
        SoeOpcode::from(self.buffer.as_ref()[fields::FLAGS] & fields::OPCODE_MASK)
    }

    /// Incomplete: more fragments follow; bytes 2-3 are fragments-left.
    pub fn incomplete(&self) -> bool {
        self.buffer.as_ref()[fields::FLAGS] & fields::INCOMPLETE != 0
    }

    /// Error: a u16 error code is present.
    pub fn error(&self) -> bool {
        self.buffer.as_ref()[fields::FLAGS] & fields::ERROR != 0
    }

    /// Drive number 0..=7.
    pub fn drive(&self) -> u8 {
        self.buffer.as_ref()[fields::FLAGS] >> fields::DRIVE_SHIFT
    }

    /// Element flags.
    pub fn elements(&self) -> ElementFlags {
        ElementFlags(self.buffer.as_ref()[fields::ELEMENTS])
    }

    /// The raw u16 at bytes 2-3: IDN or fragments-left, depending on [`Self::incomplete`].
    pub fn idn_or_fragments(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::IDN_OR_FRAGMENTS.start)
    }

    /// Everything after the header (element data and, with the error bit, the error code).
    pub fn payload(&self) -> &[u8] {
        &self.buffer.as_ref()[fields::PAYLOAD]
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> SoePacket<T> {
    /// Sets byte 0; values wider than their field are masked (callers check, see emit).
    pub fn set_flags(&mut self, opcode: SoeOpcode, incomplete: bool, error: bool, drive: u8) {
        let mut b = (u8::from(opcode) & fields::OPCODE_MASK) | (drive << fields::DRIVE_SHIFT);
        if incomplete {
            b |= fields::INCOMPLETE;
        }
        if error {
            b |= fields::ERROR;
        }
        self.buffer.as_mut()[fields::FLAGS] = b;
    }

    /// Sets the element flags.
    pub fn set_elements(&mut self, value: ElementFlags) {
        self.buffer.as_mut()[fields::ELEMENTS] = value.0;
    }

    /// Sets bytes 2-3.
    pub fn set_idn_or_fragments(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::IDN_OR_FRAGMENTS.start, value)
    }

    /// Mutable payload.
    pub fn payload_mut(&mut self) -> &mut [u8] {
        &mut self.buffer.as_mut()[fields::PAYLOAD]
    }
}

/// Bytes 2-3 of the SoE header: the IDN, or the fragments still to follow.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum IdnOrFragments {
    /// Incomplete = 0: the IDN.
    Idn(Idn),
    /// Incomplete = 1: number of fragments still to follow.
    FragmentsLeft(u16),
}

/// A parsed SoE message.
///
/// Where the error code sits (spec-notes §soe, IgH): for a read response it is the *last* two
/// bytes (element data, if any, come first); for every other opcode it is right after the
/// header at offset 4 (further bytes, if any, are kept in `data`). Both coincide when no
/// data are present, which is the usual case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SoeRepr<'a> {
    /// Opcode.
    pub opcode: SoeOpcode,
    /// Drive number 0..=7.
    pub drive: u8,
    /// Element flags.
    pub elements: ElementFlags,
    /// IDN (complete message or last fragment) or fragments-left (Incomplete = 1).
    pub idn_or_fragments: IdnOrFragments,
    /// The error code when the error bit is set.
    pub error: Option<SoeError>,
    /// Element data (without the error code).
    pub data: &'a [u8],
}

impl<'a> SoeRepr<'a> {
    /// Parses a checked SoE view. Unknown opcodes (0, 7) are kept as data: the header
    /// layout does not depend on the opcode.
    pub fn parse<T: AsRef<[u8]> + ?Sized>(packet: &SoePacket<&'a T>) -> Result<Self> {
        packet.check_len()?;
        // Copy the `&'a T` out of the view so the payload borrows the buffer, not the view.
        let buf: &'a [u8] = AsRef::<[u8]>::as_ref(packet.buffer);
        let payload = &buf[fields::PAYLOAD];
        let opcode = packet.opcode();
        let (error, data) = if packet.error() {
            // check_len guaranteed at least ERROR_CODE_LEN payload bytes.
            if opcode == SoeOpcode::ReadResponse {
                let (data, code) = payload.split_at(payload.len() - ERROR_CODE_LEN);
                (Some(SoeError::from(field::u16_le(code, 0))), data)
            } else {
                let (code, data) = payload.split_at(ERROR_CODE_LEN);
                (Some(SoeError::from(field::u16_le(code, 0))), data)
            }
        } else {
            (None, payload)
        };
        let raw = packet.idn_or_fragments();
        Ok(SoeRepr {
            opcode,
            drive: packet.drive(),
            elements: packet.elements(),
            idn_or_fragments: if packet.incomplete() {
                IdnOrFragments::FragmentsLeft(raw)
            } else {
                IdnOrFragments::Idn(Idn(raw))
            },
            error,
            data,
        })
    }

    /// Bytes needed on the wire.
    pub fn buffer_len(&self) -> usize {
        HEADER_LEN
            + self.data.len()
            + if self.error.is_some() {
                ERROR_CODE_LEN
            } else {
                0
            }
    }

    /// Writes the message into the start of `packet`'s buffer; refuses a drive above 7 or an
    /// opcode above 7.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, packet: &mut SoePacket<T>) -> Result<()> {
        room("SoE message", packet.buffer.as_ref(), self.buffer_len())?;
        if self.drive > 7 || u8::from(self.opcode) > fields::OPCODE_MASK {
            return Err(WireError::Invalid {
                what: "SoE header",
                reason: "drive number or opcode above 7",
            });
        }
        let (incomplete, raw) = match self.idn_or_fragments {
            IdnOrFragments::Idn(idn) => (false, idn.0),
            IdnOrFragments::FragmentsLeft(n) => (true, n),
        };
        packet.set_flags(self.opcode, incomplete, self.error.is_some(), self.drive);
        packet.set_elements(self.elements);
        packet.set_idn_or_fragments(raw);
        let n = self.data.len();
        let payload = packet.payload_mut();
        match self.error {
            None => payload[..n].copy_from_slice(self.data),
            Some(code) if self.opcode == SoeOpcode::ReadResponse => {
                payload[..n].copy_from_slice(self.data);
                field::set_u16_le(payload, n, u16::from(code));
            }
            Some(code) => {
                field::set_u16_le(payload, 0, u16::from(code));
                payload[ERROR_CODE_LEN..ERROR_CODE_LEN + n].copy_from_slice(self.data);
            }
        }
        Ok(())
    }
}

impl fmt::Display for SoeRepr<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("SoE ")?;
        f.write_str(self.opcode.name())?;
        if let SoeOpcode::Unknown(raw) = self.opcode {
            write!(f, " {raw}")?;
        }
        match self.idn_or_fragments {
            IdnOrFragments::Idn(idn) => write!(f, " {idn}")?,
            IdnOrFragments::FragmentsLeft(n) => write!(f, " fragments-left={n}")?,
        }
        write!(f, " drive {} elements={}", self.drive, self.elements)?;
        if let Some(code) = self.error {
            write!(f, " error {:#06x} {}", u16::from(code), code.description())?;
        }
        if !self.data.is_empty() {
            write!(f, " ({} bytes)", self.data.len())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::mailbox::{Mailbox, MailboxHeader, MailboxType};
    use proptest::prelude::*;

    // ETG.1000.6, spec-notes §soe.
    static READ_REQ: [u8; 10] = [0x04, 0x00, 0x00, 0x00, 0x00, 0x15, 0x01, 0x40, 0x18, 0x00];
    static NO_IDN_REPLY: [u8; 12] = [
        0x06, 0x00, 0x00, 0x00, 0x00, 0x15, 0x12, 0x40, 0x18, 0x00, 0x01, 0x10,
    ];

    fn mailbox_case(bytes: &[u8], expected: SoeRepr<'_>) {
        let mbx = Mailbox::new_checked(bytes).unwrap();
        let header = MailboxHeader::parse(&mbx).unwrap();
        assert_eq!(header.mailbox_type, MailboxType::Soe);
        let repr = SoeRepr::parse(&SoePacket::new_checked(mbx.data()).unwrap()).unwrap();
        assert_eq!(repr, expected);
        let mut out = vec![0xa5u8; bytes.len()];
        header
            .emit(&mut Mailbox::new_unchecked(&mut out[..]))
            .unwrap();
        repr.emit(&mut SoePacket::new_unchecked(&mut out[6..]))
            .unwrap();
        assert_eq!(out, bytes);
    }

    #[test]
    fn c15_read_request() {
        let repr = SoeRepr {
            opcode: SoeOpcode::ReadRequest,
            drive: 0,
            elements: ElementFlags::VALUE,
            idn_or_fragments: IdnOrFragments::Idn("S-0-0024".parse().unwrap()),
            error: None,
            data: &[],
        };
        mailbox_case(&READ_REQ, repr);
        assert_eq!(
            repr.to_string(),
            "SoE read req S-0-0024 drive 0 elements=value"
        );
    }

    #[test]
    fn c15_error_reply() {
        let repr = SoeRepr {
            opcode: SoeOpcode::ReadResponse,
            drive: 0,
            elements: ElementFlags::VALUE,
            idn_or_fragments: IdnOrFragments::Idn(Idn::from_raw(0x0018)),
            error: Some(SoeError::NoIdn),
            data: &[],
        };
        mailbox_case(&NO_IDN_REPLY, repr);
        assert_eq!(
            repr.to_string(),
            "SoE read resp S-0-0024 drive 0 elements=value error 0x1001 No IDN"
        );
    }

    #[test]
    fn error_code_position() {
        // Read response with 2 data bytes then the error code last.
        let read = [0x12, 0x40, 0x18, 0x00, 0xaa, 0xbb, 0x01, 0x70];
        let repr = SoeRepr::parse(&SoePacket::new_checked(&read[..]).unwrap()).unwrap();
        assert_eq!(repr.error, Some(SoeError::Unknown(0x7001)));
        assert_eq!(repr.data, &[0xaa, 0xbb]);
        // Write response: code at offset 4 (opcode 4 | error 0x10, drive 1 = 0x20).
        let write = [0x34, 0x40, 0x18, 0x00, 0x04, 0x70];
        let repr = SoeRepr::parse(&SoePacket::new_checked(&write[..]).unwrap()).unwrap();
        assert_eq!(repr.opcode, SoeOpcode::WriteResponse);
        assert_eq!(repr.drive, 1);
        assert_eq!(repr.error, Some(SoeError::DataReadOnly));
        assert!(repr.data.is_empty());
        // Error bit without the code.
        assert!(matches!(
            SoePacket::new_checked(&[0x14u8, 0x40, 0x18, 0x00, 0x01][..]),
            Err(WireError::Truncated {
                need: 6,
                have: 5,
                ..
            })
        ));
        assert!(matches!(
            SoePacket::new_checked(&[0x01u8, 0x40, 0x18][..]),
            Err(WireError::Truncated {
                need: 4,
                have: 3,
                ..
            })
        ));
    }

    #[test]
    fn idn_text() {
        assert_eq!(Idn::from_raw(0x0018).to_string(), "S-0-0024");
        assert_eq!(Idn::from_raw(0x8001).to_string(), "P-0-0001");
        assert_eq!(Idn::from_raw(0xF123).to_string(), "P-7-0291");
        assert_eq!("P-0-0001".parse::<Idn>().unwrap().raw(), 0x8001);
        assert_eq!("S-0-16".parse::<Idn>().unwrap().raw(), 0x0010);
        assert_eq!("S-7-4095".parse::<Idn>().unwrap().raw(), 0x7FFF);
        for bad in [
            "", "S-0", "X-0-1", "S-8-1", "S-0-4096", "S-0-1-2", "S--1", "S-0-+1",
        ] {
            assert!(bad.parse::<Idn>().is_err(), "{bad}");
        }
    }

    #[test]
    fn element_flags_display() {
        assert_eq!(ElementFlags::VALUE.to_string(), "value");
        assert_eq!(
            (ElementFlags::NAME | ElementFlags::ATTRIBUTE).to_string(),
            "name+attribute"
        );
        assert_eq!(ElementFlags::empty().to_string(), "none");
        assert_eq!(ElementFlags::from_bits(0x40), ElementFlags::VALUE);
    }

    #[test]
    fn attribute_decode() {
        // Worked from spec-notes §soe: factor 1, 4 bytes (010), unsigned (1), 3 decimals,
        // write-protected in OP → 0x4312_0001.
        let attr = SoeAttribute::from_u32(0x4312_0001);
        assert_eq!(
            attr,
            SoeAttribute {
                conversion_factor: 1,
                element_size: 4,
                list: false,
                procedure_command: false,
                data_type: SoeDataType::Unsigned,
                decimal_places: 3,
                write_protected_preop: false,
                write_protected_safeop: false,
                write_protected_op: true,
            }
        );
        assert_eq!(attr.to_u32().unwrap(), 0x4312_0001);
        // A list of u16 (IDN list): size 2 (01) + list bit 18 → bits 16-18 = 101; type IDN 5;
        // procedure bit 19.
        let list = SoeAttribute::from_u32(0x005D_0000);
        assert_eq!(list.element_size, 2);
        assert!(list.list && list.procedure_command);
        assert_eq!(list.data_type, SoeDataType::Idn);
        let bad = SoeAttribute {
            element_size: 3,
            ..attr
        };
        assert!(bad.to_u32().is_err());
    }

    #[test]
    fn multi_fragment_write_sequence() {
        // Mailbox of 32 bytes: capacity 32 − 10 = 22; value 3 × 22 + 5 = 71 bytes.
        let cap = fragment_capacity(32);
        assert_eq!(cap, 22);
        let value: Vec<u8> = (0..71u8).collect();
        let frags: Vec<_> = fragments(value.len(), cap).unwrap().collect();
        assert_eq!(
            frags,
            vec![
                SoeFragment {
                    range: 0..22,
                    fragments_left: Some(3)
                },
                SoeFragment {
                    range: 22..44,
                    fragments_left: Some(2)
                },
                SoeFragment {
                    range: 44..66,
                    fragments_left: Some(1)
                },
                SoeFragment {
                    range: 66..71,
                    fragments_left: None
                },
            ]
        );
        // Build the four write requests and check the headers byte by byte.
        let idn = Idn::from_raw(0x0018);
        let expected_headers: [[u8; 4]; 4] = [
            [0x0b, 0x40, 0x03, 0x00],
            [0x0b, 0x40, 0x02, 0x00],
            [0x0b, 0x40, 0x01, 0x00],
            [0x03, 0x40, 0x18, 0x00],
        ];
        let mut reassembled = Vec::new();
        for (frag, header) in frags.iter().zip(expected_headers) {
            let repr = SoeRepr {
                opcode: SoeOpcode::WriteRequest,
                drive: 0,
                elements: ElementFlags::VALUE,
                idn_or_fragments: match frag.fragments_left {
                    Some(n) => IdnOrFragments::FragmentsLeft(n),
                    None => IdnOrFragments::Idn(idn),
                },
                error: None,
                data: &value[frag.range.clone()],
            };
            let mut buf = vec![0xa5u8; repr.buffer_len()];
            assert!(buf.len() <= cap + HEADER_LEN);
            repr.emit(&mut SoePacket::new_unchecked(&mut buf[..]))
                .unwrap();
            assert_eq!(buf[..4], header);
            let parsed = SoeRepr::parse(&SoePacket::new_checked(&buf[..]).unwrap()).unwrap();
            reassembled.extend_from_slice(parsed.data);
        }
        assert_eq!(reassembled, value);
    }

    #[test]
    fn fragment_edge_cases() {
        // Exact multiple: IgH gives ceil(44/22) − 1 = 1 for the first.
        let f: Vec<_> = fragments(44, 22)
            .unwrap()
            .map(|f| f.fragments_left)
            .collect();
        assert_eq!(f, vec![Some(1), None]);
        let f: Vec<_> = fragments(0, 22).unwrap().collect();
        assert_eq!(
            f,
            vec![SoeFragment {
                range: 0..0,
                fragments_left: None
            }]
        );
        assert!(fragments(1, 0).is_err());
        assert!(fragments(70_000, 1).is_err());
        assert_eq!(fragments(65_536, 1).unwrap().count(), 65_536);
    }

    #[test]
    fn emit_refuses_bad_drive() {
        let repr = SoeRepr {
            opcode: SoeOpcode::ReadRequest,
            drive: 8,
            elements: ElementFlags::VALUE,
            idn_or_fragments: IdnOrFragments::Idn(Idn::from_raw(1)),
            error: None,
            data: &[],
        };
        let mut buf = [0u8; 4];
        assert!(
            repr.emit(&mut SoePacket::new_unchecked(&mut buf[..]))
                .is_err()
        );
        assert_eq!(buf, [0u8; 4]);
        let mut small = [0u8; 3];
        assert!(matches!(
            SoeRepr { drive: 0, ..repr }.emit(&mut SoePacket::new_unchecked(&mut small[..])),
            Err(WireError::BufferTooSmall { .. })
        ));
    }

    pub(crate) fn arb_soe() -> impl Strategy<Value = (SoeRepr<'static>, Vec<u8>)> {
        (
            0u8..8,
            0u8..8,
            any::<u8>(),
            any::<bool>(),
            any::<u16>(),
            proptest::option::of(any::<u16>()),
            proptest::collection::vec(any::<u8>(), 0..32),
        )
            .prop_map(|(op, drive, el, inc, raw, err, data)| {
                let repr = SoeRepr {
                    opcode: SoeOpcode::from(op),
                    drive,
                    elements: ElementFlags::from_bits(el),
                    idn_or_fragments: if inc {
                        IdnOrFragments::FragmentsLeft(raw)
                    } else {
                        IdnOrFragments::Idn(Idn::from_raw(raw))
                    },
                    error: err.map(SoeError::from),
                    data: &[],
                };
                (repr, data)
            })
    }

    proptest! {
        #[test]
        fn round_trip((template, data) in arb_soe()) {
            let repr = SoeRepr { data: &data, ..template };
            let mut buf = vec![0u8; repr.buffer_len()];
            repr.emit(&mut SoePacket::new_unchecked(&mut buf[..])).unwrap();
            let parsed = SoeRepr::parse(&SoePacket::new_checked(&buf[..]).unwrap()).unwrap();
            prop_assert_eq!(parsed, repr);
        }

        #[test]
        fn idn_text_round_trip(raw in any::<u16>()) {
            let idn = Idn::from_raw(raw);
            prop_assert_eq!(idn.to_string().parse::<Idn>().unwrap(), idn);
        }

        #[test]
        fn attribute_round_trip(raw in any::<u32>()) {
            let clean = raw & !((1 << 23) | (1 << 31));
            prop_assert_eq!(SoeAttribute::from_u32(clean).to_u32().unwrap(), clean);
        }

        #[test]
        fn fragments_cover_the_value(total in 0usize..2000, cap in 1usize..300) {
            let frags: Vec<_> = fragments(total, cap).unwrap().collect();
            let mut next = 0;
            for (i, f) in frags.iter().enumerate() {
                prop_assert_eq!(f.range.start, next);
                prop_assert!(f.range.len() <= cap);
                next = f.range.end;
                let left = frags.len() - 1 - i;
                prop_assert_eq!(f.fragments_left, if left == 0 { None } else { Some(left as u16) });
            }
            prop_assert_eq!(next, total);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..32)) {
            if let Ok(packet) = SoePacket::new_checked(&bytes[..])
                && let Ok(repr) = SoeRepr::parse(&packet) {
                    let _ = repr.to_string();
                }
            if let Ok(s) = core::str::from_utf8(&bytes) {
                let _ = s.parse::<Idn>();
            }
        }
    }
}
