//! The process-data layout a CoE slave reports through its mailbox (spec-notes §coe.objects, §coe.pdo):
//! for every process-data SyncManager *n* the SII declares, the PDOs assigned in 0x1C10+n
//! and the entries each mapping object (0x16xx/0x1Axx) lists. Each object is read with one
//! complete-access upload first and, when the slave refuses that, subindex by subindex.
//! A slave without CoE, or a SyncManager without an assignment object, keeps what the SII
//! says.

use crate::mailbox::{MailboxError, SlaveMailbox};
use crate::wire::sii::SiiImage;

use super::layout::{
    LayoutFuture, LayoutSource, PdSyncManager, PdoEntryInfo, PdoInfo, ProcessDataLayout, SiiLayout,
    bytes_for, process_data_syncms, sii_data_type,
};
use crate::master::error::MasterError;
use crate::master::info::SlaveInfo;

/// 0x1C10: the assignment object of SyncManager 0 (SM *n* at 0x1C10 + n).
pub(crate) const ASSIGN_BASE: u16 = 0x1C10;

/// Most PDOs or entries accepted in one assignment or mapping object (SI0 is a u8).
const MAX_ITEMS: usize = 255;

/// Reads the layout of CoE slaves through their mailbox: for every process-data
/// SyncManager *n* the SII declares, the PDOs assigned in 0x1C10+n and the entries of each
/// mapping object, each object by complete access first and subindex by subindex when the
/// slave refuses that. Slaves without CoE, and SyncManagers without an assignment object,
/// keep what the SII says ([`SiiLayout`]). The master's default source.
#[derive(Debug, Clone, Copy, Default)]
pub struct CoeLayout;

impl LayoutSource for CoeLayout {
    fn layout<'a>(
        &'a self,
        slave: &'a SlaveInfo,
        sii: &'a SiiImage<'a>,
        mailbox: Option<&'a SlaveMailbox>,
    ) -> LayoutFuture<'a> {
        let coe = slave.mailbox.is_some_and(|m| m.protocols.coe());
        match mailbox {
            Some(mailbox) if coe => Box::pin(read_layout(slave.position, sii, mailbox)),
            _ => {
                let layout = SiiLayout::of(sii);
                Box::pin(async move { Ok(layout) })
            }
        }
    }
}

/// Whether `err` says the slave does not have or cannot serve what was asked (as opposed
/// to the exchange itself failing).
fn refused(err: &MailboxError) -> bool {
    matches!(
        err,
        MailboxError::SdoAbort { .. } | MailboxError::Mailbox(_) | MailboxError::Unsupported { .. }
    )
}

/// Reads an ARRAY/RECORD of `item_len`-byte unsigned items (u16 assignments, u32 mapping
/// entries): complete access first, else SI0 and each subindex.
pub(crate) async fn read_items(
    mailbox: &SlaveMailbox,
    index: u16,
    item_len: usize,
) -> Result<Vec<u32>, MailboxError> {
    match mailbox.sdo_upload_complete(index, 0).await {
        Ok(data) => {
            if let Some(items) = parse_complete(&data, item_len) {
                return Ok(items);
            }
        }
        Err(err) if refused(&err) => {}
        Err(err) => return Err(err),
    }
    let count = mailbox
        .sdo_upload(index, 0)
        .await?
        .first()
        .copied()
        .unwrap_or(0);
    let mut items = Vec::with_capacity(usize::from(count));
    for sub in 1..=count {
        let data = mailbox.sdo_upload(index, sub).await?;
        items.push(le_value(&data, item_len));
    }
    Ok(items)
}

/// The items of a complete-access image: SI0 padded to 16 bits, then SI0 items.
/// `None` when the image is shorter than SI0 announces.
fn parse_complete(data: &[u8], item_len: usize) -> Option<Vec<u32>> {
    let count = usize::from(*data.first()?);
    let body = data.get(2..)?;
    if count > MAX_ITEMS || body.len() < count * item_len {
        return None;
    }
    Some(
        body.chunks_exact(item_len)
            .take(count)
            .map(|item| le_value(item, item_len))
            .collect(),
    )
}

/// The little-endian value of the first `len` (at most 4) bytes of `data`.
fn le_value(data: &[u8], len: usize) -> u32 {
    data.iter()
        .take(len.min(4))
        .rev()
        .fold(0u32, |acc, &b| (acc << 8) | u32::from(b))
}

async fn read_layout(
    position: u16,
    sii: &SiiImage<'_>,
    mailbox: &SlaveMailbox,
) -> Result<ProcessDataLayout, MasterError> {
    let failed = |what| {
        move |source| MasterError::Mailbox {
            position,
            what,
            source,
        }
    };
    let from_sii = SiiLayout::of(sii);
    let mut layout = ProcessDataLayout::default();
    let syncms: Vec<PdSyncManager> = process_data_syncms(sii).collect();
    for sm in syncms {
        let assign = ASSIGN_BASE + u16::from(sm.index);
        let assigned = match read_items(mailbox, assign, 2).await {
            Ok(pdos) => pdos,
            Err(err) if refused(&err) => {
                // No assignment object for this SyncManager: the SII's word stands.
                if let Some(known) = from_sii.sync_managers.iter().find(|s| s.index == sm.index) {
                    layout.sync_managers.push(*known);
                    layout.pdos.extend(
                        from_sii
                            .pdos
                            .iter()
                            .filter(|p| p.sync_manager == sm.index)
                            .cloned(),
                    );
                }
                continue;
            }
            Err(err) => return Err(failed("reading the PDO assignment")(err)),
        };
        let mut bits = 0u32;
        for pdo in assigned {
            let pdo = pdo as u16;
            let raw = read_items(mailbox, pdo, 4)
                .await
                .map_err(failed("reading a PDO mapping"))?;
            let entries: Vec<PdoEntryInfo> = raw
                .into_iter()
                .map(|raw| {
                    let mut entry = PdoEntryInfo::from_u32(raw);
                    entry.data_type = sii_entry_type(sii, entry);
                    entry
                })
                .collect();
            let info = PdoInfo {
                index: pdo,
                sync_manager: sm.index,
                entries,
            };
            bits += info.bit_length();
            layout.pdos.push(info);
        }
        let length = bytes_for(bits);
        if length > 0 {
            layout.sync_managers.push(PdSyncManager { length, ..sm });
        }
    }
    Ok(layout)
}

/// The data type the SII's PDO categories give for the object an entry maps.
fn sii_entry_type(sii: &SiiImage<'_>, entry: PdoEntryInfo) -> Option<crate::wire::coe::DataType> {
    if entry.index == 0 {
        return None;
    }
    sii.rxpdo
        .iter()
        .chain(sii.txpdo.iter())
        .flat_map(|p| p.entries.iter())
        .find(|e| e.index == entry.index && e.subindex == entry.subindex)
        .and_then(|e| sii_data_type(e.data_type))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn complete_access_images_are_split_into_items() {
        // 0x1C12: SI0 = 2, padding, 0x1600, 0x1601.
        assert_eq!(
            parse_complete(&[2, 0, 0x00, 0x16, 0x01, 0x16], 2),
            Some(vec![0x1600, 0x1601])
        );
        // A mapping object: SI0 = 1, padding, 0x60400010.
        assert_eq!(
            parse_complete(&[1, 0, 0x10, 0x00, 0x40, 0x60], 4),
            Some(vec![0x6040_0010])
        );
        // Shorter than announced: not trusted.
        assert_eq!(parse_complete(&[3, 0, 0x00, 0x16], 2), None);
        assert_eq!(parse_complete(&[], 2), None);
    }
}
