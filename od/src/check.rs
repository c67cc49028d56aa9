//! Value checks shared by every dictionary: length against the type, value against the
//! declared minimum and maximum (ETG.1000.6, spec-notes §coe.abort: 0x06070012/13, 0x06090031/32).

use core::cmp::Ordering;

use ecat_wire::coe::AbortCode;

use super::dictionary::DictEntryInfo;
use super::value::{Number, decode_number};

/// Checks the bytes of a download against the entry: a fixed-size value must have exactly
/// ⌈bit length / 8⌉ bytes, a string or DOMAIN at most its maximum length; numbers must lie
/// within the declared minimum and maximum (and fit BITn).
pub fn check_value(info: &DictEntryInfo<'_>, data: &[u8]) -> Result<(), AbortCode> {
    if info.is_variable_length() {
        return if data.len() > info.max_len {
            Err(AbortCode::LengthTooHigh)
        } else {
            Ok(())
        };
    }
    match data.len().cmp(&info.fixed_len()) {
        Ordering::Greater => return Err(AbortCode::LengthTooHigh),
        Ordering::Less => return Err(AbortCode::LengthTooLow),
        Ordering::Equal => {}
    }
    let value = match decode_number(info.data_type, data) {
        Ok(Some(v)) => v,
        Ok(None) => return Ok(()),
        // Bits set above a BITn width: the value is too high for the type.
        Err(_) => return Err(AbortCode::ValueTooHigh),
    };
    let bound = |b: &Option<std::borrow::Cow<'_, [u8]>>| -> Option<Number> {
        b.as_deref()
            .and_then(|bytes| decode_number(info.data_type, bytes).ok().flatten())
    };
    if let Some(min) = bound(&info.minimum)
        && value < min
    {
        return Err(AbortCode::ValueTooLow);
    }
    if let Some(max) = bound(&info.maximum)
        && value > max
    {
        return Err(AbortCode::ValueTooHigh);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ecat_wire::coe::{DataType, ObjectAccess};
    use std::borrow::Cow;

    fn info(data_type: DataType, bits: u16) -> DictEntryInfo<'static> {
        DictEntryInfo {
            index: 0x2000,
            subindex: 0,
            name: Cow::Borrowed("x"),
            data_type,
            bit_length: bits,
            max_len: usize::from(bits).div_ceil(8),
            access: ObjectAccess::RW,
            unit: None,
            default: None,
            minimum: None,
            maximum: None,
        }
    }

    #[test]
    fn lengths_and_ranges() {
        let mut i = info(DataType::Integer16, 16);
        assert_eq!(check_value(&i, &[1]), Err(AbortCode::LengthTooLow));
        assert_eq!(check_value(&i, &[1, 2, 3]), Err(AbortCode::LengthTooHigh));
        i.minimum = Some(Cow::Owned((-10i16).to_le_bytes().to_vec()));
        i.maximum = Some(Cow::Owned(100i16.to_le_bytes().to_vec()));
        assert_eq!(check_value(&i, &(-10i16).to_le_bytes()), Ok(()));
        assert_eq!(
            check_value(&i, &(-11i16).to_le_bytes()),
            Err(AbortCode::ValueTooLow)
        );
        assert_eq!(
            check_value(&i, &101i16.to_le_bytes()),
            Err(AbortCode::ValueTooHigh)
        );
        let b = info(DataType::Bit2, 2);
        assert_eq!(check_value(&b, &[4]), Err(AbortCode::ValueTooHigh));
        let mut s = info(DataType::VisibleString, 64);
        s.max_len = 8;
        assert_eq!(check_value(&s, b"12345678"), Ok(()));
        assert_eq!(check_value(&s, b"123456789"), Err(AbortCode::LengthTooHigh));
    }
}
