//! The process image by domain for `ecat domains` and `ecat data`: IgH's domains are
//! ecatd's slave groups, each with its own share of the image, logical address and LRW
//! ([`master_core::master::SlaveGroup`]).

use master_core::master::SlaveAddress;

use super::{Core, Result};

/// One mapped entry of a domain.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DomainEntryView {
    /// Ring position of its slave.
    pub position: u16,
    /// The PDO mapping it.
    pub pdo: u16,
    /// Object index and subindex.
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// Bits it takes.
    pub bit_length: u8,
    /// First bit from the start of the domain's share.
    pub bit_offset: u32,
    /// An output (master to slave).
    pub output: bool,
    /// Its name from the SII.
    pub name: String,
}

/// One domain (slave group).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DomainView {
    /// The group's number (0: the default group).
    pub index: usize,
    /// Logical address of its share.
    pub logical: u32,
    /// Its period in ns; 0 for the default group (every cycle).
    pub period_ns: u64,
    /// The working counter it should have and the last one it had.
    pub expected_wkc: u16,
    /// The last working counter.
    pub last_wkc: u16,
    /// Exchanges with a wrong working counter.
    pub wrong_wkc: u64,
    /// Ring positions of the slaves with entries in it.
    pub slaves: Vec<u16>,
    /// Its entries, in image order.
    pub entries: Vec<DomainEntryView>,
    /// Its share of the image as the last exchange brought it back.
    pub data: Vec<u8>,
}

impl Core {
    /// Every domain as the last scan laid it out, with its share of the image.
    pub fn domains(&self) -> Result<Vec<DomainView>> {
        let stats = self.master.group_stats();
        let snapshot = self.master.snapshot();
        let mut entries = Vec::new();
        for slave in self.master.slaves() {
            // A slave that left since the listing has no entries to show.
            if let Ok(list) = self.master.entries(SlaveAddress::Position(slave.position)) {
                entries.extend(list);
            }
        }
        Ok(stats
            .iter()
            .map(|g| {
                let (start, end) = (g.image_offset, g.image_offset + g.image_len);
                let start_bit = start as u64 * 8;
                let mine: Vec<DomainEntryView> = entries
                    .iter()
                    .filter(|e| (start..end).contains(&(e.bit_offset as usize / 8)))
                    .map(|e| DomainEntryView {
                        position: e.position,
                        pdo: e.pdo,
                        index: e.index,
                        subindex: e.subindex,
                        bit_length: e.bit_length,
                        bit_offset: (u64::from(e.bit_offset) - start_bit) as u32,
                        output: e.output,
                        name: e.name.clone(),
                    })
                    .collect();
                let mut slaves: Vec<u16> = mine.iter().map(|e| e.position).collect();
                slaves.dedup();
                DomainView {
                    index: g.group,
                    logical: g.logical,
                    period_ns: g.period.map_or(0, |p| p.as_nanos() as u64),
                    expected_wkc: g.expected_wkc,
                    last_wkc: g.last_wkc,
                    wrong_wkc: g.wrong_wkc,
                    slaves,
                    entries: mine,
                    data: snapshot.inputs.get(start..end).unwrap_or_default().to_vec(),
                }
            })
            .collect())
    }
}
