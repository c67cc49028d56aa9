//! Audit lines for writes through the gateway: the same `tracing` target (`audit`) the
//! gRPC and REST APIs write to, so one log filter shows every change made to the segment,
//! whichever way it came. A line names the client (address and port), the slave (the address
//! the client used, `master` for address 0), the object, IDN or file, and the outcome.

use std::net::SocketAddr;
use std::sync::Arc;

use tokio::sync::{OwnedSemaphorePermit, Semaphore};

use crate::wire::coe::{CoeFrame, CoeService, SdoFrame};
use crate::wire::foe::{FoePacket, FoeRepr};
use crate::wire::mailbox::{ErrorReply, ErrorReplyRepr, MailboxType};
use crate::wire::soe::SoePacket;

use super::answer::Fault;
use super::ask::Ask;

/// What became of a request, as far as the audit line says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Outcome {
    /// The slave (or the master's dictionary) answered; with the error its answer carries,
    /// if it is one (read at once: the answer's bytes are not kept, not copied per request).
    Answered(Option<String>),
    /// Delivered; the protocol gives no answer.
    Sent,
    /// The gateway answered itself (or dropped it).
    Failed(Fault),
}

impl Outcome {
    /// The outcome of an answer of type `ty` with `data`.
    pub(crate) fn answered(ty: MailboxType, data: &[u8]) -> Outcome {
        Outcome::Answered(error_of(ty, data))
    }

    /// `done`, or the error the answer carries.
    fn describe(&self) -> String {
        match self {
            Outcome::Sent => "sent".into(),
            Outcome::Answered(_) | Outcome::Failed(_) => {
                self.error().unwrap_or_else(|| "done".into())
            }
        }
    }

    /// The error, if the request failed: the gateway's own fault or an error answer.
    fn error(&self) -> Option<String> {
        match self {
            Outcome::Sent => None,
            Outcome::Failed(fault) => Some(format!("failed: {}", fault.reason().name())),
            Outcome::Answered(error) => error.clone(),
        }
    }
}

/// The error an answer carries, if it is one.
fn error_of(ty: MailboxType, data: &[u8]) -> Option<String> {
    match ty {
        MailboxType::Error => {
            let reply = ErrorReply::new_checked(data)
                .and_then(|r| ErrorReplyRepr::parse(&r))
                .ok()?;
            Some(format!("mailbox error {}", reply.detail.name()))
        }
        MailboxType::Coe => {
            let service = CoeFrame::new_checked(data).ok()?.service();
            let frame = SdoFrame::new_checked(data).ok()?;
            let abort = matches!(service, CoeService::SdoResponse | CoeService::SdoRequest)
                && frame.specifier() == 4;
            abort.then(|| {
                let code = data
                    .get(6..10)
                    .map_or(0, |c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]));
                format!("SDO abort 0x{code:08X}")
            })
        }
        MailboxType::Soe => {
            let packet = SoePacket::new_checked(data).ok()?;
            packet.error().then(|| {
                let code = data
                    .get(4..6)
                    .map_or(0, |c| u16::from_le_bytes([c[0], c[1]]));
                format!("SoE error 0x{code:04X}")
            })
        }
        MailboxType::Foe => match FoePacket::new_checked(data).and_then(|p| FoeRepr::parse(&p)) {
            Ok(FoeRepr::Error { code, .. }) => Some(format!("FoE error 0x{:04X}", u32::from(code))),
            _ => None,
        },
        _ => None,
    }
}

/// The slave part of the line.
fn slave(address: u16) -> String {
    if address == super::route::MASTER_ADDRESS {
        "master".into()
    } else {
        format!("0x{address:04X}")
    }
}

/// Logs the audit line of a write (the request that asks `ask`, to `address`)
/// that was carried out with `outcome`; nothing for the follow-up messages of a transfer.
pub(crate) fn write(client: SocketAddr, address: u16, ask: &Ask, outcome: &Outcome) {
    if !ask.is_audited() {
        return;
    }
    tracing::info!(
        target: "audit",
        client = %client,
        slave = %slave(address),
        object = %ask.object(),
        protocol = ask.ty.name(),
        outcome = %outcome.describe(),
        "gateway write"
    );
}

/// Logs the audit line of a write refused because the client's role is `read`.
pub(crate) fn refused(client: SocketAddr, address: u16, ask: &Ask) {
    tracing::warn!(
        target: "audit",
        client = %client,
        slave = %slave(address),
        object = %ask.object(),
        protocol = ask.ty.name(),
        outcome = "refused: read role",
        "gateway write refused"
    );
}

/// Whether [`failure`] logs `outcome` at `info` (a failed FoE request), not at `debug`.
pub(crate) fn failure_is_loud(ask: &Ask, outcome: &Outcome) -> bool {
    ask.ty == MailboxType::Foe && outcome.error().is_some()
}

/// Logs a request that failed, read or write: at `info` for FoE (a file transfer that broke,
/// a firmware download say, is a fault an operator looks for, with the client that ran
/// it), at `debug` for every other protocol (a client's failed read is the client's
/// business, and a busy tool would fill the log).
pub(crate) fn failure(client: SocketAddr, address: u16, ask: &Ask, outcome: &Outcome) {
    let Some(error) = outcome.error() else {
        return;
    };
    if failure_is_loud(ask, outcome) {
        tracing::info!(
            client = %client,
            slave = %slave(address),
            object = %ask.object(),
            error = %error,
            "gateway transfer failed"
        );
    } else {
        tracing::debug!(
            client = %client,
            slave = %slave(address),
            object = %ask.object(),
            protocol = ask.ty.name(),
            error = %error,
            "gateway request failed"
        );
    }
}

/// Lines the bus thread handed to the gateway's worker to be written, and not yet written:
/// bounded, so that a log sink that stalls while a client floods the gateway with writes (or
/// refused ones) cannot grow the worker's queue without end. A line that finds the backlog
/// full is written in place, holding the bus as a stalled log held the worker before.
#[derive(Debug)]
pub(crate) struct Backlog(Arc<Semaphore>);

impl Default for Backlog {
    fn default() -> Self {
        Backlog(Arc::new(Semaphore::new(Self::LIMIT)))
    }
}

impl Backlog {
    /// The most lines waiting to be written.
    pub const LIMIT: usize = 1024;

    /// A place for one more line, if the backlog has room; dropping it gives it back.
    pub fn enter(&self) -> Option<OwnedSemaphorePermit> {
        Arc::clone(&self.0).try_acquire_owned().ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gateway::answer::mailbox_error;
    use crate::wire::coe::{AbortCode, sdo_abort};
    use crate::wire::mailbox::MailboxErrorCode;

    #[test]
    fn an_answer_keeps_the_error_it_carries_and_nothing_else() {
        // An SDO abort (spec-notes §coe.abort), as a slave answers an unknown object.
        let abort = sdo_abort(0x1018, 1, AbortCode::ObjectDoesNotExist);
        let outcome = Outcome::answered(MailboxType::Coe, &abort);
        assert_eq!(outcome.describe(), "SDO abort 0x06020000");
        assert_eq!(outcome.error().as_deref(), Some("SDO abort 0x06020000"));
        // An expedited upload response (command 0x43, four bytes of data): no error.
        let upload = [0x00, 0x30, 0x43, 0x18, 0x10, 0x01, 0x01, 0x00, 0x00, 0xE0];
        let done = Outcome::answered(MailboxType::Coe, &upload);
        assert_eq!((done.describe(), done.error()), ("done".into(), None));
        // A mailbox error reply (spec-notes §mbx.error) names its code.
        let (ty, reply) = mailbox_error(MailboxErrorCode::UnsupportedProtocol);
        assert_eq!(
            Outcome::answered(ty, &reply).describe(),
            format!(
                "mailbox error {}",
                MailboxErrorCode::UnsupportedProtocol.name()
            )
        );
        // A message the gateway cannot read is no error of the slave's.
        assert_eq!(Outcome::answered(MailboxType::Coe, &[0x00]).error(), None);
        assert_eq!(Outcome::Sent.describe(), "sent");
    }

    #[test]
    fn the_backlog_of_handed_lines_is_bounded_and_frees_a_place_per_line_written() {
        let backlog = Backlog::default();
        let mut places: Vec<_> = (0..Backlog::LIMIT)
            .map(|_| backlog.enter().expect("room below the limit"))
            .collect();
        assert!(backlog.enter().is_none(), "full at the limit");
        drop(places.pop());
        let again = backlog.enter().expect("a written line frees its place");
        assert!(backlog.enter().is_none());
        drop(again);
        assert!(backlog.enter().is_some());
        drop(places);
    }
}
