//! Get OD List service data (ETG.1000.6 SDO Information "Get OD List", spec-notes §coe.info).

use core::fmt;

use crate::field;
use crate::macros::enum_with_unknown;

enum_with_unknown! {
    /// Which list of objects is requested (u16; ETG.1000.6 list types 0-5, spec-notes §coe.info).
    pub enum OdListType(u16) {
        /// 0: the number of objects in each of lists 1-5 (five u16 counts).
        Lengths = 0,
        /// 1: all objects.
        All = 1,
        /// 2: RxPDO-mappable objects.
        RxPdoMappable = 2,
        /// 3: TxPDO-mappable objects.
        TxPdoMappable = 3,
        /// 4: objects stored for device replacement (backup).
        Backup = 4,
        /// 5: startup parameters (settings).
        Settings = 5,
    }
}

impl OdListType {
    /// Wireshark/ETG-style name of the list.
    pub fn name(self) -> &'static str {
        match self {
            OdListType::Lengths => "number of objects per list",
            OdListType::All => "all objects",
            OdListType::RxPdoMappable => "RxPDO mappable",
            OdListType::TxPdoMappable => "TxPDO mappable",
            OdListType::Backup => "backup objects",
            OdListType::Settings => "settings objects",
            OdListType::Unknown(_) => "unknown list",
        }
    }
}

impl fmt::Display for OdListType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OdListType::Unknown(raw) => write!(f, "list type {raw}"),
            known => f.write_str(known.name()),
        }
    }
}

/// The service data of one Get OD List response fragment: little-endian u16 words.
///
/// Only the *first* fragment starts with the list type word; continuation fragments hold
/// object indices only (IgH, SOES). A single fragment cannot tell which it is, so the bytes
/// are kept as they came; the client concatenates fragments and then calls
/// [`OdList::first_fragment`] on the first one or on the whole. A trailing odd byte (a
/// word split across fragments) is kept in [`OdList::raw`] and skipped by [`OdList::words`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct OdList<'a>(pub &'a [u8]);

impl<'a> OdList<'a> {
    /// The raw bytes.
    pub fn raw(&self) -> &'a [u8] {
        self.0
    }

    /// Number of complete words.
    pub fn len(&self) -> usize {
        self.0.len() / 2
    }

    /// Whether there is no complete word.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The complete words, in order.
    pub fn words(&self) -> impl Iterator<Item = u16> + 'a {
        self.0.chunks_exact(2).map(|pair| field::u16_le(pair, 0))
    }

    /// Splits a first fragment into its list type and the indices that follow.
    pub fn first_fragment(&self) -> Option<(OdListType, OdList<'a>)> {
        let head = self.0.get(..2)?;
        let rest = self.0.get(2..)?;
        Some((OdListType::from(field::u16_le(head, 0)), OdList(rest)))
    }
}

impl fmt::Display for OdList<'_> {
    /// `4 words [0x0001 0x1000 0x1008 0x1009]`, cut after 8 words.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const SHOWN: usize = 8;
        write!(f, "{} words [", self.len())?;
        for (i, w) in self.words().take(SHOWN).enumerate() {
            if i > 0 {
                f.write_str(" ")?;
            }
            write!(f, "{w:#06x}")?;
        }
        if self.len() > SHOWN {
            f.write_str(" …")?;
        }
        f.write_str("]")?;
        if self.0.len() % 2 == 1 {
            f.write_str(" +1 byte")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_and_first_fragment() {
        let data = [0x01, 0x00, 0x00, 0x10, 0x08, 0x10, 0x09, 0x10];
        let list = OdList(&data);
        assert_eq!(
            list.words().collect::<Vec<_>>(),
            [1, 0x1000, 0x1008, 0x1009]
        );
        let (ty, rest) = list.first_fragment().unwrap();
        assert_eq!(ty, OdListType::All);
        assert_eq!(rest.words().collect::<Vec<_>>(), [0x1000, 0x1008, 0x1009]);
        assert_eq!(list.to_string(), "4 words [0x0001 0x1000 0x1008 0x1009]");
        assert_eq!(OdList(&[0x01]).first_fragment(), None);
        assert_eq!(OdList(&[0x01, 0x02, 0x03]).len(), 1);
        assert_eq!(OdListType::from(5), OdListType::Settings);
        assert_eq!(OdListType::from(6), OdListType::Unknown(6));
    }
}
