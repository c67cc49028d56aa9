//! TXPDO (type 50) and RXPDO (type 51) categories (ETG.2010, spec-notes §sii.categories).
//!
//! ```text
//! PDO header (8): 0 u16 index | 2 u8 entry count | 3 u8 SM | 4 u8 DC sync | 5 u8 name idx
//!                 6 u16 flags
//! entry (8):      0 u16 index | 2 u8 subindex | 3 u8 name idx | 4 u8 data type
//!                 5 u8 bit length | 6 u16 flags (reserved)
//! ```

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field::{self, Field};

mod fields {
    use super::Field;
    // PDO header.
    pub const PDO_INDEX: Field = 0..2;
    pub const PDO_COUNT: usize = 2;
    pub const PDO_SM: usize = 3;
    pub const PDO_DC_SYNC: usize = 4;
    pub const PDO_NAME: usize = 5;
    pub const PDO_FLAGS: Field = 6..8;
    // Entry.
    pub const ENTRY_INDEX: Field = 0..2;
    pub const ENTRY_SUBINDEX: usize = 2;
    pub const ENTRY_NAME: usize = 3;
    pub const ENTRY_TYPE: usize = 4;
    pub const ENTRY_BITS: usize = 5;
    pub const ENTRY_FLAGS: Field = 6..8;
}

/// Size of a PDO header.
pub const PDO_HEADER_LEN: usize = fields::PDO_FLAGS.end;
/// Size of a PDO entry.
pub const PDO_ENTRY_LEN: usize = fields::ENTRY_FLAGS.end;

/// PDO flags (header offset 6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct PdoFlags(pub u16);

impl PdoFlags {
    /// Mandatory.
    pub const MANDATORY: u16 = 0x0001;
    /// Default.
    pub const DEFAULT: u16 = 0x0002;
    /// Oversample.
    pub const OVERSAMPLE: u16 = 0x0004;
    /// Fixed content.
    pub const FIXED_CONTENT: u16 = 0x0010;
    /// Virtual content.
    pub const VIRTUAL_CONTENT: u16 = 0x0020;
    /// Download anyway.
    pub const DOWNLOAD_ANYWAY: u16 = 0x0040;
    /// From module.
    pub const FROM_MODULE: u16 = 0x0080;
    /// Module align.
    pub const MODULE_ALIGN: u16 = 0x0100;
    /// Depend on slot.
    pub const DEPEND_ON_SLOT: u16 = 0x0200;
    /// Depend on slot group.
    pub const DEPEND_ON_SLOT_GROUP: u16 = 0x0400;
    /// Overwritten by module.
    pub const OVERWRITTEN_BY_MODULE: u16 = 0x0800;
    /// Configurable.
    pub const CONFIGURABLE: u16 = 0x1000;
    /// Auto PDO name.
    pub const AUTO_PDO_NAME: u16 = 0x2000;
    /// Disable auto exclude.
    pub const DISABLE_AUTO_EXCLUDE: u16 = 0x4000;
    /// Writable.
    pub const WRITABLE: u16 = 0x8000;

    /// Whether all bits of `flag` are set.
    pub fn contains(self, flag: u16) -> bool {
        self.0 & flag == flag
    }
}

/// One PDO entry (a mapped object, or a gap when `index` is 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SiiPdoEntry {
    /// Object index; 0 = padding gap.
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
    /// Name string index.
    pub name_idx: u8,
    /// CoE data type code (low byte).
    pub data_type: u8,
    /// Bit length.
    pub bit_length: u8,
    /// Flags (reserved).
    pub flags: u16,
}

impl SiiPdoEntry {
    /// Whether this entry is a gap (index 0).
    pub fn is_gap(&self) -> bool {
        self.index == 0
    }

    fn parse(data: &[u8]) -> Self {
        SiiPdoEntry {
            index: field::u16_le(data, fields::ENTRY_INDEX.start),
            subindex: data[fields::ENTRY_SUBINDEX],
            name_idx: data[fields::ENTRY_NAME],
            data_type: data[fields::ENTRY_TYPE],
            bit_length: data[fields::ENTRY_BITS],
            flags: field::u16_le(data, fields::ENTRY_FLAGS.start),
        }
    }

    fn emit(&self, buf: &mut [u8]) {
        field::set_u16_le(buf, fields::ENTRY_INDEX.start, self.index);
        buf[fields::ENTRY_SUBINDEX] = self.subindex;
        buf[fields::ENTRY_NAME] = self.name_idx;
        buf[fields::ENTRY_TYPE] = self.data_type;
        buf[fields::ENTRY_BITS] = self.bit_length;
        field::set_u16_le(buf, fields::ENTRY_FLAGS.start, self.flags);
    }
}

impl fmt::Display for SiiPdoEntry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_gap() {
            write!(f, "gap {} bits", self.bit_length)
        } else {
            write!(
                f,
                "{:#06x}:{:02x} type {:#04x} {} bits",
                self.index, self.subindex, self.data_type, self.bit_length
            )
        }
    }
}

/// One PDO description with its entries.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Default)]
pub struct Pdo {
    /// PDO index (0x1A00.. Tx, 0x1600.. Rx).
    pub index: u16,
    /// SyncManager assigned by default (0xFF / bit 7 set = none).
    pub sync_manager: u8,
    /// DC sync.
    pub dc_sync: u8,
    /// Name string index.
    pub name_idx: u8,
    /// Flags.
    pub flags: PdoFlags,
    /// Entries (the count byte is derived from this on emit).
    pub entries: Vec<SiiPdoEntry>,
}

impl Pdo {
    /// The SyncManager this PDO is assigned to, if any.
    pub fn assigned_sm(&self) -> Option<u8> {
        (self.sync_manager & 0x80 == 0).then_some(self.sync_manager)
    }

    /// Sum of the entries' bit lengths.
    pub fn bit_length(&self) -> u32 {
        self.entries.iter().map(|e| u32::from(e.bit_length)).sum()
    }

    /// Bytes this PDO takes in the category.
    pub fn buffer_len(&self) -> usize {
        PDO_HEADER_LEN + self.entries.len() * PDO_ENTRY_LEN
    }
}

impl fmt::Display for Pdo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "PDO {:#06x} SM {} {} entries {} bits flags {:#06x}",
            self.index,
            self.sync_manager,
            self.entries.len(),
            self.bit_length(),
            self.flags.0
        )
    }
}

/// A parsed TXPDO or RXPDO category (the direction is the category type).
#[derive(Debug, Clone, PartialEq, Eq, Hash, Default)]
pub struct PdoCategoryRepr {
    /// PDOs in order.
    pub pdos: Vec<Pdo>,
}

impl PdoCategoryRepr {
    /// Parses the category data: PDO headers each followed by their entries, to the end.
    pub fn parse(data: &[u8]) -> Result<Self> {
        let mut pdos = Vec::new();
        let mut rest = data;
        while !rest.is_empty() {
            need("SII PDO header", rest, PDO_HEADER_LEN)?;
            let count = usize::from(rest[fields::PDO_COUNT]);
            let entries_len = count * PDO_ENTRY_LEN;
            let available = rest.len() - PDO_HEADER_LEN;
            if entries_len > available {
                return Err(WireError::BadLength {
                    what: "SII PDO entries",
                    declared: entries_len,
                    available,
                });
            }
            let (this, tail) = rest.split_at(PDO_HEADER_LEN + entries_len);
            pdos.push(Pdo {
                index: field::u16_le(this, fields::PDO_INDEX.start),
                sync_manager: this[fields::PDO_SM],
                dc_sync: this[fields::PDO_DC_SYNC],
                name_idx: this[fields::PDO_NAME],
                flags: PdoFlags(field::u16_le(this, fields::PDO_FLAGS.start)),
                entries: this[PDO_HEADER_LEN..]
                    .chunks_exact(PDO_ENTRY_LEN)
                    .map(SiiPdoEntry::parse)
                    .collect(),
            });
            rest = tail;
        }
        Ok(PdoCategoryRepr { pdos })
    }

    /// Data length.
    pub fn buffer_len(&self) -> usize {
        self.pdos.iter().map(Pdo::buffer_len).sum()
    }

    /// Writes all PDOs; refuses a PDO with more than 255 entries.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        if self
            .pdos
            .iter()
            .any(|p| p.entries.len() > usize::from(u8::MAX))
        {
            return Err(WireError::Invalid {
                what: "SII PDO",
                reason: "more than 255 entries",
            });
        }
        room("SII PDO", buf, self.buffer_len())?;
        let mut at = 0;
        for pdo in &self.pdos {
            let out = &mut buf[at..at + pdo.buffer_len()];
            field::set_u16_le(out, fields::PDO_INDEX.start, pdo.index);
            out[fields::PDO_COUNT] = pdo.entries.len() as u8;
            out[fields::PDO_SM] = pdo.sync_manager;
            out[fields::PDO_DC_SYNC] = pdo.dc_sync;
            out[fields::PDO_NAME] = pdo.name_idx;
            field::set_u16_le(out, fields::PDO_FLAGS.start, pdo.flags.0);
            for (e, chunk) in pdo
                .entries
                .iter()
                .zip(out[PDO_HEADER_LEN..].chunks_exact_mut(PDO_ENTRY_LEN))
            {
                e.emit(chunk);
            }
            at += pdo.buffer_len();
        }
        Ok(())
    }

    /// Total bits of the PDOs assigned to SyncManager `sm` (its process-data size, spec-notes §sii.categories).
    pub fn bits_for_sm(&self, sm: u8) -> u32 {
        self.pdos
            .iter()
            .filter(|p| p.assigned_sm() == Some(sm))
            .map(Pdo::bit_length)
            .sum()
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::Emit;
    use proptest::prelude::*;

    // spec-notes §sii.categories, EL2262 TXPDO: 0x1702, 1 entry, SM 2, DC sync 0, flags 0x0030, with entry
    // 0x1D09:0x98, UNSIGNED32 (0x07), 32 bits. String indices (5, 6) chosen by hand.
    static TXPDO: [u8; 16] = [
        0x02, 0x17, 0x01, 0x02, 0x00, 0x05, 0x30, 0x00, // header
        0x09, 0x1d, 0x98, 0x06, 0x07, 0x20, 0x00, 0x00, // entry
    ];
    // RXPDO 0x1600 (SM 0) with 0x7000:01 BOOLEAN 1 bit and a 7-bit gap.
    static RXPDO: [u8; 24] = [
        0x00, 0x16, 0x02, 0x00, 0x00, 0x07, 0x00, 0x00, // header
        0x00, 0x70, 0x01, 0x08, 0x01, 0x01, 0x00, 0x00, // Output0
        0x00, 0x00, 0x00, 0x00, 0x00, 0x07, 0x00, 0x00, // gap
    ];

    #[test]
    fn el2262_txpdo() {
        let r = PdoCategoryRepr::parse(&TXPDO).unwrap();
        let [pdo] = &r.pdos[..] else {
            panic!("one PDO expected")
        };
        assert_eq!(pdo.index, 0x1702);
        assert_eq!(pdo.assigned_sm(), Some(2));
        assert_eq!(pdo.dc_sync, 0);
        assert!(
            pdo.flags
                .contains(PdoFlags::FIXED_CONTENT | PdoFlags::VIRTUAL_CONTENT)
        );
        assert_eq!(
            pdo.entries,
            [SiiPdoEntry {
                index: 0x1D09,
                subindex: 0x98,
                name_idx: 6,
                data_type: 0x07,
                bit_length: 32,
                flags: 0
            }]
        );
        assert_eq!(r.bits_for_sm(2), 32);
        let mut out = [0xa5u8; 16];
        r.emit(&mut out).unwrap();
        assert_eq!(out, TXPDO);
    }

    #[test]
    fn el2262_rxpdo_with_gap() {
        let r = PdoCategoryRepr::parse(&RXPDO).unwrap();
        let pdo = &r.pdos[0];
        assert_eq!((pdo.index, pdo.assigned_sm()), (0x1600, Some(0)));
        assert_eq!((pdo.entries[0].index, pdo.entries[0].subindex), (0x7000, 1));
        assert_eq!(
            (pdo.entries[0].data_type, pdo.entries[0].bit_length),
            (0x01, 1)
        );
        assert!(pdo.entries[1].is_gap());
        assert_eq!(r.bits_for_sm(0), 8);
        let mut out = [0xa5u8; 24];
        r.emit(&mut out).unwrap();
        assert_eq!(out, RXPDO);
    }

    #[test]
    fn errors() {
        assert!(matches!(
            PdoCategoryRepr::parse(&RXPDO[..20]),
            Err(WireError::BadLength {
                declared: 16,
                available: 12,
                ..
            })
        ));
        assert!(matches!(
            PdoCategoryRepr::parse(&TXPDO[..4]),
            Err(WireError::Truncated { .. })
        ));
        let unassigned = Pdo {
            sync_manager: 0xFF,
            ..Default::default()
        };
        assert_eq!(unassigned.assigned_sm(), None);
        let big = PdoCategoryRepr {
            pdos: vec![Pdo {
                entries: vec![SiiPdoEntry::default(); 256],
                ..Default::default()
            }],
        };
        let mut buf = vec![0xa5u8; big.buffer_len()];
        assert!(big.emit(&mut buf).is_err());
        assert!(buf.iter().all(|&b| b == 0xa5));
    }

    pub(crate) fn arb_entry() -> impl Strategy<Value = SiiPdoEntry> {
        (
            any::<u16>(),
            proptest::array::uniform4(any::<u8>()),
            any::<u16>(),
        )
            .prop_map(|(index, b, flags)| SiiPdoEntry {
                index,
                subindex: b[0],
                name_idx: b[1],
                data_type: b[2],
                bit_length: b[3],
                flags,
            })
    }

    pub(crate) fn arb_pdo() -> impl Strategy<Value = Pdo> {
        (
            any::<u16>(),
            proptest::array::uniform3(any::<u8>()),
            any::<u16>(),
            proptest::collection::vec(arb_entry(), 0..6),
        )
            .prop_map(|(index, b, flags, entries)| Pdo {
                index,
                sync_manager: b[0],
                dc_sync: b[1],
                name_idx: b[2],
                flags: PdoFlags(flags),
                entries,
            })
    }

    proptest! {
        #[test]
        fn round_trip(pdos in proptest::collection::vec(arb_pdo(), 0..4)) {
            let r = PdoCategoryRepr { pdos };
            let buf = r.to_vec().unwrap();
            prop_assert_eq!(PdoCategoryRepr::parse(&buf).unwrap(), r);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..80)) {
            if let Ok(r) = PdoCategoryRepr::parse(&bytes) {
                for p in &r.pdos { let _ = p.to_string(); }
            }
        }
    }
}
