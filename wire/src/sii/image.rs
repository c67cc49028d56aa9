//! A whole SII image: the fixed area plus the typed categories (ETG.2010, spec-notes §sii).

use core::fmt;

use super::category::{CategoryIter, CategoryRepr, CategoryType};
use super::dc::{DcCategoryRepr, DcEntry};
use super::fixed::{FIXED_LEN, SiiFixed, SiiFixedRepr};
use super::fmmu::{FmmuCategoryRepr, FmmuUsage};
use super::general::GeneralRepr;
use super::pdo::{Pdo, PdoCategoryRepr};
use super::strings::StringsRepr;
use super::syncm::{SyncmCategoryRepr, SyncmEntry};
use crate::error::Result;

/// One category, decoded by type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SiiCategory<'a> {
    /// STRINGS (10).
    Strings(StringsRepr<'a>),
    /// GENERAL (30).
    General(GeneralRepr),
    /// FMMU (40).
    Fmmu(FmmuCategoryRepr),
    /// SYNCM (41).
    Syncm(SyncmCategoryRepr),
    /// TXPDO (50).
    TxPdo(PdoCategoryRepr),
    /// RXPDO (51).
    RxPdo(PdoCategoryRepr),
    /// DC (60).
    Dc(DcCategoryRepr),
    /// Any other type (NOP, DataTypes, FMMU_EX, SYNCUNIT, device or vendor specific), raw.
    Other(CategoryRepr<'a>),
}

impl<'a> SiiCategory<'a> {
    /// Decodes a raw category by its type.
    pub fn parse(raw: CategoryRepr<'a>) -> Result<Self> {
        Ok(match raw.category_type {
            CategoryType::Strings => SiiCategory::Strings(StringsRepr::parse(raw.data)?),
            CategoryType::General => SiiCategory::General(GeneralRepr::parse(raw.data)?),
            CategoryType::Fmmu => SiiCategory::Fmmu(FmmuCategoryRepr::parse(raw.data)?),
            CategoryType::Syncm => SiiCategory::Syncm(SyncmCategoryRepr::parse(raw.data)?),
            CategoryType::TxPdo => SiiCategory::TxPdo(PdoCategoryRepr::parse(raw.data)?),
            CategoryType::RxPdo => SiiCategory::RxPdo(PdoCategoryRepr::parse(raw.data)?),
            CategoryType::Dc => SiiCategory::Dc(DcCategoryRepr::parse(raw.data)?),
            _ => SiiCategory::Other(raw),
        })
    }
}

/// A parsed SII image.
///
/// The first STRINGS, GENERAL and FMMU categories are used (later duplicates land in
/// `other`); SYNCM, TXPDO, RXPDO and DC categories are concatenated in image order. NOP
/// categories are dropped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SiiImage<'a> {
    /// The fixed area.
    pub fixed: SiiFixedRepr,
    /// Whether word 7 matches words 0-6 (a bad checksum is reported, not refused).
    pub checksum_ok: bool,
    /// The string table (empty without a STRINGS category).
    pub strings: StringsRepr<'a>,
    /// GENERAL.
    pub general: Option<GeneralRepr>,
    /// FMMU usage, one entry per FMMU (empty without the category).
    pub fmmu: Vec<FmmuUsage>,
    /// SyncManager entries in SM order.
    pub syncm: Vec<SyncmEntry>,
    /// TxPDOs (slave → master).
    pub txpdo: Vec<Pdo>,
    /// RxPDOs (master → slave).
    pub rxpdo: Vec<Pdo>,
    /// DC operation modes.
    pub dc: Vec<DcEntry>,
    /// Every other category, raw, in image order.
    pub other: Vec<CategoryRepr<'a>>,
}

impl<'a> SiiImage<'a> {
    /// Parses a whole image: at least the 128-byte fixed area, then the category list up to
    /// END or the end of `image`. A malformed category is an error.
    pub fn parse(image: &'a [u8]) -> Result<Self> {
        let view = SiiFixed::new_checked(image)?;
        let mut sii = SiiImage {
            fixed: SiiFixedRepr::parse(&view)?,
            checksum_ok: view.checksum_ok(),
            strings: StringsRepr::default(),
            general: None,
            fmmu: Vec::new(),
            syncm: Vec::new(),
            txpdo: Vec::new(),
            rxpdo: Vec::new(),
            dc: Vec::new(),
            other: Vec::new(),
        };
        let (mut have_strings, mut have_fmmu) = (false, false);
        let area = image.get(FIXED_LEN..).unwrap_or_default();
        for raw in CategoryIter::new(area) {
            let raw = raw?;
            match SiiCategory::parse(raw)? {
                SiiCategory::Strings(s) if !have_strings => {
                    sii.strings = s;
                    have_strings = true;
                }
                SiiCategory::General(g) if sii.general.is_none() => sii.general = Some(g),
                SiiCategory::Fmmu(f) if !have_fmmu => {
                    sii.fmmu = f.usages;
                    have_fmmu = true;
                }
                SiiCategory::Syncm(s) => sii.syncm.extend(s.entries),
                SiiCategory::TxPdo(p) => sii.txpdo.extend(p.pdos),
                SiiCategory::RxPdo(p) => sii.rxpdo.extend(p.pdos),
                SiiCategory::Dc(d) => sii.dc.extend(d.entries),
                SiiCategory::Other(c) if c.category_type == CategoryType::Nop => {}
                _ => sii.other.push(raw),
            }
        }
        Ok(sii)
    }

    /// String with 1-based `index` (0 = none).
    pub fn string(&self, index: u8) -> Option<&'a str> {
        self.strings.get_str(index)
    }

    /// Device name (GENERAL name index).
    pub fn name(&self) -> Option<&'a str> {
        self.string(self.general?.name_idx)
    }

    /// Order code / device type (GENERAL order index).
    pub fn order(&self) -> Option<&'a str> {
        self.string(self.general?.order_idx)
    }

    /// Group (GENERAL group index).
    pub fn group(&self) -> Option<&'a str> {
        self.string(self.general?.group_idx)
    }

    /// Name of a PDO.
    pub fn pdo_name(&self, pdo: &Pdo) -> Option<&'a str> {
        self.string(pdo.name_idx)
    }
}

impl fmt::Display for SiiImage<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.fixed)?;
        if let Some(name) = self.name() {
            write!(f, " \"{name}\"")?;
        }
        write!(
            f,
            ", {} SMs, {} FMMUs, {} TxPDOs, {} RxPDOs",
            self.syncm.len(),
            self.fmmu.len(),
            self.txpdo.len(),
            self.rxpdo.len()
        )?;
        if !self.checksum_ok {
            f.write_str(", BAD CHECKSUM")?;
        }
        Ok(())
    }
}
