//! A configured PDO assignment, written to a CoE slave in PREOP (spec-notes §coe.pdo: the
//! reference capture's sequence): for each SyncManager named, clear 0x1C1n:00, rewrite
//! the mapping of each PDO that comes with entries (clear :00, write :01.., write the count),
//! write 0x1C1n:01.. and finally the count 0x1C1n:00. The slave then exchanges what was
//! written, and the layout is read back from it ([`CoeLayout`](crate::master::CoeLayout)).

use crate::mailbox::{MailboxError, SlaveMailbox};
use crate::wire::mailbox::MailboxType;

use super::coe_layout::ASSIGN_BASE;
use crate::master::context::Context;
use crate::master::error::MasterError;
use crate::master::info::SlaveInfo;

use super::pdo_assignment::PdoAssignment;

/// Writes `assignments` to the slave behind `mailbox`, in the order of spec-notes §coe.pdo.
pub(crate) async fn write(
    position: u16,
    mailbox: &SlaveMailbox,
    assignments: &[PdoAssignment],
) -> Result<(), MasterError> {
    let failed = |what| {
        move |source: MailboxError| MasterError::Mailbox {
            position,
            what,
            source,
        }
    };
    for assignment in assignments {
        let assign = ASSIGN_BASE + u16::from(assignment.sync_manager);
        let count = u8::try_from(assignment.pdos.len())
            .map_err(|_| MasterError::InvalidArgument("more than 255 PDOs in one assignment"))?;
        mailbox
            .sdo_download(assign, 0, &[0])
            .await
            .map_err(failed("clearing the PDO assignment"))?;
        for pdo in &assignment.pdos {
            let Some(entries) = &pdo.entries else {
                continue;
            };
            let mapped = u8::try_from(entries.len())
                .map_err(|_| MasterError::InvalidArgument("more than 255 entries in one PDO"))?;
            mailbox
                .sdo_download(pdo.index, 0, &[0])
                .await
                .map_err(failed("clearing a PDO mapping"))?;
            for (sub, entry) in (1u8..).zip(entries) {
                mailbox
                    .sdo_download(pdo.index, sub, &entry.to_u32().to_le_bytes())
                    .await
                    .map_err(failed("writing a PDO mapping entry"))?;
            }
            mailbox
                .sdo_download(pdo.index, 0, &[mapped])
                .await
                .map_err(failed("writing the PDO mapping count"))?;
        }
        for (sub, pdo) in (1u8..).zip(&assignment.pdos) {
            mailbox
                .sdo_download(assign, sub, &pdo.index.to_le_bytes())
                .await
                .map_err(failed("writing the PDO assignment"))?;
        }
        mailbox
            .sdo_download(assign, 0, &[count])
            .await
            .map_err(failed("writing the PDO assignment count"))?;
    }
    Ok(())
}

/// Writes the configured PDO assignment of the slave of `info`, if it has one; returns
/// whether something was written. The slave must be in PREOP with a CoE mailbox.
pub(crate) async fn apply(ctx: &Context, info: &SlaveInfo) -> Result<bool, MasterError> {
    let Some(assignments) = ctx.pdo_config_for(info) else {
        return Ok(false);
    };
    if !info.mailbox.is_some_and(|m| m.protocols.coe()) {
        return Err(MasterError::Mailbox {
            position: info.position,
            what: "writing the configured PDO assignment",
            source: MailboxError::Unsupported {
                station: info.station,
                protocol: MailboxType::Coe,
            },
        });
    }
    let mailbox = ctx
        .mailboxes
        .slave(info.station)
        .map_err(|_| MasterError::NoMailbox {
            position: info.position,
            state: info.al_state,
        })?;
    write(info.position, &mailbox, &assignments).await?;
    Ok(true)
}
