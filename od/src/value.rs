//! Typed values ⇄ CoE bytes, by data type (ETG.1000.6, spec-notes §coe.types).
//!
//! Dictionaries store every value as the little-endian bytes that travel in an SDO transfer;
//! these helpers turn Rust values into those bytes and back, checking that the value fits
//! the CoE type (an `u32` of 70 000 does not fit UNSIGNED16, a negative number no unsigned
//! type). Integers convert across widths and signedness whenever the value fits, so
//! `5u8` can initialise an INTEGER32 entry.

use core::fmt;

use thiserror::Error;

use ecat_wire::coe::DataType;

/// Why a value could not be encoded into, or decoded from, the bytes of a CoE data type.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ValueError {
    /// The bytes have the wrong length for a fixed-size type.
    #[error("{data_type}: {got} bytes, {expected} expected")]
    Length {
        /// The CoE type.
        data_type: DataType,
        /// Bytes the type has.
        expected: usize,
        /// Bytes given.
        got: usize,
    },
    /// The value does not fit the type's range.
    #[error("{data_type}: value {value} out of range")]
    OutOfRange {
        /// The CoE type.
        data_type: DataType,
        /// The value, as text.
        value: String,
    },
    /// The Rust type cannot represent the CoE type (or the other way round).
    #[error("{data_type} cannot be converted to or from {rust_type}")]
    TypeMismatch {
        /// The CoE type.
        data_type: DataType,
        /// The Rust type.
        rust_type: &'static str,
    },
    /// VISIBLE_STRING holds ISO 646 (ASCII) text only.
    #[error("VISIBLE_STRING holds ASCII text only")]
    NotAscii,
    /// UNICODE_STRING bytes are not valid UTF-16LE.
    #[error("UNICODE_STRING is not valid UTF-16LE")]
    BadUnicode,
}

/// How the bytes of a data type are interpreted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TypeKind {
    /// BOOLEAN: one byte holding 0 or 1 (one bit in complete access and PDOs).
    Boolean,
    /// Unsigned integers, BYTE/WORD/DWORD, BITARRn and BITn, `bits` wide.
    Unsigned {
        /// Width in bits.
        bits: u16,
    },
    /// Two's complement integers, `bits` wide.
    Signed {
        /// Width in bits.
        bits: u16,
    },
    /// REAL32 (IEEE 754 single).
    Real32,
    /// REAL64 (IEEE 754 double).
    Real64,
    /// VISIBLE_STRING: variable length ASCII.
    VisibleString,
    /// OCTET_STRING: variable length bytes.
    OctetString,
    /// UNICODE_STRING: variable length UTF-16LE.
    UnicodeString,
    /// DOMAIN: variable length bytes, possibly large.
    Domain,
    /// Anything else (TIME_OF_DAY, GUID, records, unknown): bytes of the entry's bit length.
    Opaque,
}

impl TypeKind {
    /// Classifies a data type.
    pub fn of(data_type: DataType) -> TypeKind {
        use DataType::*;
        match data_type {
            Boolean => TypeKind::Boolean,
            Integer8 | Integer16 | Integer24 | Integer32 | Integer40 | Integer48 | Integer56
            | Integer64 => TypeKind::Signed {
                bits: data_type.bit_size().unwrap_or(64),
            },
            Unsigned8 | Unsigned16 | Unsigned24 | Unsigned32 | Unsigned40 | Unsigned48
            | Unsigned56 | Unsigned64 | Byte | Word | Dword | BitArr8 | BitArr16 | BitArr32
            | Bit1 | Bit2 | Bit3 | Bit4 | Bit5 | Bit6 | Bit7 | Bit8 | Bit9 | Bit10 | Bit11
            | Bit12 | Bit13 | Bit14 | Bit15 | Bit16 => TypeKind::Unsigned {
                bits: data_type.bit_size().unwrap_or(64),
            },
            Real32 => TypeKind::Real32,
            Real64 => TypeKind::Real64,
            VisibleString => TypeKind::VisibleString,
            OctetString => TypeKind::OctetString,
            UnicodeString => TypeKind::UnicodeString,
            Domain => TypeKind::Domain,
            _ => TypeKind::Opaque,
        }
    }

    /// Whether values of this kind have a variable length (strings and DOMAIN): such
    /// entries store up to a maximum length (complete access lays them out at that length).
    pub fn is_variable_length(self) -> bool {
        matches!(
            self,
            TypeKind::VisibleString
                | TypeKind::OctetString
                | TypeKind::UnicodeString
                | TypeKind::Domain
        )
    }
}

/// Whether entries of `data_type` have a variable length (strings, DOMAIN).
pub fn is_variable_length(data_type: DataType) -> bool {
    TypeKind::of(data_type).is_variable_length()
}

/// Bytes that hold a value of `bits` bits.
pub const fn bytes_for_bits(bits: u16) -> usize {
    (bits as usize).div_ceil(8)
}

/// Bytes of a fixed-size type, `None` for variable-length and opaque types.
fn fixed_len(data_type: DataType) -> Option<usize> {
    match TypeKind::of(data_type) {
        TypeKind::Boolean => Some(1),
        TypeKind::Unsigned { bits } | TypeKind::Signed { bits } => Some(bytes_for_bits(bits)),
        TypeKind::Real32 => Some(4),
        TypeKind::Real64 => Some(8),
        _ => None,
    }
}

/// A number decoded from the bytes of a numeric type, for range checks and conversions.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
pub enum Number {
    /// Any integer type or BOOLEAN.
    Int(i128),
    /// REAL32 or REAL64.
    Real(f64),
}

impl fmt::Display for Number {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Number::Int(v) => write!(f, "{v}"),
            Number::Real(v) => write!(f, "{v}"),
        }
    }
}

/// Decodes the bytes of a numeric type; `Ok(None)` for non-numeric types.
///
/// Integers must have exactly the type's byte length; a BITn value with bits above n set
/// is out of range.
pub fn decode_number(data_type: DataType, bytes: &[u8]) -> Result<Option<Number>, ValueError> {
    let kind = TypeKind::of(data_type);
    if let Some(expected) = fixed_len(data_type)
        && bytes.len() != expected
    {
        return Err(ValueError::Length {
            data_type,
            expected,
            got: bytes.len(),
        });
    }
    let mut raw = [0u8; 8];
    let n = bytes.len().min(8);
    raw[..n].copy_from_slice(&bytes[..n]);
    let unsigned = u64::from_le_bytes(raw);
    Ok(Some(match kind {
        TypeKind::Boolean => Number::Int(i128::from(unsigned != 0)),
        TypeKind::Unsigned { bits } => {
            if bits < 64 && unsigned >> bits != 0 {
                return Err(ValueError::OutOfRange {
                    data_type,
                    value: unsigned.to_string(),
                });
            }
            Number::Int(i128::from(unsigned))
        }
        TypeKind::Signed { bits } => {
            // Sign-extend from the type's width (INTEGER24 etc. are not native widths).
            let shift = 64 - u32::from(bits);
            Number::Int(i128::from(((unsigned << shift) as i64) >> shift))
        }
        TypeKind::Real32 => Number::Real(f64::from(f32::from_le_bytes([
            raw[0], raw[1], raw[2], raw[3],
        ]))),
        TypeKind::Real64 => Number::Real(f64::from_le_bytes(raw)),
        _ => return Ok(None),
    }))
}

/// Encodes an integer into the bytes of an integer type or BOOLEAN, checking its range.
pub fn encode_int(
    data_type: DataType,
    value: i128,
    rust_type: &'static str,
) -> Result<Vec<u8>, ValueError> {
    let (min, max, len) = match TypeKind::of(data_type) {
        TypeKind::Boolean => (0, 1, 1),
        TypeKind::Unsigned { bits } => (0, (1i128 << bits) - 1, bytes_for_bits(bits)),
        TypeKind::Signed { bits } => (
            -(1i128 << (bits - 1)),
            (1i128 << (bits - 1)) - 1,
            bytes_for_bits(bits),
        ),
        _ => {
            return Err(ValueError::TypeMismatch {
                data_type,
                rust_type,
            });
        }
    };
    if value < min || value > max {
        return Err(ValueError::OutOfRange {
            data_type,
            value: value.to_string(),
        });
    }
    // Two's complement little-endian, cut to the type's width.
    Ok(value.to_le_bytes()[..len].to_vec())
}

/// A Rust value that can be written into a dictionary entry of a given CoE type.
pub trait EncodeValue {
    /// The CoE bytes of `self` as a value of `data_type`.
    fn encode(&self, data_type: DataType) -> Result<Vec<u8>, ValueError>;
}

/// A Rust value that can be read from the bytes of a dictionary entry.
pub trait DecodeValue: Sized {
    /// Reads a value of `data_type` from its CoE bytes.
    fn decode(data_type: DataType, bytes: &[u8]) -> Result<Self, ValueError>;
}

macro_rules! integer_value {
    ($($t:ty),*) => {$(
        impl EncodeValue for $t {
            fn encode(&self, data_type: DataType) -> Result<Vec<u8>, ValueError> {
                encode_int(data_type, i128::from(*self), stringify!($t))
            }
        }

        impl DecodeValue for $t {
            fn decode(data_type: DataType, bytes: &[u8]) -> Result<Self, ValueError> {
                match decode_number(data_type, bytes)? {
                    Some(Number::Int(v)) => <$t>::try_from(v).map_err(|_| {
                        ValueError::OutOfRange { data_type, value: v.to_string() }
                    }),
                    _ => Err(ValueError::TypeMismatch { data_type, rust_type: stringify!($t) }),
                }
            }
        }
    )*};
}

integer_value!(u8, u16, u32, u64, i8, i16, i32, i64);

impl EncodeValue for bool {
    fn encode(&self, data_type: DataType) -> Result<Vec<u8>, ValueError> {
        encode_int(data_type, i128::from(*self), "bool")
    }
}

impl DecodeValue for bool {
    fn decode(data_type: DataType, bytes: &[u8]) -> Result<Self, ValueError> {
        match decode_number(data_type, bytes)? {
            Some(Number::Int(v)) if v == 0 || v == 1 || data_type == DataType::Boolean => {
                Ok(v != 0)
            }
            Some(Number::Int(v)) => Err(ValueError::OutOfRange {
                data_type,
                value: v.to_string(),
            }),
            _ => Err(ValueError::TypeMismatch {
                data_type,
                rust_type: "bool",
            }),
        }
    }
}

impl EncodeValue for f32 {
    fn encode(&self, data_type: DataType) -> Result<Vec<u8>, ValueError> {
        match data_type {
            DataType::Real32 => Ok(self.to_le_bytes().to_vec()),
            // Widening is exact.
            DataType::Real64 => Ok(f64::from(*self).to_le_bytes().to_vec()),
            _ => Err(ValueError::TypeMismatch {
                data_type,
                rust_type: "f32",
            }),
        }
    }
}

impl DecodeValue for f32 {
    fn decode(data_type: DataType, bytes: &[u8]) -> Result<Self, ValueError> {
        match (data_type, decode_number(data_type, bytes)?) {
            (DataType::Real32, Some(Number::Real(v))) => Ok(v as f32),
            _ => Err(ValueError::TypeMismatch {
                data_type,
                rust_type: "f32",
            }),
        }
    }
}

impl EncodeValue for f64 {
    fn encode(&self, data_type: DataType) -> Result<Vec<u8>, ValueError> {
        match data_type {
            DataType::Real64 => Ok(self.to_le_bytes().to_vec()),
            // Narrowing only when nothing is lost, so a stored value reads back equal.
            DataType::Real32 if f64::from(*self as f32) == *self || self.is_nan() => {
                Ok((*self as f32).to_le_bytes().to_vec())
            }
            DataType::Real32 => Err(ValueError::OutOfRange {
                data_type,
                value: self.to_string(),
            }),
            _ => Err(ValueError::TypeMismatch {
                data_type,
                rust_type: "f64",
            }),
        }
    }
}

impl DecodeValue for f64 {
    fn decode(data_type: DataType, bytes: &[u8]) -> Result<Self, ValueError> {
        match decode_number(data_type, bytes)? {
            Some(Number::Real(v)) => Ok(v),
            _ => Err(ValueError::TypeMismatch {
                data_type,
                rust_type: "f64",
            }),
        }
    }
}

impl EncodeValue for str {
    fn encode(&self, data_type: DataType) -> Result<Vec<u8>, ValueError> {
        match TypeKind::of(data_type) {
            TypeKind::VisibleString if !self.is_ascii() => Err(ValueError::NotAscii),
            TypeKind::VisibleString | TypeKind::OctetString | TypeKind::Domain => {
                Ok(self.as_bytes().to_vec())
            }
            TypeKind::UnicodeString => Ok(self.encode_utf16().flat_map(u16::to_le_bytes).collect()),
            _ => Err(ValueError::TypeMismatch {
                data_type,
                rust_type: "str",
            }),
        }
    }
}

impl EncodeValue for &str {
    fn encode(&self, data_type: DataType) -> Result<Vec<u8>, ValueError> {
        (**self).encode(data_type)
    }
}

impl EncodeValue for String {
    fn encode(&self, data_type: DataType) -> Result<Vec<u8>, ValueError> {
        self.as_str().encode(data_type)
    }
}

impl DecodeValue for String {
    /// Text up to the first NUL (devices often pad strings with NULs).
    fn decode(data_type: DataType, bytes: &[u8]) -> Result<Self, ValueError> {
        match TypeKind::of(data_type) {
            TypeKind::VisibleString | TypeKind::OctetString | TypeKind::Domain => {
                let text = bytes.split(|&b| b == 0).next().unwrap_or(&[]);
                if !text.is_ascii() && TypeKind::of(data_type) == TypeKind::VisibleString {
                    return Err(ValueError::NotAscii);
                }
                String::from_utf8(text.to_vec()).map_err(|_| ValueError::TypeMismatch {
                    data_type,
                    rust_type: "String",
                })
            }
            TypeKind::UnicodeString => {
                if !bytes.len().is_multiple_of(2) {
                    return Err(ValueError::BadUnicode);
                }
                let units = bytes
                    .chunks_exact(2)
                    .map(|p| u16::from_le_bytes([p[0], p[1]]))
                    .take_while(|&u| u != 0);
                char::decode_utf16(units)
                    .collect::<Result<String, _>>()
                    .map_err(|_| ValueError::BadUnicode)
            }
            _ => Err(ValueError::TypeMismatch {
                data_type,
                rust_type: "String",
            }),
        }
    }
}

impl EncodeValue for [u8] {
    /// Raw bytes: any variable-length type, or a fixed-size type when the length matches.
    fn encode(&self, data_type: DataType) -> Result<Vec<u8>, ValueError> {
        if let Some(expected) = fixed_len(data_type)
            && self.len() != expected
        {
            return Err(ValueError::Length {
                data_type,
                expected,
                got: self.len(),
            });
        }
        if TypeKind::of(data_type) == TypeKind::VisibleString && !self.is_ascii() {
            return Err(ValueError::NotAscii);
        }
        Ok(self.to_vec())
    }
}

impl EncodeValue for &[u8] {
    fn encode(&self, data_type: DataType) -> Result<Vec<u8>, ValueError> {
        (**self).encode(data_type)
    }
}

impl<const N: usize> EncodeValue for [u8; N] {
    fn encode(&self, data_type: DataType) -> Result<Vec<u8>, ValueError> {
        self.as_slice().encode(data_type)
    }
}

impl EncodeValue for Vec<u8> {
    fn encode(&self, data_type: DataType) -> Result<Vec<u8>, ValueError> {
        self.as_slice().encode(data_type)
    }
}

impl DecodeValue for Vec<u8> {
    /// The raw bytes of any type.
    fn decode(_data_type: DataType, bytes: &[u8]) -> Result<Self, ValueError> {
        Ok(bytes.to_vec())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integers_fit_or_fail() {
        assert_eq!(5u8.encode(DataType::Integer32).unwrap(), [5, 0, 0, 0]);
        assert_eq!(
            (-2i16).encode(DataType::Integer24).unwrap(),
            [0xfe, 0xff, 0xff]
        );
        assert_eq!(
            0x12_3456u32.encode(DataType::Unsigned24).unwrap(),
            [0x56, 0x34, 0x12]
        );
        assert!(matches!(
            70_000u32.encode(DataType::Unsigned16),
            Err(ValueError::OutOfRange { .. })
        ));
        assert!(matches!(
            (-1i32).encode(DataType::Unsigned8),
            Err(ValueError::OutOfRange { .. })
        ));
        assert!(matches!(
            4u8.encode(DataType::Bit2),
            Err(ValueError::OutOfRange { .. })
        ));
        assert!(matches!(
            1u8.encode(DataType::VisibleString),
            Err(ValueError::TypeMismatch { .. })
        ));
        assert_eq!(
            i32::decode(DataType::Integer24, &[0xfe, 0xff, 0xff]).unwrap(),
            -2
        );
        assert_eq!(
            u64::decode(DataType::Unsigned64, &u64::MAX.to_le_bytes()).unwrap(),
            u64::MAX
        );
        assert!(matches!(
            u8::decode(DataType::Unsigned16, &[0x00, 0x01]),
            Err(ValueError::OutOfRange { .. })
        ));
        assert!(matches!(
            u16::decode(DataType::Unsigned16, &[1]),
            Err(ValueError::Length {
                expected: 2,
                got: 1,
                ..
            })
        ));
    }

    #[test]
    fn bools_reals_strings() {
        assert_eq!(true.encode(DataType::Boolean).unwrap(), [1]);
        assert!(bool::decode(DataType::Boolean, &[1]).unwrap());
        assert_eq!(
            1.5f32.encode(DataType::Real32).unwrap(),
            1.5f32.to_le_bytes()
        );
        assert_eq!(
            f64::decode(DataType::Real32, &1.5f32.to_le_bytes()).unwrap(),
            1.5
        );
        assert!(0.1f64.encode(DataType::Real32).is_err());
        assert_eq!("ab".encode(DataType::VisibleString).unwrap(), b"ab");
        assert_eq!(
            ValueError::NotAscii,
            "µ".encode(DataType::VisibleString).unwrap_err()
        );
        assert_eq!(
            String::decode(DataType::VisibleString, b"EL2004\0\0").unwrap(),
            "EL2004"
        );
        let wide = "µs".encode(DataType::UnicodeString).unwrap();
        assert_eq!(wide, [0xb5, 0x00, b's', 0x00]);
        assert_eq!(
            String::decode(DataType::UnicodeString, &wide).unwrap(),
            "µs"
        );
        assert!(String::decode(DataType::UnicodeString, &[0]).is_err());
        assert!(matches!(
            [1u8, 2, 3].encode(DataType::Unsigned16),
            Err(ValueError::Length { .. })
        ));
    }
}
