//! Get Object Description response data (spec-notes §coe.info "Get Object Description").
//!
//! ```text
//! u16 index, u16 data type, u8 max subindex, u8 object code, name (ASCII, rest of message)
//! ```

use core::fmt;

use crate::coe::data_type::{DataType, ObjectCode};
use crate::coe::display::Ascii;
use crate::error::{Result, need};
use crate::field::{self, Field};

mod fields {
    use super::Field;
    pub const INDEX: Field = 0..2;
    pub const DATA_TYPE: Field = 2..4;
    pub const MAX_SUBINDEX: usize = 4;
    pub const OBJECT_CODE: usize = 5;
    pub const NAME: usize = 6;
}

/// Bytes of the fixed part (before the name).
pub const OBJECT_DESCRIPTION_FIXED_LEN: usize = fields::NAME;

/// A Get Object Description response.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ObjectDescription<'a> {
    /// Object index.
    pub index: u16,
    /// Data type of the object (of its entries for ARRAY).
    pub data_type: DataType,
    /// Highest subindex.
    pub max_subindex: u8,
    /// VAR / ARRAY / RECORD ...
    pub object_code: ObjectCode,
    /// Object name (ASCII, not NUL-terminated; the rest of the message).
    pub name: &'a [u8],
}

impl<'a> ObjectDescription<'a> {
    /// Parses the service data of a response.
    pub fn parse(data: &'a [u8]) -> Result<Self> {
        need(
            "SDO Info object description",
            data,
            OBJECT_DESCRIPTION_FIXED_LEN,
        )?;
        Ok(ObjectDescription {
            index: field::u16_le(data, fields::INDEX.start),
            data_type: DataType::from(field::u16_le(data, fields::DATA_TYPE.start)),
            max_subindex: data[fields::MAX_SUBINDEX],
            object_code: ObjectCode::from(data[fields::OBJECT_CODE]),
            name: data.get(fields::NAME..).unwrap_or(&[]),
        })
    }

    /// Bytes of service data.
    pub fn buffer_len(&self) -> usize {
        OBJECT_DESCRIPTION_FIXED_LEN + self.name.len()
    }

    /// Writes the service data into `out` (exactly `buffer_len()` bytes, checked by caller).
    pub(crate) fn write(&self, out: &mut [u8]) {
        field::set_u16_le(out, fields::INDEX.start, self.index);
        field::set_u16_le(out, fields::DATA_TYPE.start, self.data_type.into());
        out[fields::MAX_SUBINDEX] = self.max_subindex;
        out[fields::OBJECT_CODE] = self.object_code.into();
        out[fields::NAME..].copy_from_slice(self.name);
    }
}

impl fmt::Display for ObjectDescription<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "0x{:04X} {} {} max sub {} \"{}\"",
            self.index,
            self.object_code,
            self.data_type,
            self.max_subindex,
            Ascii(self.name)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn parse_and_write() {
        // By hand: 0x1C12, UNSIGNED16 (0x0006), max sub 2, ARRAY (8), "RxPDO assign".
        let mut bytes = vec![0x12, 0x1c, 0x06, 0x00, 0x02, 0x08];
        bytes.extend_from_slice(b"RxPDO assign");
        let o = ObjectDescription::parse(&bytes).unwrap();
        assert_eq!(
            (o.index, o.data_type, o.max_subindex, o.object_code),
            (0x1C12, DataType::Unsigned16, 2, ObjectCode::Array)
        );
        assert_eq!(o.name, b"RxPDO assign");
        let mut out = vec![0xa5; o.buffer_len()];
        o.write(&mut out);
        assert_eq!(out, bytes);
        assert!(ObjectDescription::parse(&bytes[..5]).is_err());
        assert_eq!(
            o.to_string(),
            "0x1C12 ARRAY UNSIGNED16 max sub 2 \"RxPDO assign\""
        );
    }

    proptest! {
        #[test]
        fn round_trip(
            index in any::<u16>(), dt in any::<u16>(), max in any::<u8>(), code in any::<u8>(),
            name in proptest::collection::vec(any::<u8>(), 0..20),
        ) {
            let o = ObjectDescription {
                index, data_type: DataType::from(dt), max_subindex: max,
                object_code: ObjectCode::from(code), name: &name,
            };
            let mut out = vec![0u8; o.buffer_len()];
            o.write(&mut out);
            prop_assert_eq!(ObjectDescription::parse(&out).unwrap(), o);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..20)) {
            if let Ok(o) = ObjectDescription::parse(&bytes) {
                let _ = o.to_string();
            }
        }
    }
}
