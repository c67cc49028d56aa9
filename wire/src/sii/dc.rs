//! DC category, type 60: 24 bytes per operation mode (spec-notes §sii.categories, KickCAT's layout).
//!
//! ```text
//! 0x00 u32 SYNC0 cycle time | 0x04 u32 SYNC0 shift | 0x08 u32 SYNC1 shift
//! 0x0C i16 SYNC1 cycle factor | 0x0E u16 AssignActivate | 0x10 i16 SYNC0 cycle factor
//! 0x12 u8 name idx | 0x13 u8 description idx | 0x14 4 bytes reserved
//! ```

use core::fmt;

use crate::error::{Result, WireError, room};
use crate::field::{self, Field};

mod fields {
    use super::Field;
    pub const SYNC0_CYCLE: Field = 0x00..0x04;
    pub const SYNC0_SHIFT: Field = 0x04..0x08;
    pub const SYNC1_SHIFT: Field = 0x08..0x0C;
    pub const SYNC1_FACTOR: Field = 0x0C..0x0E;
    pub const ASSIGN_ACTIVATE: Field = 0x0E..0x10;
    pub const SYNC0_FACTOR: Field = 0x10..0x12;
    pub const NAME: usize = 0x12;
    pub const DESCRIPTION: usize = 0x13;
    pub const RESERVED: Field = 0x14..0x18;
}

/// Size of one DC entry.
pub const DC_ENTRY_LEN: usize = fields::RESERVED.end;

/// One DC operation mode. The reserved bytes are dropped (written 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct DcEntry {
    /// SYNC0 cycle time in ns (0 = use the master cycle).
    pub sync0_cycle: u32,
    /// SYNC0 shift time.
    pub sync0_shift: u32,
    /// SYNC1 shift time.
    pub sync1_shift: u32,
    /// SYNC1 cycle factor.
    pub sync1_cycle_factor: i16,
    /// AssignActivate (value for 0x0980/0x0981).
    pub assign_activate: u16,
    /// SYNC0 cycle factor.
    pub sync0_cycle_factor: i16,
    /// Name string index.
    pub name_idx: u8,
    /// Description string index.
    pub description_idx: u8,
}

impl DcEntry {
    /// Parses one 24-byte entry.
    pub fn parse(data: &[u8]) -> Result<Self> {
        crate::error::need("SII DC entry", data, DC_ENTRY_LEN)?;
        Ok(DcEntry {
            sync0_cycle: field::u32_le(data, fields::SYNC0_CYCLE.start),
            sync0_shift: field::u32_le(data, fields::SYNC0_SHIFT.start),
            sync1_shift: field::u32_le(data, fields::SYNC1_SHIFT.start),
            sync1_cycle_factor: field::u16_le(data, fields::SYNC1_FACTOR.start) as i16,
            assign_activate: field::u16_le(data, fields::ASSIGN_ACTIVATE.start),
            sync0_cycle_factor: field::u16_le(data, fields::SYNC0_FACTOR.start) as i16,
            name_idx: data[fields::NAME],
            description_idx: data[fields::DESCRIPTION],
        })
    }

    /// Writes one 24-byte entry.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        room("SII DC entry", buf, DC_ENTRY_LEN)?;
        field::set_u32_le(buf, fields::SYNC0_CYCLE.start, self.sync0_cycle);
        field::set_u32_le(buf, fields::SYNC0_SHIFT.start, self.sync0_shift);
        field::set_u32_le(buf, fields::SYNC1_SHIFT.start, self.sync1_shift);
        field::set_u16_le(
            buf,
            fields::SYNC1_FACTOR.start,
            self.sync1_cycle_factor as u16,
        );
        field::set_u16_le(buf, fields::ASSIGN_ACTIVATE.start, self.assign_activate);
        field::set_u16_le(
            buf,
            fields::SYNC0_FACTOR.start,
            self.sync0_cycle_factor as u16,
        );
        buf[fields::NAME] = self.name_idx;
        buf[fields::DESCRIPTION] = self.description_idx;
        buf[fields::RESERVED].fill(0);
        Ok(())
    }
}

impl fmt::Display for DcEntry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "DC mode #{} AssignActivate {:#06x} SYNC0 {} ns x{} shift {} SYNC1 x{} shift {}",
            self.name_idx,
            self.assign_activate,
            self.sync0_cycle,
            self.sync0_cycle_factor,
            self.sync0_shift,
            self.sync1_cycle_factor,
            self.sync1_shift
        )
    }
}

/// The parsed DC category.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Default)]
pub struct DcCategoryRepr {
    /// Operation modes.
    pub entries: Vec<DcEntry>,
}

impl DcCategoryRepr {
    /// Parses the category data; its length must be a multiple of 24 (`BadLength`).
    pub fn parse(data: &[u8]) -> Result<Self> {
        if !data.len().is_multiple_of(DC_ENTRY_LEN) {
            return Err(WireError::BadLength {
                what: "SII DC",
                declared: data.len(),
                available: data.len() - data.len() % DC_ENTRY_LEN,
            });
        }
        let entries = data
            .chunks_exact(DC_ENTRY_LEN)
            .map(DcEntry::parse)
            .collect::<Result<_>>()?;
        Ok(DcCategoryRepr { entries })
    }

    /// Data length.
    pub fn buffer_len(&self) -> usize {
        self.entries.len() * DC_ENTRY_LEN
    }

    /// Writes all entries.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        room("SII DC", buf, self.buffer_len())?;
        for (entry, out) in self.entries.iter().zip(buf.chunks_exact_mut(DC_ENTRY_LEN)) {
            entry.emit(out)?;
        }
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::Emit;
    use proptest::prelude::*;

    // An EL2262-like element (spec-notes §sii.categories): cycle/shift 0, SYNC1 factor −1, AssignActivate 0x0730,
    // SYNC0 factor −8, name index 7 ("DcSync2", index chosen by hand), description 0.
    static ENTRY: [u8; 24] = [
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, // times
        0xff, 0xff, // SYNC1 factor −1
        0x30, 0x07, // AssignActivate
        0xf8, 0xff, // SYNC0 factor −8
        0x07, 0x00, // name, description
        0x00, 0x00, 0x00, 0x00,
    ];

    #[test]
    fn by_hand() {
        let r = DcCategoryRepr::parse(&ENTRY).unwrap();
        let e = r.entries[0];
        assert_eq!((e.sync0_cycle, e.sync0_shift, e.sync1_shift), (0, 0, 0));
        assert_eq!(e.sync1_cycle_factor, -1);
        assert_eq!(e.assign_activate, 0x0730);
        assert_eq!(e.sync0_cycle_factor, -8);
        assert_eq!((e.name_idx, e.description_idx), (7, 0));
        let mut out = [0xa5u8; 24];
        r.emit(&mut out).unwrap();
        assert_eq!(out, ENTRY);
        assert!(DcCategoryRepr::parse(&ENTRY[..20]).is_err());
    }

    pub(crate) fn arb_entry() -> impl Strategy<Value = DcEntry> {
        (
            proptest::array::uniform3(any::<u32>()),
            any::<i16>(),
            any::<u16>(),
            any::<i16>(),
            any::<u8>(),
            any::<u8>(),
        )
            .prop_map(|(t, f1, aa, f0, n, d)| DcEntry {
                sync0_cycle: t[0],
                sync0_shift: t[1],
                sync1_shift: t[2],
                sync1_cycle_factor: f1,
                assign_activate: aa,
                sync0_cycle_factor: f0,
                name_idx: n,
                description_idx: d,
            })
    }

    proptest! {
        #[test]
        fn round_trip(entries in proptest::collection::vec(arb_entry(), 0..5)) {
            let r = DcCategoryRepr { entries };
            let buf = r.to_vec().unwrap();
            prop_assert_eq!(DcCategoryRepr::parse(&buf).unwrap(), r);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..60)) {
            if let Ok(r) = DcCategoryRepr::parse(&bytes) {
                for e in r.entries { let _ = e.to_string(); }
            }
        }
    }
}
