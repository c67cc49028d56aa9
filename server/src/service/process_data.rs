//! Process data for the APIs: the layout every attached control program gets (the same
//! entries as the application interface's shared image, docs/application.md) and the values
//! of the last completed cycle, decoded by type. Values come from the master's snapshot of
//! that cycle: reading them sends no frame.

use ecat_app::entry::Entry;
use master_core::master::SlaveAddress;
use master_core::wire::coe::DataType;

use super::{Core, Result};

/// One mapped entry and where it sits in the image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PdEntryView {
    /// Ring position of its slave.
    pub slave: u16,
    /// The slave's station address.
    pub station: u16,
    /// The PDO mapping it.
    pub pdo: u16,
    /// Object index.
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// Its name (SII).
    pub name: String,
    /// Its CoE data type's name (`UNSIGNED16`), empty when not known.
    pub data_type: String,
    /// First bit in the image.
    pub bit_offset: u32,
    /// Bits it takes.
    pub bit_length: u16,
    /// `in` (slave to master) or `out`.
    pub direction: &'static str,
}

impl From<&Entry> for PdEntryView {
    fn from(e: &Entry) -> PdEntryView {
        PdEntryView {
            slave: e.position,
            station: e.station,
            pdo: e.pdo,
            index: e.index,
            subindex: e.subindex,
            name: e.name.clone(),
            data_type: match e.data_type {
                0 => String::new(),
                code => DataType::from(code).to_string(),
            },
            bit_offset: e.bit_offset,
            bit_length: e.bit_length,
            direction: e.direction.as_str(),
        }
    }
}

/// The layout of the process image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LayoutView {
    /// The application interface's layout generation (0 when it does not serve).
    pub generation: u32,
    /// Bytes of the image.
    pub image_len: usize,
    /// The cycle period in ns.
    pub period_ns: u64,
    /// Every entry, slave by slave (outputs first within a slave).
    pub entries: Vec<PdEntryView>,
}

impl Core {
    /// The process image's layout: every mapped entry with its place, as an attached
    /// program gets it.
    pub fn process_data_layout(&self, slave: Option<&str>) -> Result<LayoutView> {
        let only = slave.map(|s| self.position_of(s)).transpose()?;
        let (entries, image_len) = crate::app::layout_entries(&self.master);
        Ok(LayoutView {
            generation: self.app_status().map_or(0, |s| s.generation),
            image_len,
            period_ns: u64::try_from(self.master.cycle_timing().period.as_nanos())
                .unwrap_or(u64::MAX),
            entries: entries
                .iter()
                .filter(|e| only.is_none_or(|p| e.position == p))
                .map(PdEntryView::from)
                .collect(),
        })
    }

    /// The ring position of the slave `slave` names.
    fn position_of(&self, slave: &str) -> Result<u16> {
        let address: SlaveAddress = self.address(slave)?;
        self.master
            .slave(address)
            .map(|s| s.position)
            .map_err(Into::into)
    }
}
