//! SoE values as text, with the value types of CoE ([`super::value`]). An IDN's value element
//! is either fixed (2, 4 or 8 bytes) or of variable length: a list or a string, whose data
//! starts with its current and its maximum length in bytes, 16 bits each (ETG.1000.6, SoE
//! data element; spec-notes §soe). A string is read without that header and written with
//! it; every other type is the element's bytes as CoE's.

use super::value::{self, ValueType};
use crate::error::ApiError;

/// The value type a request names for an IDN: none when empty; `auto` is CoE's only (SoE
/// has no SDO Information to take it from).
pub fn parse_type(name: &str) -> Result<Option<ValueType>, ApiError> {
    let name = name.trim();
    if name.is_empty() {
        return Ok(None);
    }
    if name.eq_ignore_ascii_case("auto") {
        return Err(ApiError::invalid_field(
            "value_type",
            "SoE has no auto type: name one (u16, u32, i32, string, hex, ...)",
        ));
    }
    name.parse()
        .map(Some)
        .map_err(|err: ApiError| err.in_field("value_type"))
}

/// The text of an IDN's value element `bytes` read as `ty`.
pub fn decode(ty: ValueType, bytes: &[u8]) -> Result<String, ApiError> {
    if ty == ValueType::String
        && let Some(text) = variable(bytes)
    {
        return value::decode(ValueType::String, text);
    }
    value::decode(ty, bytes)
}

/// The value element for `text` as `ty`: a string gets its length header.
pub fn encode(ty: ValueType, text: &str) -> Result<Vec<u8>, ApiError> {
    let bytes = value::encode(ty, text).map_err(|err| err.in_field("value"))?;
    if ty != ValueType::String {
        return Ok(bytes);
    }
    let len = u16::try_from(bytes.len())
        .map_err(|_| ApiError::invalid_field("value", "a string of at most 65535 bytes"))?;
    let mut out = Vec::with_capacity(4 + bytes.len());
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(&bytes);
    Ok(out)
}

/// The data of a variable-length element, if `bytes` is one (its current length matches).
fn variable(bytes: &[u8]) -> Option<&[u8]> {
    let (header, data) = bytes.split_at_checked(4)?;
    let current = usize::from(u16::from_le_bytes([header[0], header[1]]));
    (current == data.len()).then_some(data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_string_travels_with_its_length_header_and_numbers_as_coe_s() {
        let element = encode(ValueType::String, "MKD071").unwrap();
        assert_eq!(element[..4], [6, 0, 6, 0]);
        assert_eq!(&element[4..], b"MKD071");
        assert_eq!(decode(ValueType::String, &element).unwrap(), "MKD071");
        // An element with a larger maximum, as a drive keeps it.
        let kept = [3, 0, 32, 0, b'a', b'b', b'c'];
        assert_eq!(decode(ValueType::String, &kept).unwrap(), "abc");
        assert_eq!(
            encode(ValueType::U32, "1000").unwrap(),
            1000u32.to_le_bytes()
        );
        assert_eq!(decode(ValueType::U16, &[0x10, 0x27]).unwrap(), "10000");
        let wrong = decode(ValueType::U32, &[1, 2]).unwrap_err();
        assert_eq!(wrong.kind, crate::error::ErrorKind::InvalidArgument);
        let bad = encode(ValueType::U16, "70000").unwrap_err();
        assert_eq!(bad.field, Some("value"));
        assert_eq!(parse_type("").unwrap(), None);
        assert_eq!(parse_type("uint32").unwrap(), Some(ValueType::U32));
        assert_eq!(parse_type("auto").unwrap_err().field, Some("value_type"));
        assert_eq!(parse_type("u7").unwrap_err().field, Some("value_type"));
    }
}
