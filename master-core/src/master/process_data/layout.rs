//! Where a slave's process data comes from: which SyncManagers carry it, how long they
//! are, and which PDOs and entries they hold. The SII's SYNCM and PDO categories are one
//! source ([`SiiLayout`]); CoE (0x1C1n and the mapped PDOs, read through the slave's
//! mailbox) is the other ([`CoeLayout`](crate::master::CoeLayout), the master's default).

use std::future::Future;
use std::pin::Pin;

use crate::mailbox::SlaveMailbox;
use crate::wire::coe::DataType;
use crate::wire::register::SmControl;
use crate::wire::sii::SiiImage;
use crate::wire::sii::syncm::SyncmType;

use crate::master::error::MasterError;
use crate::master::info::SlaveInfo;

/// One process-data SyncManager of a slave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PdSyncManager {
    /// SyncManager number.
    pub index: u8,
    /// Physical start address.
    pub start: u16,
    /// Length in bytes (the sum of the mapped PDOs, rounded up).
    pub length: u16,
    /// Control byte to write (buffered mode, direction, IRQ and watchdog bits).
    pub control: SmControl,
    /// True for outputs (master → slave), false for inputs.
    pub outputs: bool,
}

/// One mapped entry of a PDO: `(index << 16) | (subindex << 8) | bit_length` in the
/// mapping object (ETG.1000.6, spec-notes §coe.objects); index 0 is a gap.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PdoEntryInfo {
    /// Mapped object index (0: a gap of `bit_length` bits).
    pub index: u16,
    /// Mapped subindex.
    pub subindex: u8,
    /// Bits the entry takes in the PDO.
    pub bit_length: u8,
    /// The entry's data type, when the SII names it (CoE mapping objects do not say).
    pub data_type: Option<DataType>,
}

impl PdoEntryInfo {
    /// An entry mapping `index:subindex` with `bit_length` bits, data type unknown.
    pub const fn new(index: u16, subindex: u8, bit_length: u8) -> PdoEntryInfo {
        PdoEntryInfo {
            index,
            subindex,
            bit_length,
            data_type: None,
        }
    }

    /// The entry as a mapping object stores it.
    pub fn to_u32(self) -> u32 {
        (u32::from(self.index) << 16) | (u32::from(self.subindex) << 8) | u32::from(self.bit_length)
    }

    /// The entry a mapping object's value describes.
    pub fn from_u32(raw: u32) -> PdoEntryInfo {
        PdoEntryInfo::new((raw >> 16) as u16, (raw >> 8) as u8, raw as u8)
    }
}

/// One PDO assigned to a process-data SyncManager, with its entries in image order.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct PdoInfo {
    /// PDO mapping object (0x1600.. outputs, 0x1A00.. inputs).
    pub index: u16,
    /// The SyncManager carrying it.
    pub sync_manager: u8,
    /// The mapped entries.
    pub entries: Vec<PdoEntryInfo>,
}

impl PdoInfo {
    /// Bits the PDO takes.
    pub fn bit_length(&self) -> u32 {
        self.entries.iter().map(|e| u32::from(e.bit_length)).sum()
    }
}

/// A slave's process-data SyncManagers, in SyncManager order, and the PDOs they carry.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ProcessDataLayout {
    /// The SyncManagers carrying process data (empty: none).
    pub sync_managers: Vec<PdSyncManager>,
    /// The PDOs, by SyncManager and then in assignment order (empty when the source only
    /// knows the lengths, e.g. a SYNCM entry without PDOs).
    pub pdos: Vec<PdoInfo>,
}

impl ProcessDataLayout {
    /// Output bytes in all.
    pub fn outputs_len(&self) -> usize {
        self.len(true)
    }

    /// Input bytes in all.
    pub fn inputs_len(&self) -> usize {
        self.len(false)
    }

    fn len(&self, outputs: bool) -> usize {
        self.sync_managers
            .iter()
            .filter(|sm| sm.outputs == outputs)
            .map(|sm| usize::from(sm.length))
            .sum()
    }
}

/// A boxed future, as the [`LayoutSource`] trait returns.
pub type LayoutFuture<'a> =
    Pin<Box<dyn Future<Output = Result<ProcessDataLayout, MasterError>> + Send + 'a>>;

/// Decides a slave's process-data layout while it is in PREOP.
///
/// Runs on the master's runtime; a CoE implementation awaits mailbox transfers on
/// `mailbox` (the slave's mailbox, `None` for a slave without one).
pub trait LayoutSource: Send + Sync {
    /// The layout of `slave`, whose parsed SII image is `sii`.
    fn layout<'a>(
        &'a self,
        slave: &'a SlaveInfo,
        sii: &'a SiiImage<'a>,
        mailbox: Option<&'a SlaveMailbox>,
    ) -> LayoutFuture<'a>;
}

/// The layout the SII describes: SYNCM entries of type outputs/inputs, each as long as the
/// PDOs the TXPDO/RXPDO categories assign to it (spec-notes §sii.categories), or its SYNCM length when no PDO is
/// assigned. Virtual SyncManagers and empty ones carry nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct SiiLayout;

impl SiiLayout {
    /// The layout of one image (synchronous; what [`LayoutSource::layout`] returns).
    pub fn of(sii: &SiiImage<'_>) -> ProcessDataLayout {
        let mut sync_managers = Vec::new();
        let mut pdos = Vec::new();
        for sm in process_data_syncms(sii) {
            let list = if sm.outputs { &sii.rxpdo } else { &sii.txpdo };
            let assigned: Vec<_> = list
                .iter()
                .filter(|p| p.assigned_sm() == Some(sm.index))
                .collect();
            let length = if assigned.is_empty() {
                sm.length
            } else {
                let bits: u32 = assigned.iter().map(|p| p.bit_length()).sum();
                bytes_for(bits)
            };
            if length == 0 {
                continue;
            }
            pdos.extend(assigned.iter().map(|p| {
                PdoInfo {
                    index: p.index,
                    sync_manager: sm.index,
                    entries: p
                        .entries
                        .iter()
                        .map(|e| PdoEntryInfo {
                            index: e.index,
                            subindex: e.subindex,
                            bit_length: e.bit_length,
                            data_type: sii_data_type(e.data_type),
                        })
                        .collect(),
                }
            }));
            sync_managers.push(PdSyncManager { length, ..sm });
        }
        ProcessDataLayout {
            sync_managers,
            pdos,
        }
    }
}

/// Bytes taken by `bits` bits of process data.
pub(crate) fn bytes_for(bits: u32) -> u16 {
    u16::try_from(bits.div_ceil(8)).unwrap_or(u16::MAX)
}

/// The process-data SyncManagers the SII's SYNCM category declares (type outputs or
/// inputs, not virtual), with their SYNCM length, whatever it is.
pub(crate) fn process_data_syncms<'s>(
    sii: &'s SiiImage<'_>,
) -> impl Iterator<Item = PdSyncManager> + 's {
    sii.syncm.iter().enumerate().filter_map(|(index, entry)| {
        let index = u8::try_from(index).ok()?;
        let outputs = match entry.effective_type() {
            SyncmType::Outputs => true,
            SyncmType::Inputs => false,
            _ => return None,
        };
        if entry.enable.virtual_sm() {
            return None;
        }
        let control = match entry.control {
            0 if outputs => SmControl::OUTPUTS,
            0 => SmControl::INPUTS,
            raw => SmControl::decode(raw),
        };
        Some(PdSyncManager {
            index,
            start: entry.start,
            length: entry.length,
            control,
            outputs,
        })
    })
}

/// The data type an SII PDO entry names (its low byte; 0: not given).
pub(crate) fn sii_data_type(raw: u8) -> Option<DataType> {
    (raw != 0).then(|| DataType::from(u16::from(raw)))
}

impl LayoutSource for SiiLayout {
    fn layout<'a>(
        &'a self,
        _slave: &'a SlaveInfo,
        sii: &'a SiiImage<'a>,
        _mailbox: Option<&'a SlaveMailbox>,
    ) -> LayoutFuture<'a> {
        let layout = SiiLayout::of(sii);
        Box::pin(async move { Ok(layout) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::sii::SiiBuilder;
    use crate::wire::sii::fixed::SiiFixedRepr;
    use crate::wire::sii::pdo::{Pdo, PdoFlags, SiiPdoEntry};
    use crate::wire::sii::syncm::{SyncmEnable, SyncmEntry};

    fn sm(start: u16, length: u16, control: u8, enable: u8, sm_type: SyncmType) -> SyncmEntry {
        SyncmEntry {
            start,
            length,
            control,
            status: 0,
            enable: SyncmEnable(enable),
            sm_type,
        }
    }

    fn pdo(index: u16, sm: u8, bits: &[u8]) -> Pdo {
        Pdo {
            index,
            sync_manager: sm,
            dc_sync: 0,
            name_idx: 0,
            flags: PdoFlags(0),
            entries: bits
                .iter()
                .map(|&bit_length| SiiPdoEntry {
                    index: 0x7000,
                    subindex: 1,
                    name_idx: 0,
                    data_type: 0,
                    bit_length,
                    flags: 0,
                })
                .collect(),
        }
    }

    #[test]
    fn sizes_come_from_the_assigned_pdos_else_from_syncm() {
        let mut b = SiiBuilder::new(SiiFixedRepr::default());
        b.syncm = vec![
            sm(0x1000, 128, 0x26, 1, SyncmType::MailboxOut),
            sm(0x1080, 128, 0x22, 1, SyncmType::MailboxIn),
            // Length 0 in SYNCM: computed from the PDOs, 1 + 16 bits → 3 bytes.
            sm(0x1100, 0, 0x64, 1, SyncmType::Outputs),
            // No PDO assigned: the SYNCM length counts; type inferred from control 0x20.
            sm(0x1200, 4, 0x00, 1, SyncmType::Unspecified),
            // Virtual: carries nothing.
            sm(0x0998, 8, 0x20, 0x04, SyncmType::Inputs),
        ];
        b.rxpdo = vec![pdo(0x1600, 2, &[1, 16]), pdo(0x1601, 0xFF, &[32])];
        let image = b.build().unwrap();
        let sii = SiiImage::parse(&image).unwrap();
        let layout = SiiLayout::of(&sii);
        assert_eq!(
            layout.sync_managers,
            vec![
                PdSyncManager {
                    index: 2,
                    start: 0x1100,
                    length: 3,
                    control: SmControl::decode(0x64),
                    outputs: true,
                },
                PdSyncManager {
                    index: 3,
                    start: 0x1200,
                    length: 4,
                    control: SmControl::INPUTS,
                    outputs: false,
                },
            ]
        );
        assert_eq!((layout.outputs_len(), layout.inputs_len()), (3, 4));
        // Only the PDO assigned to a SyncManager is listed; 0x1601 (no SM) is not.
        assert_eq!(layout.pdos.len(), 1);
        assert_eq!(layout.pdos[0].index, 0x1600);
        assert_eq!(layout.pdos[0].bit_length(), 17);
    }
}
