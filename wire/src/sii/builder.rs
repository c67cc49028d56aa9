//! `SiiBuilder`: emits a complete, valid SII image (spec-notes §sii) — used by the simulator to
//! give its slaves an EEPROM.

use super::category::{CATEGORY_HEADER_LEN, Category, CategoryRepr, CategoryType};
use super::dc::{DcCategoryRepr, DcEntry};
use super::fixed::{FIXED_LEN, SiiFixed, SiiFixedRepr};
use super::fmmu::{FmmuCategoryRepr, FmmuUsage};
use super::general::GeneralRepr;
use super::image::SiiImage;
use super::pdo::{Pdo, PdoCategoryRepr};
use super::strings::StringsRepr;
use super::syncm::{SyncmCategoryRepr, SyncmEntry};
use crate::Emit;
use crate::error::{Result, WireError};

/// Default minimum EEPROM size: 2 KiB (size word 0x000F, like simple Beckhoff terminals).
pub const DEFAULT_MIN_EEPROM_BYTES: usize = 2048;

/// Builds an SII image from representations.
///
/// The image is: the fixed area (checksum computed, size word derived from the EEPROM size),
/// then STRINGS, GENERAL, FMMU, SYNCM, TXPDO, RXPDO, DC and the extra categories (each
/// omitted when empty), then END; the rest of the EEPROM is 0xFF like an erased part. The
/// EEPROM size is the smallest power of two holding everything, at least
/// `min_eeprom_bytes`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SiiBuilder {
    /// Fixed area; `size_word` is overwritten by [`SiiBuilder::build`].
    pub fixed: SiiFixedRepr,
    /// String table (index 1 = `strings[0]`).
    pub strings: Vec<Vec<u8>>,
    /// GENERAL.
    pub general: Option<GeneralRepr>,
    /// FMMU usage.
    pub fmmu: Vec<FmmuUsage>,
    /// SyncManagers.
    pub syncm: Vec<SyncmEntry>,
    /// TxPDOs.
    pub txpdo: Vec<Pdo>,
    /// RxPDOs.
    pub rxpdo: Vec<Pdo>,
    /// DC operation modes.
    pub dc: Vec<DcEntry>,
    /// Further raw categories (type, data with an even length), written after the rest.
    pub extra: Vec<(CategoryType, Vec<u8>)>,
    /// Minimum EEPROM size in bytes.
    pub min_eeprom_bytes: usize,
}

impl SiiBuilder {
    /// A builder with the given fixed area and no categories.
    pub fn new(fixed: SiiFixedRepr) -> Self {
        SiiBuilder {
            fixed,
            strings: Vec::new(),
            general: None,
            fmmu: Vec::new(),
            syncm: Vec::new(),
            txpdo: Vec::new(),
            rxpdo: Vec::new(),
            dc: Vec::new(),
            extra: Vec::new(),
            min_eeprom_bytes: DEFAULT_MIN_EEPROM_BYTES,
        }
    }

    /// The 1-based index of `s`, adding it to the table if it is not there yet; refuses a
    /// 256th string or one longer than 255 bytes.
    pub fn add_string(&mut self, s: &str) -> Result<u8> {
        if let Some(i) = self.strings.iter().position(|t| t == s.as_bytes()) {
            return u8::try_from(i + 1).map_err(|_| too_many_strings());
        }
        if s.len() > usize::from(u8::MAX) {
            return Err(WireError::Invalid {
                what: "SII builder",
                reason: "string longer than 255 bytes",
            });
        }
        let index = u8::try_from(self.strings.len() + 1).map_err(|_| too_many_strings())?;
        self.strings.push(s.as_bytes().to_vec());
        Ok(index)
    }

    /// A builder holding everything a parsed image holds (strings copied).
    pub fn from_image(image: &SiiImage<'_>) -> Self {
        SiiBuilder {
            fixed: image.fixed,
            strings: image.strings.strings.iter().map(|s| s.to_vec()).collect(),
            general: image.general,
            fmmu: image.fmmu.clone(),
            syncm: image.syncm.clone(),
            txpdo: image.txpdo.clone(),
            rxpdo: image.rxpdo.clone(),
            dc: image.dc.clone(),
            extra: image
                .other
                .iter()
                .map(|c| (c.category_type, c.data.to_vec()))
                .collect(),
            min_eeprom_bytes: DEFAULT_MIN_EEPROM_BYTES,
        }
    }

    /// The category list (type, data) in image order.
    fn categories(&self) -> Result<Vec<(CategoryType, Vec<u8>)>> {
        let mut cats = Vec::new();
        if !self.strings.is_empty() {
            let repr = StringsRepr {
                strings: self.strings.iter().map(|s| &s[..]).collect(),
            };
            let data = repr.to_vec()?;
            cats.push((CategoryType::Strings, data));
        }
        if let Some(general) = &self.general {
            let data = general.to_vec()?;
            cats.push((CategoryType::General, data));
        }
        if !self.fmmu.is_empty() {
            let repr = FmmuCategoryRepr {
                usages: self.fmmu.clone(),
            };
            let data = repr.to_vec()?;
            cats.push((CategoryType::Fmmu, data));
        }
        if !self.syncm.is_empty() {
            let repr = SyncmCategoryRepr {
                entries: self.syncm.clone(),
            };
            let data = repr.to_vec()?;
            cats.push((CategoryType::Syncm, data));
        }
        for (ty, pdos) in [
            (CategoryType::TxPdo, &self.txpdo),
            (CategoryType::RxPdo, &self.rxpdo),
        ] {
            if !pdos.is_empty() {
                let repr = PdoCategoryRepr { pdos: pdos.clone() };
                let data = repr.to_vec()?;
                cats.push((ty, data));
            }
        }
        if !self.dc.is_empty() {
            let repr = DcCategoryRepr {
                entries: self.dc.clone(),
            };
            let data = repr.to_vec()?;
            cats.push((CategoryType::Dc, data));
        }
        for (ty, data) in &self.extra {
            if *ty == CategoryType::End {
                return Err(WireError::Invalid {
                    what: "SII builder",
                    reason: "END cannot be an extra category",
                });
            }
            cats.push((*ty, data.clone()));
        }
        Ok(cats)
    }

    /// Emits the complete image.
    pub fn build(&self) -> Result<Vec<u8>> {
        let cats = self.categories()?;
        let used = FIXED_LEN
            + cats
                .iter()
                .map(|(_, d)| CATEGORY_HEADER_LEN + d.len())
                .sum::<usize>()
            + 2; // END
        let size = used.max(self.min_eeprom_bytes).next_power_of_two();
        let size_word = SiiFixedRepr::size_word_for(size).ok_or(WireError::BadLength {
            what: "SII image",
            declared: size,
            available: (usize::from(u16::MAX) + 1) * 128,
        })?;
        let mut image = vec![0xFFu8; size];
        let fixed = SiiFixedRepr {
            size_word,
            ..self.fixed
        };
        fixed.emit(&mut SiiFixed::new_unchecked(&mut image[..FIXED_LEN]))?;
        let mut at = FIXED_LEN;
        for (ty, data) in &cats {
            let repr = CategoryRepr {
                category_type: *ty,
                data,
            };
            let len = repr.buffer_len();
            repr.emit(&mut Category::new_unchecked(&mut image[at..at + len]))?;
            at += len;
        }
        // END: type 0xFFFF; the erased fill after it is 0xFF already, written for clarity.
        image[at..at + 2].copy_from_slice(&u16::from(CategoryType::End).to_le_bytes());
        Ok(image)
    }
}

fn too_many_strings() -> WireError {
    WireError::Invalid {
        what: "SII builder",
        reason: "more than 255 strings",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sii::fixed::{MailboxProtocols, SiiMailboxArea};
    use crate::sii::general::{CoeDetails, PhysicalPorts};
    use crate::sii::pdo::{PdoFlags, SiiPdoEntry};
    use crate::sii::syncm::{SyncmEnable, SyncmType};
    use proptest::prelude::*;

    fn el2262_like() -> SiiBuilder {
        let mut b = SiiBuilder::new(SiiFixedRepr {
            pdi_control: 0x0506,
            alias: 0,
            vendor_id: 2,
            product_code: 0x08D6_3052,
            revision: 0x0010_0000,
            version: 1,
            ..Default::default()
        });
        let name = b.add_string("EL2262").unwrap();
        let group = b.add_string("DigOut").unwrap();
        let out0 = b.add_string("Output0").unwrap();
        let start = b.add_string("StartTimeNextOutput").unwrap();
        let sync = b.add_string("DcSync").unwrap();
        assert_eq!(b.add_string("EL2262").unwrap(), name, "deduplicated");
        b.general = Some(GeneralRepr {
            group_idx: group,
            order_idx: name,
            name_idx: name,
            ebus_current_ma: 70,
            physical_ports: PhysicalPorts(0x0033),
            ..Default::default()
        });
        b.fmmu = vec![
            FmmuUsage::Outputs,
            FmmuUsage::Outputs,
            FmmuUsage::Inputs,
            FmmuUsage::Unused,
        ];
        b.syncm = vec![
            SyncmEntry {
                start: 0x1000,
                length: 0,
                control: 0x64,
                status: 0,
                enable: SyncmEnable(0x09),
                sm_type: SyncmType::Outputs,
            },
            SyncmEntry {
                start: 0x0998,
                length: 0,
                control: 0,
                status: 0,
                enable: SyncmEnable(0x04),
                sm_type: SyncmType::Inputs,
            },
        ];
        b.txpdo = vec![Pdo {
            index: 0x1702,
            sync_manager: 2,
            dc_sync: 0,
            name_idx: 0,
            flags: PdoFlags(0x0030),
            entries: vec![SiiPdoEntry {
                index: 0x1D09,
                subindex: 0x98,
                name_idx: start,
                data_type: 0x07,
                bit_length: 32,
                flags: 0,
            }],
        }];
        b.rxpdo = vec![Pdo {
            index: 0x1600,
            sync_manager: 0,
            dc_sync: 0,
            name_idx: out0,
            flags: PdoFlags(0),
            entries: vec![SiiPdoEntry {
                index: 0x7000,
                subindex: 1,
                name_idx: out0,
                data_type: 0x01,
                bit_length: 1,
                flags: 0,
            }],
        }];
        b.dc = vec![DcEntry {
            sync1_cycle_factor: -1,
            assign_activate: 0x0730,
            sync0_cycle_factor: -1,
            name_idx: sync,
            ..Default::default()
        }];
        b
    }

    #[test]
    fn build_then_parse() {
        let b = el2262_like();
        let image = b.build().unwrap();
        assert_eq!(image.len(), 2048);
        // Word 0x3E = 0x000F (2 KiB), word 7 = CRC, high byte 0.
        assert_eq!(&image[124..126], &[0x0f, 0x00]);
        assert_eq!(image[15], 0x00);
        // The first category at word 0x40 is STRINGS (type 10).
        assert_eq!(&image[128..130], &[0x0a, 0x00]);
        let sii = SiiImage::parse(&image).unwrap();
        assert!(sii.checksum_ok);
        assert_eq!(sii.name(), Some("EL2262"));
        assert_eq!(sii.group(), Some("DigOut"));
        assert_eq!(
            sii.string(sii.txpdo[0].entries[0].name_idx),
            Some("StartTimeNextOutput")
        );
        assert_eq!(sii.pdo_name(&sii.rxpdo[0]), Some("Output0"));
        assert_eq!(sii.syncm[0].effective_type(), SyncmType::Outputs);
        let mut expected = b.clone();
        expected.fixed.size_word = 0x000F;
        assert_eq!(SiiBuilder::from_image(&sii), expected);
        // Rebuilding the parsed image gives the same bytes.
        assert_eq!(SiiBuilder::from_image(&sii).build().unwrap(), image);
    }

    #[test]
    fn hand_made_image() {
        // EL2004-like fixed area (spec-notes §sii.fixed) + GENERAL (§sii.categories) + END, laid out by hand.
        let mut image = vec![0u8; 128];
        image[..16].copy_from_slice(&[
            0x04, 0x01, 0x00, 0x00, 0x00, 0x00, 0x0f, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
            0xd8, 0x00,
        ]);
        image[124..128].copy_from_slice(&[0x0f, 0x00, 0x01, 0x00]);
        image.extend_from_slice(&[0x1e, 0x00, 0x10, 0x00]); // GENERAL, 16 words
        image.extend_from_slice(&[
            0x02, 0x00, 0x01, 0x04, 0x0c, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x64, 0x00,
            0x03, 0x00, 0x33, 0x00,
        ]);
        image.extend_from_slice(&[0u8; 14]);
        image.extend_from_slice(&[0x00, 0x00, 0x01, 0x00, 0xaa, 0xbb]); // NOP, 1 word
        image.extend_from_slice(&[0x2a, 0x00, 0x02, 0x00, 0xfe, 0xff, 0x00, 0x00]); // FMMU_EX
        image.extend_from_slice(&[0xff, 0xff, 0xff, 0xff]);
        let sii = SiiImage::parse(&image).unwrap();
        assert!(sii.checksum_ok);
        assert_eq!(sii.fixed.pdi_control, 0x0104);
        let g = sii.general.unwrap();
        assert_eq!(g.ebus_current_ma, 100);
        assert_eq!(g.coe_details, CoeDetails(0));
        assert_eq!(sii.name(), None, "no STRINGS category");
        assert_eq!(sii.other.len(), 1, "NOP dropped, FMMU_EX kept raw");
        assert_eq!(sii.other[0].category_type, CategoryType::FmmuEx);
        // A category running past the image is refused.
        let cut = &image[..128 + 20];
        assert!(matches!(
            SiiImage::parse(cut),
            Err(WireError::BadLength { .. })
        ));
        assert!(SiiImage::parse(&image[..127]).is_err());
    }

    #[test]
    fn builder_refusals() {
        let mut b = SiiBuilder::new(SiiFixedRepr::default());
        for i in 0..255 {
            b.add_string(&format!("s{i}")).unwrap();
        }
        assert!(b.add_string("one too many").is_err());
        assert!(
            SiiBuilder::new(SiiFixedRepr::default())
                .add_string(&"x".repeat(256))
                .is_err()
        );
        let mut b = SiiBuilder::new(SiiFixedRepr::default());
        b.extra.push((CategoryType::Unknown(0x0800), vec![1, 2, 3]));
        assert!(b.build().is_err(), "odd category data");
        let mut b = SiiBuilder::new(SiiFixedRepr::default());
        b.extra.push((CategoryType::End, vec![]));
        assert!(b.build().is_err());
    }

    fn arb_fixed() -> impl Strategy<Value = SiiFixedRepr> {
        (
            any::<[u16; 5]>(),
            any::<[u32; 4]>(),
            any::<[u16; 8]>(),
            any::<u16>(),
        )
            .prop_map(|(w, id, mb, protocols)| SiiFixedRepr {
                pdi_control: w[0],
                pdi_config: w[1],
                sync_impulse_len: w[2],
                pdi_config2: w[3],
                alias: w[4],
                vendor_id: id[0],
                product_code: id[1],
                revision: id[2],
                serial: id[3],
                std_rx_mailbox: SiiMailboxArea {
                    offset: mb[0],
                    size: mb[1],
                },
                std_tx_mailbox: SiiMailboxArea {
                    offset: mb[2],
                    size: mb[3],
                },
                boot_rx_mailbox: SiiMailboxArea {
                    offset: mb[4],
                    size: mb[5],
                },
                boot_tx_mailbox: SiiMailboxArea {
                    offset: mb[6],
                    size: mb[7],
                },
                mailbox_protocols: MailboxProtocols(protocols),
                version: 1,
                ..Default::default()
            })
    }

    fn arb_builder() -> impl Strategy<Value = SiiBuilder> {
        (
            arb_fixed(),
            proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..12), 0..6),
            proptest::option::of(crate::sii::general::tests::arb_general()),
            proptest::collection::vec(any::<u8>(), 0..4),
            proptest::collection::vec(crate::sii::syncm::tests::arb_entry(), 0..4),
            proptest::collection::vec(crate::sii::pdo::tests::arb_pdo(), 0..3),
            proptest::collection::vec(crate::sii::pdo::tests::arb_pdo(), 0..3),
            proptest::collection::vec(crate::sii::dc::tests::arb_entry(), 0..3),
            proptest::collection::vec(
                (
                    prop_oneof![1u16..10, Just(20u16), Just(42), Just(43), 0x0800u16..0xFFFF],
                    proptest::collection::vec(any::<u8>(), 0..6),
                ),
                0..3,
            ),
        )
            .prop_map(
                |(fixed, strings, general, fmmu, syncm, txpdo, rxpdo, dc, extra)| {
                    let mut b = SiiBuilder::new(fixed);
                    b.strings = strings;
                    b.general = general;
                    // Whole words of usage bytes, so that parsing gives the same list back.
                    b.fmmu = fmmu
                        .iter()
                        .flat_map(|&u| [FmmuUsage::from(u), FmmuUsage::Unused])
                        .collect();
                    b.syncm = syncm;
                    b.txpdo = txpdo;
                    b.rxpdo = rxpdo;
                    b.dc = dc;
                    b.extra = extra
                        .into_iter()
                        .map(|(ty, mut d)| {
                            if d.len() % 2 == 1 {
                                d.push(0);
                            }
                            (CategoryType::from(ty), d)
                        })
                        .collect();
                    b
                },
            )
    }

    proptest! {
        #[test]
        fn round_trip(b in arb_builder()) {
            let image = b.build().unwrap();
            let sii = SiiImage::parse(&image).unwrap();
            prop_assert!(sii.checksum_ok);
            let mut expected = b.clone();
            expected.fixed.size_word = SiiFixedRepr::size_word_for(image.len()).unwrap();
            prop_assert_eq!(SiiBuilder::from_image(&sii), expected);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
            if let Ok(sii) = SiiImage::parse(&bytes) {
                let _ = (sii.to_string(), sii.name(), sii.order());
            }
        }

        #[test]
        fn never_panics_on_corrupted_images(
            flips in proptest::collection::vec((128usize..600, any::<u8>()), 1..6),
            cut in 0usize..2048,
        ) {
            let mut image = el2262_like().build().unwrap();
            for (at, v) in flips {
                if let Some(b) = image.get_mut(at) {
                    *b = v;
                }
            }
            image.truncate(cut.max(1));
            if let Ok(sii) = SiiImage::parse(&image) {
                let _ = sii.to_string();
            }
        }
    }
}
