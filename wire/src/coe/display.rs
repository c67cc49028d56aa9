//! Small formatting helpers shared by the CoE `Display` implementations.

use core::fmt;

/// `0xIIII:SS`, the usual object address notation.
pub(crate) struct ObjAddr(pub u16, pub u8);

impl fmt::Display for ObjAddr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "0x{:04X}:{:02X}", self.0, self.1)
    }
}

/// Space-separated hex bytes in brackets, cut after 16 bytes.
pub(crate) struct Hex<'a>(pub &'a [u8]);

impl fmt::Display for Hex<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const SHOWN: usize = 16;
        f.write_str("[")?;
        for (i, b) in self.0.iter().take(SHOWN).enumerate() {
            if i > 0 {
                f.write_str(" ")?;
            }
            write!(f, "{b:02x}")?;
        }
        if self.0.len() > SHOWN {
            f.write_str(" …")?;
        }
        f.write_str("]")
    }
}

/// ASCII text with non-printable bytes shown as '.', for names in Display.
pub(crate) struct Ascii<'a>(pub &'a [u8]);

impl fmt::Display for Ascii<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use fmt::Write;
        for &b in self.0 {
            f.write_char(if b.is_ascii_graphic() || b == b' ' {
                char::from(b)
            } else {
                '.'
            })?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn helpers() {
        assert_eq!(Hex(&[0x02, 0, 0, 0]).to_string(), "[02 00 00 00]");
        assert_eq!(Hex(&[]).to_string(), "[]");
        let long = Hex(&[0u8; 17]).to_string();
        assert_eq!(long.matches("00").count(), 16);
        assert!(long.ends_with(" …]"));
        assert_eq!(ObjAddr(0x1c12, 1).to_string(), "0x1C12:01");
        assert_eq!(Ascii(b"Ab c\x00\xff").to_string(), "Ab c..");
    }
}
