//! Admission and audit of the operations that need the write role ([`Operation`]), in one
//! place for every adapter (gRPC, REST and so the dashboard).
//!
//! [`Core::admit`] checks the caller's role and gives a [`Ticket`]; each core method that
//! performs such an operation takes the ticket, names its target and value on it, and hands
//! it its result, which writes the audit line: who, what, on what, the value's size and
//! SHA-256 prefix, and the outcome. A write cannot reach the segment without a ticket, so no
//! adapter can forget the check or the line. The adapters admit before they read a call's
//! arguments: a read token is refused the same way whatever it sent.
//!
//! The mailbox gateway (ETG.8200) admits its clients by address in master-core
//! (`gateway::access`), below this layer, and writes its own audit line to the same target.

use std::fmt::Display;

use super::operation::Operation;
use super::{Core, Result};
use crate::error::ApiError;
use crate::security::{Caller, Role};

/// Leave to perform one [`Operation`], given by [`Core::admit`]; it writes the operation's
/// audit line once the operation has its outcome (or, dropped unused, that it was not
/// carried out).
#[derive(Debug)]
#[must_use = "a ticket is handed to the core method it admits"]
pub struct Ticket {
    caller: String,
    operation: Operation,
    /// The transport's call (`PUT /api/v1/slaves/3/state`, `/ecat.v1.BusService/RequestState`)
    /// when the transport noted it ([`crate::audit::caller`]).
    call: Option<String>,
    target: String,
    value: Option<(usize, String)>,
    finished: bool,
    /// Where the outcome is also published, as a `write` event (none in unit tests).
    events: Option<std::sync::Arc<super::history::EventLog>>,
}

impl Core {
    /// Admits `caller` (the adapter's authenticated caller; `None` when it has none) for
    /// `operation`: a ticket for a write token, PERMISSION_DENIED (and a `warn` audit line)
    /// for a read token, UNAUTHENTICATED without a caller.
    pub fn admit(&self, caller: Option<&Caller>, operation: Operation) -> Result<Ticket> {
        self.with_events(admit(caller, operation, ""))
    }

    fn with_events(&self, ticket: Result<Ticket>) -> Result<Ticket> {
        ticket.map(|mut ticket| {
            ticket.events = Some(std::sync::Arc::clone(self.event_log()));
            ticket
        })
    }

    /// [`Core::admit`] where the core knows the target before it admits (a read whose effect
    /// depends on its address): a refusal names it, in the audit line and the error.
    pub(crate) fn admit_on(
        &self,
        caller: Option<&Caller>,
        operation: Operation,
        target: &str,
    ) -> Result<Ticket> {
        self.with_events(admit(caller, operation, target))
    }
}

/// [`Core::admit`]: the role check itself needs nothing of the core's state.
fn admit(caller: Option<&Caller>, operation: Operation, target: &str) -> Result<Ticket> {
    let caller = caller.ok_or_else(|| ApiError::unauthenticated("a bearer token is required"))?;
    let call = crate::audit::caller().map(|c| c.operation);
    if caller.role < Role::Write {
        tracing::warn!(
            target: "audit",
            caller = %caller.name,
            operation = operation.name(),
            call,
            target,
            "write refused: read-only token"
        );
        let on = if target.is_empty() {
            String::new()
        } else {
            format!(" ({target})")
        };
        return Err(ApiError::permission_denied(format!(
            "{} needs a write token{on}",
            operation.name()
        )));
    }
    Ok(Ticket {
        caller: caller.name.clone(),
        operation,
        call,
        target: String::new(),
        value: None,
        finished: false,
        events: None,
    })
}

impl Ticket {
    /// The caller's token name.
    pub fn caller(&self) -> &str {
        &self.caller
    }

    /// The operation it admits.
    pub fn operation(&self) -> Operation {
        self.operation
    }

    /// Checks that the ticket admits `operation` and names `target` (the slave, file or
    /// object written) for the audit line. A ticket of another operation is a bug in the
    /// adapter: refused as internal.
    pub(crate) fn check(&mut self, operation: Operation, target: impl Display) -> Result<()> {
        self.target = target.to_string();
        if self.operation == operation {
            Ok(())
        } else {
            Err(ApiError::internal(format!(
                "{} was admitted as {}",
                operation.name(),
                self.operation.name()
            )))
        }
    }

    /// Notes the value written (its size and digest prefix go into the audit line).
    pub(crate) fn value(&mut self, data: &[u8]) {
        self.value = Some(crate::audit::describe(data));
    }

    /// Writes the audit line with `result`'s outcome and passes `result` on.
    pub(crate) fn finish<T>(mut self, result: Result<T>) -> Result<T> {
        self.finished = true;
        match &result {
            Ok(_) => self.log("done"),
            Err(err) => self.log(&format!("error: {}: {}", err.tag, err.message)),
        }
        result
    }

    fn log(&self, outcome: &str) {
        let (size, sha256) = match &self.value {
            Some((size, digest)) => (Some(*size), Some(digest.as_str())),
            None => (None, None),
        };
        tracing::info!(
            target: "audit",
            caller = %self.caller,
            operation = self.operation.name(),
            call = self.call.as_deref(),
            target = %self.target,
            size,
            sha256,
            outcome,
            "write finished"
        );
        if let Some(events) = &self.events {
            let on = if self.target.is_empty() {
                String::new()
            } else {
                format!(" on {}", self.target)
            };
            let size = size.map_or(String::new(), |size| format!(", {size} bytes"));
            events.publish(super::view::EventView::note(
                "write",
                format!(
                    "{}{on} by {}{size}: {outcome}",
                    self.operation.name(),
                    self.caller
                ),
            ));
        }
    }
}

impl Drop for Ticket {
    fn drop(&mut self) {
        if !self.finished {
            // Admitted, then its arguments were refused, its time limit ran out or the caller
            // went away: the operation may have been cut short.
            self.log("error: ended without an outcome (refused arguments, time limit or the caller left)");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_write_token_is_admitted_for_every_operation() {
        let reader = Caller {
            name: "viewer".into(),
            role: Role::Read,
        };
        let writer = Caller {
            name: "engineer".into(),
            role: Role::Write,
        };
        for &operation in Operation::ALL {
            let refused = admit(Some(&reader), operation, "").unwrap_err();
            assert_eq!(refused.kind, crate::error::ErrorKind::PermissionDenied);
            assert!(refused.message.starts_with(operation.name()), "{refused:?}");
            let none = admit(None, operation, "").unwrap_err();
            assert_eq!(none.kind, crate::error::ErrorKind::Unauthenticated);
            let ticket = admit(Some(&writer), operation, "").unwrap();
            assert_eq!(ticket.operation(), operation);
            ticket.finish(Ok(())).unwrap();
        }
    }

    #[test]
    fn a_ticket_admits_its_own_operation_only() {
        let mut ticket = Ticket {
            caller: "test".into(),
            operation: Operation::CoeDownload,
            call: None,
            target: String::new(),
            value: None,
            finished: false,
            events: None,
        };
        assert!(ticket.check(Operation::CoeDownload, "3").is_ok());
        let err = ticket.check(Operation::FoeWrite, "3").unwrap_err();
        assert_eq!(err.kind, crate::error::ErrorKind::Internal);
        ticket.finish(Ok(())).unwrap();
    }
}
