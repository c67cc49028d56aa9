//! Where a slave's process data comes from: which SyncManagers carry it and how long they
//! are. The SII's SYNCM and PDO categories are one source ([`SiiLayout`]); CoE (0x1C12,
//! 0x1C13 and the mapped PDOs) is another, plugged in through [`LayoutSource`] once the
//! mailbox engine exists.

use std::future::Future;
use std::pin::Pin;

use crate::wire::register::SmControl;
use crate::wire::sii::SiiImage;
use crate::wire::sii::syncm::SyncmType;

use super::error::MasterError;
use super::info::SlaveInfo;

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

/// A slave's process-data SyncManagers, in SyncManager order.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ProcessDataLayout {
    /// The SyncManagers carrying process data (empty: none).
    pub sync_managers: Vec<PdSyncManager>,
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
/// Runs on the master's runtime; a CoE implementation may await mailbox transfers.
pub trait LayoutSource: Send + Sync {
    /// The layout of `slave`, whose parsed SII image is `sii`.
    fn layout<'a>(&'a self, slave: &'a SlaveInfo, sii: &'a SiiImage<'a>) -> LayoutFuture<'a>;
}

/// The layout the SII describes: SYNCM entries of type outputs/inputs, each as long as the
/// PDOs the TXPDO/RXPDO categories assign to it (§4.8), or its SYNCM length when no PDO is
/// assigned. Virtual SyncManagers and empty ones carry nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct SiiLayout;

impl SiiLayout {
    /// The layout of one image (synchronous; what [`LayoutSource::layout`] returns).
    pub fn of(sii: &SiiImage<'_>) -> ProcessDataLayout {
        let mut sync_managers = Vec::new();
        for (index, entry) in sii.syncm.iter().enumerate() {
            let Ok(index) = u8::try_from(index) else {
                break;
            };
            let outputs = match entry.effective_type() {
                SyncmType::Outputs => true,
                SyncmType::Inputs => false,
                _ => continue,
            };
            if entry.enable.virtual_sm() {
                continue;
            }
            let pdos = if outputs { &sii.rxpdo } else { &sii.txpdo };
            let assigned: Vec<_> = pdos
                .iter()
                .filter(|p| p.assigned_sm() == Some(index))
                .collect();
            let length = if assigned.is_empty() {
                entry.length
            } else {
                let bits: u32 = assigned.iter().map(|p| p.bit_length()).sum();
                u16::try_from(bits.div_ceil(8)).unwrap_or(u16::MAX)
            };
            if length == 0 {
                continue;
            }
            let control = match entry.control {
                0 if outputs => SmControl::OUTPUTS,
                0 => SmControl::INPUTS,
                raw => SmControl::decode(raw),
            };
            sync_managers.push(PdSyncManager {
                index,
                start: entry.start,
                length,
                control,
                outputs,
            });
        }
        ProcessDataLayout { sync_managers }
    }
}

impl LayoutSource for SiiLayout {
    fn layout<'a>(&'a self, _slave: &'a SlaveInfo, sii: &'a SiiImage<'a>) -> LayoutFuture<'a> {
        let layout = SiiLayout::of(sii);
        Box::pin(async move { Ok(layout) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::sii::SiiBuilder;
    use crate::wire::sii::fixed::SiiFixedRepr;
    use crate::wire::sii::pdo::{Pdo, PdoEntry, PdoFlags};
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
                .map(|&bit_length| PdoEntry {
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
    }
}
