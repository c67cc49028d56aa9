//! Each slave's SyncManagers and the PDOs the master assigned to them, as IgH's
//! `ethercat pdos` shows them: the SyncManagers as the slave's SII declares them (start
//! address, default size, control byte, enable byte), the PDOs and their entries as the
//! master laid them out (read through CoE, or from the SII), named as the SII names them.
//! Everything comes from what the master keeps: no frame is sent.

use master_core::master::{ProcessDataLayout, SlaveAddress};
use master_core::wire::sii::SiiImage;

use super::{Core, Result};

/// One entry a PDO maps (index 0: a gap).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PdoEntryView {
    /// Object index.
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// Bits it takes.
    pub bit_length: u8,
    /// Its name from the SII (empty for a gap or an entry the SII does not name).
    pub name: String,
}

/// One PDO assigned to a SyncManager.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PdoView {
    /// Its mapping object.
    pub index: u16,
    /// Its name from the SII (empty when the SII does not name it).
    pub name: String,
    /// Its entries in image order.
    pub entries: Vec<PdoEntryView>,
}

/// One SyncManager of a slave.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SyncManagerView {
    /// SyncManager number.
    pub index: u8,
    /// Physical start address.
    pub start: u16,
    /// The SII's default size in bytes (0: computed from the PDOs).
    pub default_size: u16,
    /// Control byte (register 0x0804's layout).
    pub control: u8,
    /// The SII's enable byte.
    pub enable: u8,
    /// Bytes of process data the master laid out in it (0: none).
    pub length: u16,
    /// The PDOs the master assigned to it, in assignment order.
    pub pdos: Vec<PdoView>,
}

/// One slave's SyncManagers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SlavePdosView {
    /// Ring position.
    pub slave: u16,
    /// Station address.
    pub station: u16,
    /// Its SyncManagers in SyncManager order.
    pub sync_managers: Vec<SyncManagerView>,
}

impl Core {
    /// The SyncManagers and PDOs of every slave, or of `slave`, in ring order.
    pub fn pdo_layout(&self, slave: Option<super::SlaveName>) -> Result<Vec<SlavePdosView>> {
        let only = slave
            .map(|s| -> Result<u16> {
                let address = self.address(s)?;
                Ok(self.master.slave(address)?.position)
            })
            .transpose()?;
        Ok(self
            .master
            .slaves()
            .iter()
            .filter(|s| only.is_none_or(|p| s.position == p))
            .map(|s| {
                let address = SlaveAddress::Position(s.position);
                // A slave lost since the list was taken shows no SyncManagers.
                let sii = self.master.sii_image(address).unwrap_or_default();
                let layout = self.master.process_data_layout(address).unwrap_or_default();
                SlavePdosView {
                    slave: s.position,
                    station: s.station,
                    sync_managers: sync_managers(SiiImage::parse(&sii).ok().as_ref(), &layout),
                }
            })
            .collect())
    }
}

/// The SII's SyncManagers with the master's PDOs in them; a process-data SyncManager the
/// SII does not declare (a layout from elsewhere) is shown with the master's settings.
fn sync_managers(sii: Option<&SiiImage<'_>>, layout: &ProcessDataLayout) -> Vec<SyncManagerView> {
    let mut out: Vec<SyncManagerView> = sii
        .map(|sii| {
            sii.syncm
                .iter()
                .enumerate()
                .filter_map(|(index, sm)| {
                    Some(SyncManagerView {
                        index: u8::try_from(index).ok()?,
                        start: sm.start,
                        default_size: sm.length,
                        control: sm.control,
                        enable: sm.enable.0,
                        length: 0,
                        pdos: Vec::new(),
                    })
                })
                .collect()
        })
        .unwrap_or_default();
    for pd in &layout.sync_managers {
        let at = match out.iter().position(|sm| sm.index == pd.index) {
            Some(at) => at,
            None => {
                out.push(SyncManagerView {
                    index: pd.index,
                    start: pd.start,
                    default_size: 0,
                    control: pd.control.encode().unwrap_or(0),
                    enable: 1,
                    length: 0,
                    pdos: Vec::new(),
                });
                out.len() - 1
            }
        };
        out[at].length = pd.length;
    }
    for pdo in &layout.pdos {
        let Some(sm) = out.iter_mut().find(|sm| sm.index == pdo.sync_manager) else {
            continue;
        };
        sm.pdos.push(PdoView {
            index: pdo.index,
            name: sii.map(|s| pdo_name(s, pdo.index)).unwrap_or_default(),
            entries: pdo
                .entries
                .iter()
                .map(|e| PdoEntryView {
                    index: e.index,
                    subindex: e.subindex,
                    bit_length: e.bit_length,
                    name: match (sii, e.index) {
                        (Some(s), 1..) => entry_name(s, pdo.index, e.index, e.subindex),
                        _ => String::new(),
                    },
                })
                .collect(),
        });
    }
    out.sort_by_key(|sm| sm.index);
    out
}

/// The name the SII gives PDO `index`.
fn pdo_name(sii: &SiiImage<'_>, index: u16) -> String {
    sii.rxpdo
        .iter()
        .chain(sii.txpdo.iter())
        .find(|p| p.index == index)
        .and_then(|p| sii.string(p.name_idx))
        .unwrap_or_default()
        .to_owned()
}

/// The name the SII gives entry `index:subindex`: in PDO `pdo` first, else in any PDO (a
/// mapping the master wrote may move an entry to another PDO).
fn entry_name(sii: &SiiImage<'_>, pdo: u16, index: u16, subindex: u8) -> String {
    let all = || sii.rxpdo.iter().chain(sii.txpdo.iter());
    let named = |p: &master_core::wire::sii::pdo::Pdo| {
        p.entries
            .iter()
            .find(|e| e.index == index && e.subindex == subindex)
            .and_then(|e| sii.string(e.name_idx))
    };
    all()
        .filter(|p| p.index == pdo)
        .find_map(named)
        .or_else(|| all().find_map(named))
        .unwrap_or_default()
        .to_owned()
}

#[cfg(test)]
mod tests {
    use master_core::master::{PdSyncManager, PdoEntryInfo, PdoInfo};
    use master_core::wire::register::SmControl;

    use super::*;

    #[test]
    fn a_layout_without_an_sii_shows_the_masters_sync_managers_and_pdos() {
        let layout = ProcessDataLayout {
            sync_managers: vec![PdSyncManager {
                index: 2,
                start: 0x1100,
                length: 2,
                control: SmControl::OUTPUTS,
                outputs: true,
            }],
            pdos: vec![PdoInfo {
                index: 0x1600,
                sync_manager: 2,
                entries: vec![PdoEntryInfo::new(0x7000, 1, 1), PdoEntryInfo::new(0, 0, 15)],
            }],
        };
        let sms = sync_managers(None, &layout);
        assert_eq!(sms.len(), 1);
        let sm = &sms[0];
        assert_eq!(
            (sm.index, sm.start, sm.control, sm.length),
            (2, 0x1100, 0x64, 2)
        );
        assert_eq!(sm.pdos[0].index, 0x1600);
        assert_eq!(sm.pdos[0].entries[1].index, 0, "the gap is kept");
        assert_eq!(sm.pdos[0].entries[1].bit_length, 15);
    }
}
