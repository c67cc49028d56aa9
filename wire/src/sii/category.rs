//! The SII category list from word 0x40 (ETG.2010, spec-notes §sii.categories).
//!
//! ```text
//! u16 type | u16 size (words of data) | size × 2 bytes of data | next category ...
//! ... | 0xFFFF (END)
//! ```

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field::{self, Field, Rest};
use crate::macros::enum_with_unknown;

mod fields {
    use super::{Field, Rest};
    pub const TYPE: Field = 0..2;
    pub const SIZE: Field = 2..4;
    pub const DATA: Rest = 4..;
}

/// Size of a category header (type + size).
pub const CATEGORY_HEADER_LEN: usize = fields::DATA.start;

enum_with_unknown! {
    /// Category type (ETG.2010, spec-notes §sii.categories).
    pub enum CategoryType(u16) {
        /// 0: no operation, skip.
        Nop = 0,
        /// 10: strings.
        Strings = 10,
        /// 20: data types.
        DataTypes = 20,
        /// 30: general information.
        General = 30,
        /// 40: FMMU usage.
        Fmmu = 40,
        /// 41: SyncManager configuration.
        Syncm = 41,
        /// 42: FMMU extension (ETG.2010).
        FmmuEx = 42,
        /// 43: sync unit.
        SyncUnit = 43,
        /// 50: TxPDO descriptions (slave → master).
        TxPdo = 50,
        /// 51: RxPDO descriptions (master → slave).
        RxPdo = 51,
        /// 60: distributed clock operation modes.
        Dc = 60,
        /// 0xFFFF: end of the category list.
        End = 0xFFFF,
    }
}

impl CategoryType {
    /// Name in the standard's (and Wireshark's) spelling.
    pub fn name(self) -> &'static str {
        match self {
            CategoryType::Nop => "NOP",
            CategoryType::Strings => "STRINGS",
            CategoryType::DataTypes => "DataTypes",
            CategoryType::General => "GENERAL",
            CategoryType::Fmmu => "FMMU",
            CategoryType::Syncm => "SYNCM",
            CategoryType::FmmuEx => "FMMU_EX",
            CategoryType::SyncUnit => "SYNCUNIT",
            CategoryType::TxPdo => "TXPDO",
            CategoryType::RxPdo => "RXPDO",
            CategoryType::Dc => "DC",
            CategoryType::End => "END",
            CategoryType::Unknown(raw) if (1..=9).contains(&raw) => "device specific",
            CategoryType::Unknown(raw) if raw >= 0x0800 => "vendor specific",
            CategoryType::Unknown(_) => "unknown",
        }
    }

    /// Whether the type is in the vendor/device specific range 0x0800–0xFFFE (spec-notes §sii.categories; the
    /// sources disagree on the lower bound, this is the wider reading).
    pub fn is_vendor_specific(self) -> bool {
        matches!(u16::from(self), 0x0800..=0xFFFE)
    }
}

impl fmt::Display for CategoryType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CategoryType::Unknown(raw) => write!(f, "{} ({raw:#06x})", self.name()),
            known => f.write_str(known.name()),
        }
    }
}

/// View of one category: header plus the declared data.
#[derive(Debug, Clone)]
pub struct Category<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Category<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        Category { buffer }
    }

    /// Wraps a buffer and checks the header and declared data length.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let view = Self::new_unchecked(buffer);
        view.check_len()?;
        Ok(view)
    }

    /// Checks the header and that `size` words of data are present.
    pub fn check_len(&self) -> Result<()> {
        let buf = self.buffer.as_ref();
        need("SII category header", buf, CATEGORY_HEADER_LEN)?;
        let declared = self.data_len();
        let available = buf.len() - CATEGORY_HEADER_LEN;
        if declared > available {
            return Err(WireError::BadLength {
                what: "SII category size",
                declared,
                available,
            });
        }
        Ok(())
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Category type.
    pub fn category_type(&self) -> CategoryType {
        CategoryType::from(field::u16_le(self.buffer.as_ref(), fields::TYPE.start))
    }

    /// Size in words.
    pub fn size_words(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::SIZE.start)
    }

    /// Size of the data in bytes.
    pub fn data_len(&self) -> usize {
        usize::from(self.size_words()) * 2
    }

    /// The data (`size` words after the header).
    pub fn data(&self) -> &[u8] {
        &self.buffer.as_ref()[fields::DATA.start..CATEGORY_HEADER_LEN + self.data_len()]
    }

    /// Header plus data.
    pub fn total_len(&self) -> usize {
        CATEGORY_HEADER_LEN + self.data_len()
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Category<T> {
    /// Sets the type.
    pub fn set_category_type(&mut self, value: CategoryType) {
        field::set_u16_le(self.buffer.as_mut(), fields::TYPE.start, u16::from(value))
    }

    /// Sets the size in words.
    pub fn set_size_words(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::SIZE.start, value)
    }

    /// Mutable data.
    pub fn data_mut(&mut self) -> &mut [u8] {
        let end = CATEGORY_HEADER_LEN + self.data_len();
        &mut self.buffer.as_mut()[fields::DATA.start..end]
    }
}

/// A category: its type and its raw data (typed parsers live in the sibling modules).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CategoryRepr<'a> {
    /// Type.
    pub category_type: CategoryType,
    /// Data, an even number of bytes.
    pub data: &'a [u8],
}

impl<'a> CategoryRepr<'a> {
    /// Parses a checked view.
    pub fn parse(view: &Category<&'a [u8]>) -> Result<Self> {
        view.check_len()?;
        let buf: &'a [u8] = view.buffer;
        Ok(CategoryRepr {
            category_type: view.category_type(),
            data: &buf[fields::DATA.start..view.total_len()],
        })
    }

    /// Header plus data.
    pub fn buffer_len(&self) -> usize {
        CATEGORY_HEADER_LEN + self.data.len()
    }

    /// Writes header and data; refuses an odd data length or one beyond 0xFFFF words.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, view: &mut Category<T>) -> Result<()> {
        if !self.data.len().is_multiple_of(2) {
            return Err(WireError::Invalid {
                what: "SII category",
                reason: "data is not a whole number of words",
            });
        }
        let words = u16::try_from(self.data.len() / 2).map_err(|_| WireError::BadLength {
            what: "SII category size",
            declared: self.data.len() / 2,
            available: usize::from(u16::MAX),
        })?;
        room("SII category", view.buffer.as_ref(), self.buffer_len())?;
        view.set_category_type(self.category_type);
        view.set_size_words(words);
        view.data_mut().copy_from_slice(self.data);
        Ok(())
    }
}

impl fmt::Display for CategoryRepr<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "SII category {} ({} bytes)",
            self.category_type,
            self.data.len()
        )
    }
}

/// Iterator over the category list of `area` (the image from byte 128 on).
///
/// Yields every category except END, including NOP and unknown types (callers skip those by
/// type; the iterator has already skipped their data via the size field). Stops at END, at
/// the end of the image, or after the first error (a truncated header or a size beyond the
/// image, `BadLength`).
#[derive(Debug, Clone)]
pub struct CategoryIter<'a> {
    rest: &'a [u8],
    done: bool,
}

impl<'a> CategoryIter<'a> {
    /// Iterates over the categories at the start of `area`.
    pub fn new(area: &'a [u8]) -> Self {
        CategoryIter {
            rest: area,
            done: false,
        }
    }
}

impl<'a> Iterator for CategoryIter<'a> {
    type Item = Result<CategoryRepr<'a>>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        // Fewer than two bytes left: the image ended without END (allowed, spec-notes §sii.categories).
        if self.rest.len() < 2 {
            self.done = true;
            return None;
        }
        if field::u16_le(self.rest, fields::TYPE.start) == u16::from(CategoryType::End) {
            self.done = true;
            return None;
        }
        let view = Category::new_unchecked(self.rest);
        if let Err(e) = view.check_len() {
            self.done = true;
            return Some(Err(e));
        }
        let total = view.total_len();
        let (this, rest) = self.rest.split_at(total);
        self.rest = rest;
        Some(Ok(CategoryRepr {
            category_type: view.category_type(),
            data: &this[CATEGORY_HEADER_LEN..],
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Emit;
    use proptest::prelude::*;

    #[test]
    fn walks_and_skips() {
        // FMMU (2 words) `01 01 02 ff` as in the EL2262 dump (spec-notes §sii.categories), a vendor category
        // 0x0800 with 1 word, then END.
        let area = [
            0x28, 0x00, 0x02, 0x00, 0x01, 0x01, 0x02, 0xff, // FMMU
            0x00, 0x08, 0x01, 0x00, 0xaa, 0xbb, // vendor
            0xff, 0xff, 0x00, 0x00, // END
            0x0a, 0x00, // never reached
        ];
        let cats: Vec<_> = CategoryIter::new(&area).collect::<Result<_>>().unwrap();
        assert_eq!(cats.len(), 2);
        assert_eq!(cats[0].category_type, CategoryType::Fmmu);
        assert_eq!(cats[0].data, &[0x01, 0x01, 0x02, 0xff]);
        assert_eq!(cats[1].category_type, CategoryType::Unknown(0x0800));
        assert!(cats[1].category_type.is_vendor_specific());
        assert_eq!(cats[1].data, &[0xaa, 0xbb]);
    }

    #[test]
    fn end_of_image_without_end_marker() {
        let area = [0x28, 0x00, 0x01, 0x00, 0x01, 0x02];
        let cats: Vec<_> = CategoryIter::new(&area).collect();
        assert_eq!(cats.len(), 1);
        assert!(cats[0].is_ok());
        // A lone END type without its size word still ends the list.
        assert_eq!(CategoryIter::new(&[0xff, 0xff]).count(), 0);
    }

    #[test]
    fn size_beyond_image() {
        let area = [0x1e, 0x00, 0x10, 0x00, 0x00, 0x00];
        let mut it = CategoryIter::new(&area);
        assert_eq!(
            it.next(),
            Some(Err(WireError::BadLength {
                what: "SII category size",
                declared: 32,
                available: 2
            }))
        );
        assert_eq!(it.next(), None);
        // A header cut short.
        assert!(matches!(
            CategoryIter::new(&[0x1e, 0x00, 0x10]).next(),
            Some(Err(WireError::Truncated { .. }))
        ));
    }

    #[test]
    fn emit_refuses_odd() {
        let mut buf = [0xa5u8; 8];
        let bad = CategoryRepr {
            category_type: CategoryType::General,
            data: &[1, 2, 3],
        };
        assert!(
            bad.emit(&mut Category::new_unchecked(&mut buf[..]))
                .is_err()
        );
        assert_eq!(buf, [0xa5; 8]);
    }

    proptest! {
        #[test]
        fn round_trip(ty in 0u16..0xFFFF, words in proptest::collection::vec(any::<u16>(), 0..20)) {
            let data: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
            let repr = CategoryRepr { category_type: CategoryType::from(ty), data: &data };
            let buf = repr.to_vec().unwrap();
            let view = Category::new_checked(&buf[..]).unwrap();
            prop_assert_eq!(CategoryRepr::parse(&view).unwrap(), repr);
            let walked: Vec<_> = CategoryIter::new(&buf).collect::<Result<_>>().unwrap();
            prop_assert_eq!(walked, vec![repr]);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            for c in CategoryIter::new(&bytes) {
                let _ = c.map(|c| c.to_string());
            }
            if let Ok(view) = Category::new_checked(&bytes[..]) {
                let _ = CategoryRepr::parse(&view);
                let _ = view.data();
            }
        }
    }
}
