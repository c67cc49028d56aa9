//! Get Entry Description service data (ETG.1000.6, spec-notes §coe.info "Get Entry Description").
//!
//! ```text
//! request:  u16 index, u8 subindex, u8 value info
//! response: u16 index, u8 subindex, u8 value info, u16 data type, u16 bit length,
//!           u16 object access, [unit type], [default], [minimum], [maximum], description
//! ```
//! Default/minimum/maximum have ⌈bit length / 8⌉ bytes each and are present only when the
//! value-info bit asks for them.
//!
//! **Unit type width** is uncertain (spec-notes §coe.info: Wireshark reads 2 bytes, newer
//! documents 4). We use 4 bytes ([`UNIT_TYPE_LEN`]), following the newer documents and the
//! UNSIGNED32 of CiA 301 physical units; master and simulator agree through this codec, and
//! the master avoids requesting the unit type from real slaves.

use core::fmt;

use crate::coe::data_type::{DataType, ObjectAccess};
use crate::error::{Result, WireError, need};
use crate::field::{self, Field};

mod fields {
    use super::Field;
    pub const INDEX: Field = 0..2;
    pub const SUBINDEX: usize = 2;
    pub const VALUE_INFO: usize = 3;
    pub const DATA_TYPE: Field = 4..6;
    pub const BIT_LENGTH: Field = 6..8;
    pub const ACCESS: Field = 8..10;
}

/// Bytes of a Get Entry Description request's service data.
pub const ENTRY_REQUEST_LEN: usize = fields::VALUE_INFO + 1;
/// Bytes of the fixed part of a Get Entry Description response.
pub const ENTRY_RESPONSE_FIXED_LEN: usize = fields::ACCESS.end;
/// Width of the unit type field (see the module documentation).
pub const UNIT_TYPE_LEN: usize = 4;

/// Value-info byte: which optional parts an entry description carries (spec-notes §coe.info).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ValueInfo(pub u8);

impl ValueInfo {
    /// Bit 0 (SOES): access rights (informative; always in the access word).
    pub const ACCESS: u8 = 0x01;
    /// Bit 1 (SOES): object category (informative).
    pub const CATEGORY: u8 = 0x02;
    /// Bit 2 (SOES): PDO mappable (informative).
    pub const MAPPABLE: u8 = 0x04;
    /// Bit 3: unit type present.
    pub const UNIT_TYPE: u8 = 0x08;
    /// Bit 4: default value present.
    pub const DEFAULT: u8 = 0x10;
    /// Bit 5: minimum value present.
    pub const MINIMUM: u8 = 0x20;
    /// Bit 6: maximum value present.
    pub const MAXIMUM: u8 = 0x40;

    /// Whether all bits of `mask` are set.
    pub const fn contains(self, mask: u8) -> bool {
        self.0 & mask == mask
    }
}

/// Size of a default/minimum/maximum value of an entry of `bit_length` bits.
pub const fn value_len(bit_length: u16) -> usize {
    (bit_length as usize).div_ceil(8)
}

/// A Get Entry Description response.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct EntryDescription<'a> {
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
    /// Which optional parts follow (the request's value info, echoed).
    pub value_info: ValueInfo,
    /// Data type of the entry.
    pub data_type: DataType,
    /// Size in bits.
    pub bit_length: u16,
    /// Access and mapping flags.
    pub access: ObjectAccess,
    /// Unit type, present iff value-info bit 3.
    pub unit_type: Option<u32>,
    /// Default value (⌈bit_length/8⌉ bytes), present iff value-info bit 4.
    pub default: Option<&'a [u8]>,
    /// Minimum value, present iff value-info bit 5.
    pub minimum: Option<&'a [u8]>,
    /// Maximum value, present iff value-info bit 6.
    pub maximum: Option<&'a [u8]>,
    /// Entry name (ASCII, not NUL-terminated; the rest of the message).
    pub description: &'a [u8],
}

impl<'a> EntryDescription<'a> {
    /// Parses the service data of a response fragment.
    pub fn parse(data: &'a [u8]) -> Result<Self> {
        const WHAT: &str = "SDO Info entry description";
        need(WHAT, data, ENTRY_RESPONSE_FIXED_LEN)?;
        let value_info = ValueInfo(data[fields::VALUE_INFO]);
        let bit_length = field::u16_le(data, fields::BIT_LENGTH.start);
        let mut rest = &data[ENTRY_RESPONSE_FIXED_LEN..];
        let mut take = |present: bool, n: usize| -> Result<Option<&'a [u8]>> {
            if !present {
                return Ok(None);
            }
            match (rest.get(..n), rest.get(n..)) {
                (Some(part), Some(after)) => {
                    rest = after;
                    Ok(Some(part))
                }
                _ => Err(WireError::Truncated {
                    what: WHAT,
                    need: data.len() - rest.len() + n,
                    have: data.len(),
                }),
            }
        };
        let unit_type = take(value_info.contains(ValueInfo::UNIT_TYPE), UNIT_TYPE_LEN)?
            .map(|b| field::u32_le(b, 0));
        let n = value_len(bit_length);
        let default = take(value_info.contains(ValueInfo::DEFAULT), n)?;
        let minimum = take(value_info.contains(ValueInfo::MINIMUM), n)?;
        let maximum = take(value_info.contains(ValueInfo::MAXIMUM), n)?;
        Ok(EntryDescription {
            index: field::u16_le(data, fields::INDEX.start),
            subindex: data[fields::SUBINDEX],
            value_info,
            data_type: DataType::from(field::u16_le(data, fields::DATA_TYPE.start)),
            bit_length,
            access: ObjectAccess(field::u16_le(data, fields::ACCESS.start)),
            unit_type,
            default,
            minimum,
            maximum,
            description: rest,
        })
    }

    /// Bytes of service data.
    pub fn buffer_len(&self) -> usize {
        let opt = |v: Option<&[u8]>| v.map_or(0, <[u8]>::len);
        ENTRY_RESPONSE_FIXED_LEN
            + self.unit_type.map_or(0, |_| UNIT_TYPE_LEN)
            + opt(self.default)
            + opt(self.minimum)
            + opt(self.maximum)
            + self.description.len()
    }

    /// Checks that the optional parts agree with the value info and the bit length.
    pub(crate) fn validate(&self) -> Result<()> {
        let vi = self.value_info;
        let n = value_len(self.bit_length);
        let ok = |bit: u8, v: Option<&[u8]>| match v {
            Some(v) => vi.contains(bit) && v.len() == n,
            None => !vi.contains(bit),
        };
        if self.unit_type.is_some() != vi.contains(ValueInfo::UNIT_TYPE)
            || !ok(ValueInfo::DEFAULT, self.default)
            || !ok(ValueInfo::MINIMUM, self.minimum)
            || !ok(ValueInfo::MAXIMUM, self.maximum)
        {
            return Err(WireError::Invalid {
                what: "SDO Info entry description",
                reason: "optional values disagree with value info or bit length",
            });
        }
        Ok(())
    }

    /// Writes the service data into `out` (exactly `buffer_len()` bytes, checked by caller).
    pub(crate) fn write(&self, out: &mut [u8]) {
        field::set_u16_le(out, fields::INDEX.start, self.index);
        out[fields::SUBINDEX] = self.subindex;
        out[fields::VALUE_INFO] = self.value_info.0;
        field::set_u16_le(out, fields::DATA_TYPE.start, self.data_type.into());
        field::set_u16_le(out, fields::BIT_LENGTH.start, self.bit_length);
        field::set_u16_le(out, fields::ACCESS.start, self.access.0);
        let mut at = ENTRY_RESPONSE_FIXED_LEN;
        let mut put = |bytes: &[u8]| {
            out[at..at + bytes.len()].copy_from_slice(bytes);
            at += bytes.len();
        };
        if let Some(unit) = self.unit_type {
            put(&unit.to_le_bytes());
        }
        for part in [self.default, self.minimum, self.maximum]
            .into_iter()
            .flatten()
        {
            put(part);
        }
        put(self.description);
    }
}

impl fmt::Display for EntryDescription<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "0x{:04X}:{:02X} {} {} bits {} \"{}\"",
            self.index,
            self.subindex,
            self.data_type,
            self.bit_length,
            self.access,
            crate::coe::display::Ascii(self.description)
        )
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn parse_with_all_optional_values() {
        // By hand: 0x6040:00, value info 0x78 (unit, default, min, max), UNSIGNED16 (0x0006),
        // 16 bits, access 0x007F (RW + RxPDO); unit 0x00000000, default 0x0000, min 0x0001,
        // max 0xFFFF, name "Ctrl".
        let bytes = [
            0x40, 0x60, 0x00, 0x78, 0x06, 0x00, 0x10, 0x00, 0x7f, 0x00, 0, 0, 0, 0, 0x00, 0x00,
            0x01, 0x00, 0xff, 0xff, b'C', b't', b'r', b'l',
        ];
        let e = EntryDescription::parse(&bytes).unwrap();
        assert_eq!(e.index, 0x6040);
        assert_eq!(e.data_type, DataType::Unsigned16);
        assert_eq!(e.access, ObjectAccess(0x7f));
        assert_eq!(e.unit_type, Some(0));
        assert_eq!(e.default, Some(&[0u8, 0][..]));
        assert_eq!(e.minimum, Some(&[1u8, 0][..]));
        assert_eq!(e.maximum, Some(&[0xffu8, 0xff][..]));
        assert_eq!(e.description, b"Ctrl");
        assert_eq!(e.buffer_len(), bytes.len());
        let mut out = vec![0xa5; bytes.len()];
        e.validate().unwrap();
        e.write(&mut out);
        assert_eq!(out, bytes);
        // Cut inside the maximum value.
        assert!(matches!(
            EntryDescription::parse(&bytes[..19]),
            Err(WireError::Truncated { .. })
        ));
        assert!(EntryDescription::parse(&bytes[..9]).is_err());
    }

    #[test]
    fn bit_sized_values_take_one_byte() {
        assert_eq!(value_len(1), 1);
        assert_eq!(value_len(8), 1);
        assert_eq!(value_len(9), 2);
        assert_eq!(value_len(0), 0);
    }

    pub(crate) fn arb_entry_parts()
    -> impl Strategy<Value = (u16, u8, u8, u16, u16, u16, u32, Vec<u8>, Vec<u8>)> {
        (
            any::<u16>(),
            any::<u8>(),
            any::<u8>(),
            any::<u16>(),
            0u16..80,
            any::<u16>(),
            any::<u32>(),
            proptest::collection::vec(any::<u8>(), 30),
            proptest::collection::vec(any::<u8>(), 0..20),
        )
    }

    /// Builds a consistent entry description borrowing `values` (30 bytes) and `desc`.
    pub(crate) fn entry_from<'a>(
        (index, subindex, vi, dt, bits, access, unit): (u16, u8, u8, u16, u16, u16, u32),
        values: &'a [u8],
        desc: &'a [u8],
    ) -> EntryDescription<'a> {
        let vi = ValueInfo(vi);
        let n = value_len(bits);
        let part = |bit: u8, at: usize| vi.contains(bit).then(|| &values[at..at + n]);
        EntryDescription {
            index,
            subindex,
            value_info: vi,
            data_type: DataType::from(dt),
            bit_length: bits,
            access: ObjectAccess(access),
            unit_type: vi.contains(ValueInfo::UNIT_TYPE).then_some(unit),
            default: part(ValueInfo::DEFAULT, 0),
            minimum: part(ValueInfo::MINIMUM, 10),
            maximum: part(ValueInfo::MAXIMUM, 20),
            description: desc,
        }
    }

    proptest! {
        #[test]
        fn round_trip((i, s, vi, dt, bits, acc, unit, values, desc) in arb_entry_parts()) {
            let e = entry_from((i, s, vi, dt, bits, acc, unit), &values, &desc);
            e.validate().unwrap();
            let mut out = vec![0u8; e.buffer_len()];
            e.write(&mut out);
            prop_assert_eq!(EntryDescription::parse(&out).unwrap(), e);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
            if let Ok(e) = EntryDescription::parse(&bytes) {
                let _ = e.to_string();
            }
        }
    }
}
