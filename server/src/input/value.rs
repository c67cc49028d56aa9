//! Typed values over raw little-endian bytes, for a type the caller names: integers, reals,
//! bool, strings, or raw hex.

use master_core::wire::coe::DataType;

use crate::error::ApiError;

/// A value type a caller can name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValueType {
    /// BOOLEAN (one byte).
    Bool,
    /// UNSIGNED8/16/32/64.
    U8,
    /// UNSIGNED16.
    U16,
    /// UNSIGNED32.
    U32,
    /// UNSIGNED64.
    U64,
    /// INTEGER8.
    I8,
    /// INTEGER16.
    I16,
    /// INTEGER32.
    I32,
    /// INTEGER64.
    I64,
    /// REAL32.
    F32,
    /// REAL64.
    F64,
    /// VISIBLE_STRING.
    String,
    /// Raw bytes as hex.
    Hex,
}

impl std::str::FromStr for ValueType {
    type Err = ApiError;

    fn from_str(name: &str) -> Result<ValueType, ApiError> {
        Ok(match name.to_ascii_lowercase().as_str() {
            "bool" => ValueType::Bool,
            "u8" | "uint8" => ValueType::U8,
            "u16" | "uint16" => ValueType::U16,
            "u32" | "uint32" => ValueType::U32,
            "u64" | "uint64" => ValueType::U64,
            "i8" | "int8" => ValueType::I8,
            "i16" | "int16" => ValueType::I16,
            "i32" | "int32" => ValueType::I32,
            "i64" | "int64" => ValueType::I64,
            // IgH's `ethercat --type` names too: float, double, octet_string.
            "f32" | "real32" | "float" => ValueType::F32,
            "f64" | "real64" | "double" => ValueType::F64,
            "string" | "visible_string" => ValueType::String,
            "hex" | "raw" | "octet_string" => ValueType::Hex,
            other => return Err(ApiError::invalid(format!("unknown value type {other:?}"))),
        })
    }
}

/// How a value given or asked for as text is typed: by the type the slave's SDO Information
/// names for the entry (`auto`), or as a type named by the caller.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Typing {
    /// The slave's SDO Information type.
    Auto,
    /// A named type.
    As(ValueType),
}

impl std::str::FromStr for Typing {
    type Err = ApiError;

    /// `auto` or a [`ValueType`] name; an unknown name is refused naming the `value_type`
    /// field (REST's `type`).
    fn from_str(name: &str) -> Result<Typing, ApiError> {
        if name.trim().eq_ignore_ascii_case("auto") {
            return Ok(Typing::Auto);
        }
        name.trim().parse().map(Typing::As).map_err(|_| {
            ApiError::invalid_field(
                "value_type",
                format!(
                    "unknown value type {name:?}: use auto, bool, u8..u64, i8..i64, f32, f64, \
                     string or hex"
                ),
            )
        })
    }
}

fn fixed<const N: usize>(bytes: &[u8]) -> Result<[u8; N], ApiError> {
    bytes
        .try_into()
        .map_err(|_| ApiError::invalid(format!("{} bytes where the type has {N}", bytes.len())))
}

/// The text of `bytes` read as `ty`.
pub fn decode(ty: ValueType, bytes: &[u8]) -> Result<String, ApiError> {
    Ok(match ty {
        ValueType::Bool => (fixed::<1>(bytes)?[0] != 0).to_string(),
        ValueType::U8 => u8::from_le_bytes(fixed(bytes)?).to_string(),
        ValueType::U16 => u16::from_le_bytes(fixed(bytes)?).to_string(),
        ValueType::U32 => u32::from_le_bytes(fixed(bytes)?).to_string(),
        ValueType::U64 => u64::from_le_bytes(fixed(bytes)?).to_string(),
        ValueType::I8 => i8::from_le_bytes(fixed(bytes)?).to_string(),
        ValueType::I16 => i16::from_le_bytes(fixed(bytes)?).to_string(),
        ValueType::I32 => i32::from_le_bytes(fixed(bytes)?).to_string(),
        ValueType::I64 => i64::from_le_bytes(fixed(bytes)?).to_string(),
        ValueType::F32 => f32::from_le_bytes(fixed(bytes)?).to_string(),
        ValueType::F64 => f64::from_le_bytes(fixed(bytes)?).to_string(),
        ValueType::String => String::from_utf8_lossy(bytes)
            .trim_end_matches('\0')
            .to_owned(),
        ValueType::Hex => hex::encode(bytes),
    })
}

fn int<T: std::str::FromStr + TryFrom<i128>>(text: &str) -> Result<T, ApiError> {
    let bad = || ApiError::invalid(format!("{text:?} does not fit the type"));
    let value: i128 = match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => i128::from_str_radix(hex, 16).map_err(|_| bad())?,
        None => text.parse().map_err(|_| bad())?,
    };
    T::try_from(value).map_err(|_| bad())
}

/// The bytes of `text` written as `ty` (integers in decimal or `0x` hex).
pub fn encode(ty: ValueType, text: &str) -> Result<Vec<u8>, ApiError> {
    let text = text.trim();
    let real = |t: &str| {
        t.parse::<f64>()
            .map_err(|_| ApiError::invalid(format!("{t:?} is not a number")))
    };
    Ok(match ty {
        ValueType::Bool => match text {
            "true" | "1" => vec![1],
            "false" | "0" => vec![0],
            _ => return Err(ApiError::invalid(format!("{text:?} is not a bool"))),
        },
        ValueType::U8 => int::<u8>(text)?.to_le_bytes().to_vec(),
        ValueType::U16 => int::<u16>(text)?.to_le_bytes().to_vec(),
        ValueType::U32 => int::<u32>(text)?.to_le_bytes().to_vec(),
        ValueType::U64 => int::<u64>(text)?.to_le_bytes().to_vec(),
        ValueType::I8 => int::<i8>(text)?.to_le_bytes().to_vec(),
        ValueType::I16 => int::<i16>(text)?.to_le_bytes().to_vec(),
        ValueType::I32 => int::<i32>(text)?.to_le_bytes().to_vec(),
        ValueType::I64 => int::<i64>(text)?.to_le_bytes().to_vec(),
        ValueType::F32 => (real(text)? as f32).to_le_bytes().to_vec(),
        ValueType::F64 => real(text)?.to_le_bytes().to_vec(),
        ValueType::String => text.as_bytes().to_vec(),
        ValueType::Hex => hex::decode(text).map_err(|_| ApiError::invalid("not hex"))?,
    })
}

/// A number as users type it in paths and on the command line: decimal or `0x` hex,
/// narrowed to the width of `T`; `field` names it in the error.
pub fn parse_number<T: TryFrom<u64>>(text: &str, field: &str) -> Result<T, ApiError> {
    let text = text.trim();
    let bad = || ApiError::invalid(format!("bad {field} {text:?}"));
    let value = match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u64::from_str_radix(hex, 16).map_err(|_| bad())?,
        None => text.parse::<u64>().map_err(|_| bad())?,
    };
    T::try_from(value).map_err(|_| bad())
}

/// An SoE IDN in either syntax: `S-0-0011` / `P-0-0100` (ETG.1000.6, spec-notes §soe) or a
/// number in the one syntax (`0x8064`, `32868`).
pub fn parse_idn(text: &str, field: &str) -> Result<u16, ApiError> {
    let text = text.trim();
    if text.contains('-') {
        let idn: master_core::wire::soe::Idn = text
            .parse()
            .map_err(|err| ApiError::invalid(format!("bad {field} {text:?}: {err}")))?;
        Ok(idn.raw())
    } else {
        parse_number(text, field)
    }
}

/// The value type for a CoE data type from SDO Information (raw hex for the types without
/// a plain text form: octet strings, domains, structures).
pub fn for_data_type(data_type: DataType) -> ValueType {
    match data_type {
        DataType::Boolean => ValueType::Bool,
        DataType::Integer8 => ValueType::I8,
        DataType::Integer16 => ValueType::I16,
        DataType::Integer32 => ValueType::I32,
        DataType::Integer64 => ValueType::I64,
        DataType::Unsigned8 | DataType::Byte => ValueType::U8,
        DataType::Unsigned16 | DataType::Word => ValueType::U16,
        DataType::Unsigned32 | DataType::Dword => ValueType::U32,
        DataType::Unsigned64 => ValueType::U64,
        DataType::Real32 => ValueType::F32,
        DataType::Real64 => ValueType::F64,
        DataType::VisibleString => ValueType::String,
        _ => ValueType::Hex,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_typing_is_auto_or_a_type_name_and_junk_names_its_field() {
        assert_eq!("AUTO".parse::<Typing>().unwrap(), Typing::Auto);
        assert_eq!(
            " u16 ".parse::<Typing>().unwrap(),
            Typing::As(ValueType::U16)
        );
        let err = "u7".parse::<Typing>().unwrap_err();
        assert_eq!(err.field, Some("value_type"));
        assert!(err.message.contains("u7"), "{err:?}");
    }

    #[test]
    fn round_trips_and_range_checks() {
        for (ty, text) in [
            (ValueType::U16, "65535"),
            (ValueType::I32, "-5"),
            (ValueType::U32, "3758096385"),
            (ValueType::F32, "1.5"),
            (ValueType::Bool, "true"),
            (ValueType::String, "abc"),
            (ValueType::Hex, "0a0b"),
        ] {
            assert_eq!(
                decode(ty, &encode(ty, text).unwrap()).unwrap(),
                text,
                "{ty:?}"
            );
        }
        assert_eq!(
            encode(ValueType::U32, "0xe0000001").unwrap(),
            0xe000_0001u32.to_le_bytes()
        );
        assert!(encode(ValueType::U8, "256").is_err());
        assert!(encode(ValueType::I8, "-129").is_err());
        assert!(decode(ValueType::U16, &[1, 2, 3]).is_err());
        assert!("quad".parse::<ValueType>().is_err());
        // IgH's type names.
        assert_eq!("float".parse::<ValueType>().unwrap(), ValueType::F32);
        assert_eq!("double".parse::<ValueType>().unwrap(), ValueType::F64);
        assert_eq!("uint16".parse::<ValueType>().unwrap(), ValueType::U16);
        assert_eq!("octet_string".parse::<ValueType>().unwrap(), ValueType::Hex);
        assert_eq!(parse_idn("P-0-0100", "idn").unwrap(), 0x8064);
        assert_eq!(parse_idn("S-0-0011", "idn").unwrap(), 11);
        assert_eq!(parse_idn("0x8064", "idn").unwrap(), 0x8064);
        assert!(parse_idn("X-0-0011", "idn").is_err());
        assert_eq!(for_data_type(DataType::Unsigned32), ValueType::U32);
        assert_eq!(for_data_type(DataType::OctetString), ValueType::Hex);
    }
}
