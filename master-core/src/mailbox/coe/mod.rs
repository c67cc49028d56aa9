//! CoE client (ETG.1000.6, spec-notes §coe.sdo): SDO transfers, SDO Information, emergencies.
//!
//! - [`sdo`]: upload and download, expedited, normal and segmented, complete access;
//! - [`info`]: SDO Information (OD list, object and entry descriptions, fragmented);
//! - emergencies are routed by the engine (`SlaveMailbox::emergencies`,
//!   `SlaveMailbox::subscribe_emergencies`).

pub(crate) mod info;
pub(crate) mod sdo;

pub use info::{EntryInfo, ObjectInfo};

use crate::mailbox::engine::exchange::Exchange;
use crate::mailbox::error::Result;
use crate::wire::Emit;
use crate::wire::coe::CoeRepr;
use crate::wire::mailbox::MailboxType;

/// Sends one CoE message built by `repr`.
pub(crate) async fn send_coe(x: &mut Exchange, repr: &CoeRepr<'_>) -> Result<()> {
    x.send(MailboxType::Coe, |buf| repr.emit_into(buf)).await
}
