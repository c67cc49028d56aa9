//! STRINGS category, type 10 (ETG.2010, spec-notes §sii.categories).
//!
//! ```text
//! u8 count N | N × (u8 length L | L bytes, no terminator) | pad to an even byte count
//! ```
//! Other categories refer to strings by **1-based** index; index 0 means "no string".

use core::fmt;

use crate::error::{Result, WireError, room};

/// The string table of an SII image, borrowing the category data.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Default)]
pub struct StringsRepr<'a> {
    /// The strings in order; `strings[0]` has index 1.
    pub strings: Vec<&'a [u8]>,
}

impl<'a> StringsRepr<'a> {
    /// Parses the category data. Empty data is an empty table; trailing padding is ignored;
    /// a string running past the data is `BadLength`.
    pub fn parse(data: &'a [u8]) -> Result<Self> {
        let Some((&count, mut rest)) = data.split_first() else {
            return Ok(StringsRepr::default());
        };
        let mut strings = Vec::with_capacity(usize::from(count));
        for _ in 0..count {
            let Some((&len, tail)) = rest.split_first() else {
                return Err(WireError::Truncated {
                    what: "SII string length",
                    need: 1,
                    have: 0,
                });
            };
            let len = usize::from(len);
            if len > tail.len() {
                return Err(WireError::BadLength {
                    what: "SII string",
                    declared: len,
                    available: tail.len(),
                });
            }
            let (s, tail) = tail.split_at(len);
            strings.push(s);
            rest = tail;
        }
        Ok(StringsRepr { strings })
    }

    /// The string with 1-based `index`; `None` for 0 or an index past the table.
    pub fn get(&self, index: u8) -> Option<&'a [u8]> {
        let i = usize::from(index).checked_sub(1)?;
        self.strings.get(i).copied()
    }

    /// The string with 1-based `index` as text, if it is valid UTF-8 (ASCII in practice).
    pub fn get_str(&self, index: u8) -> Option<&'a str> {
        core::str::from_utf8(self.get(index)?).ok()
    }

    /// Data length including the count byte and padding to an even byte count.
    pub fn buffer_len(&self) -> usize {
        let raw = 1 + self.strings.iter().map(|s| 1 + s.len()).sum::<usize>();
        raw + raw % 2
    }

    /// Writes the category data (padding byte 0); refuses more than 255 strings or a string
    /// longer than 255 bytes.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        let count = u8::try_from(self.strings.len()).map_err(|_| WireError::Invalid {
            what: "SII strings",
            reason: "more than 255 strings",
        })?;
        if self.strings.iter().any(|s| s.len() > usize::from(u8::MAX)) {
            return Err(WireError::Invalid {
                what: "SII strings",
                reason: "string longer than 255 bytes",
            });
        }
        let len = self.buffer_len();
        room("SII strings", buf, len)?;
        let out = &mut buf[..len];
        out[0] = count;
        let mut at = 1;
        for s in &self.strings {
            out[at] = s.len() as u8;
            out[at + 1..at + 1 + s.len()].copy_from_slice(s);
            at += 1 + s.len();
        }
        out[at..].fill(0);
        Ok(())
    }
}

impl fmt::Display for StringsRepr<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "STRINGS {}", self.strings.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Emit;
    use proptest::prelude::*;

    // Two strings "EL2004" and "DcSync" (names from spec-notes §sii.categories), laid out by hand:
    // count 2, len 6 "EL2004", len 6 "DcSync", 1 pad byte → 16 bytes.
    static DATA: [u8; 16] = [
        0x02, 0x06, b'E', b'L', b'2', b'0', b'0', b'4', 0x06, b'D', b'c', b'S', b'y', b'n', b'c',
        0x00,
    ];

    #[test]
    fn parse_by_hand() {
        let s = StringsRepr::parse(&DATA).unwrap();
        assert_eq!(s.get(0), None);
        assert_eq!(s.get_str(1), Some("EL2004"));
        assert_eq!(s.get_str(2), Some("DcSync"));
        assert_eq!(s.get(3), None);
        assert_eq!(s.buffer_len(), 16);
        let mut out = [0xa5u8; 16];
        s.emit(&mut out).unwrap();
        assert_eq!(out, DATA);
    }

    #[test]
    fn errors() {
        assert!(matches!(
            StringsRepr::parse(&DATA[..10]),
            Err(WireError::BadLength {
                declared: 6,
                available: 1,
                ..
            })
        ));
        assert!(StringsRepr::parse(&[0x02, 0x00]).is_err());
        assert_eq!(StringsRepr::parse(&[]).unwrap().strings.len(), 0);
        let long = [b'x'; 256];
        let bad = StringsRepr {
            strings: vec![&long[..]],
        };
        let mut buf = [0xa5u8; 300];
        assert!(bad.emit(&mut buf).is_err());
        assert!(buf.iter().all(|&b| b == 0xa5));
    }

    proptest! {
        #[test]
        fn round_trip(strings in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..20), 0..10)) {
            let repr = StringsRepr { strings: strings.iter().map(|s| &s[..]).collect() };
            let buf = repr.to_vec().unwrap();
            prop_assert_eq!(buf.len() % 2, 0);
            prop_assert_eq!(StringsRepr::parse(&buf).unwrap(), repr);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..64), i in any::<u8>()) {
            if let Ok(s) = StringsRepr::parse(&bytes) {
                let _ = s.get_str(i);
            }
        }
    }
}
