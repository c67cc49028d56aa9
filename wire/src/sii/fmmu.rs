//! FMMU category, type 40: one usage byte per FMMU (ETG.2010, spec-notes §sii.categories).
//!
//! Note the encoding differs from the FMMU type register (spec-notes §esc.fmmu): here 1 = outputs and
//! 2 = inputs.

use core::fmt;

use crate::error::{Result, WireError, room};
use crate::macros::enum_with_unknown;

enum_with_unknown! {
    /// What an FMMU channel is used for.
    pub enum FmmuUsage(u8) {
        /// 0x00: not used.
        NotUsed = 0x00,
        /// 0x01: process data outputs.
        Outputs = 0x01,
        /// 0x02: process data inputs.
        Inputs = 0x02,
        /// 0x03: SyncManager status (mailbox state polling).
        SyncManagerStatus = 0x03,
        /// 0xFF: not used (also the padding byte).
        Unused = 0xFF,
    }
}

impl FmmuUsage {
    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            FmmuUsage::NotUsed | FmmuUsage::Unused => "unused",
            FmmuUsage::Outputs => "outputs",
            FmmuUsage::Inputs => "inputs",
            FmmuUsage::SyncManagerStatus => "SM status",
            FmmuUsage::Unknown(_) => "unknown",
        }
    }
}

/// The parsed FMMU category: one entry per data byte, in FMMU order.
///
/// Parsing keeps every byte, padding included (padding reads as "unused"); emit pads an odd
/// count with 0xFF to a whole word.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Default)]
pub struct FmmuCategoryRepr {
    /// Usage of FMMU 0, 1, ...
    pub usages: Vec<FmmuUsage>,
}

impl FmmuCategoryRepr {
    /// Parses the category data.
    pub fn parse(data: &[u8]) -> Result<Self> {
        Ok(FmmuCategoryRepr {
            usages: data.iter().map(|&b| FmmuUsage::from(b)).collect(),
        })
    }

    /// Data length, padded to a word.
    pub fn buffer_len(&self) -> usize {
        self.usages.len() + self.usages.len() % 2
    }

    /// Writes the usage bytes and the padding; refuses a list too long for a category.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        let len = self.buffer_len();
        room("SII FMMU", buf, len)?;
        if len > usize::from(u16::MAX) * 2 {
            return Err(WireError::BadLength {
                what: "SII FMMU",
                declared: len,
                available: usize::from(u16::MAX) * 2,
            });
        }
        for (out, usage) in buf.iter_mut().zip(&self.usages) {
            *out = u8::from(*usage);
        }
        if !self.usages.len().is_multiple_of(2) {
            buf[len - 1] = u8::from(FmmuUsage::Unused);
        }
        Ok(())
    }
}

impl fmt::Display for FmmuCategoryRepr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("FMMU")?;
        for (n, u) in self.usages.iter().enumerate() {
            write!(f, " {n}:{}", u.name())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Emit;
    use proptest::prelude::*;

    #[test]
    fn el2262() {
        // ETG.2010, spec-notes §sii.categories: `01 01 02 ff` = outputs, outputs, inputs, unused.
        let data = [0x01, 0x01, 0x02, 0xff];
        let r = FmmuCategoryRepr::parse(&data).unwrap();
        assert_eq!(
            r.usages,
            [
                FmmuUsage::Outputs,
                FmmuUsage::Outputs,
                FmmuUsage::Inputs,
                FmmuUsage::Unused
            ]
        );
        let mut out = [0xa5u8; 4];
        r.emit(&mut out).unwrap();
        assert_eq!(out, data);
    }

    #[test]
    fn odd_count_is_padded() {
        let r = FmmuCategoryRepr {
            usages: vec![
                FmmuUsage::Outputs,
                FmmuUsage::Inputs,
                FmmuUsage::SyncManagerStatus,
            ],
        };
        let mut out = [0xa5u8; 4];
        r.emit(&mut out).unwrap();
        assert_eq!(out, [0x01, 0x02, 0x03, 0xff]);
        assert!(r.emit(&mut [0u8; 3]).is_err());
    }

    proptest! {
        #[test]
        fn round_trip(bytes in proptest::collection::vec(any::<u8>(), 0..16)) {
            let mut bytes = bytes;
            if bytes.len() % 2 == 1 { bytes.push(0xFF); }
            let r = FmmuCategoryRepr::parse(&bytes).unwrap();
            let out = r.to_vec().unwrap();
            prop_assert_eq!(&out, &bytes);
            prop_assert_eq!(FmmuCategoryRepr::parse(&out).unwrap(), r);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..16)) {
            let _ = FmmuCategoryRepr::parse(&bytes).map(|r| r.to_string());
        }
    }
}
