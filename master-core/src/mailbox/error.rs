//! The one error type of the mailbox engine and its protocol clients.

use crate::bus::BusError;
use crate::wire::WireError;
use crate::wire::coe::AbortCode;
use crate::wire::eoe::EoeResult;
use crate::wire::foe::FoeError;
use crate::wire::mailbox::{MailboxErrorCode, MailboxType};
use crate::wire::soe::{Idn, SoeError};

/// Why a mailbox request failed.
///
/// Errors a slave reports come back with the slave's own code and the standard text of
/// that code (SDO aborts, SoE and FoE errors, mailbox error replies); the rest say what the
/// master saw.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MailboxError {
    /// No slave with this station address is known to the engine.
    #[error("no mailbox slave with station address {0:#06x}")]
    UnknownSlave(u16),
    /// The slave does not announce the protocol (SII word 0x1C).
    #[error("slave {station:#06x} does not support {}", protocol.name())]
    Unsupported {
        /// Station address.
        station: u16,
        /// The protocol asked for.
        protocol: MailboxType,
    },
    /// The slave's request queue is full ([`MailboxConfig::queue_len`](super::MailboxConfig::queue_len)).
    #[error("the request queue of slave {0:#06x} is full")]
    QueueFull(u16),
    /// The caller went away before the request completed (only the engine sees this).
    #[error("the request was cancelled")]
    Cancelled,
    /// The engine was shut down.
    #[error("the mailbox engine was shut down")]
    Shutdown,
    /// The request did not complete before its deadline.
    #[error("slave {station:#06x}: no answer in time ({waiting_for})")]
    Timeout {
        /// Station address.
        station: u16,
        /// What the engine was waiting for when the time ran out.
        waiting_for: &'static str,
    },
    /// The deadline passed while the request waited for its turn behind the requests
    /// queued before it for the same slave: it was never sent and changed nothing. The
    /// deadline counts from the call (as a caller's own deadline does), so a slave stalled
    /// by one long request fails the ones behind it this way, at once and safe to retry.
    #[error(
        "slave {station:#06x}: not sent: its {waited_ms} ms went by waiting behind the requests \
         queued before it (the slave is busy; nothing was changed)"
    )]
    NotSent {
        /// Station address.
        station: u16,
        /// How long it waited, ms.
        waited_ms: u64,
    },
    /// A datagram of the request failed on the bus.
    #[error("bus: {0}")]
    Bus(#[from] BusError),
    /// The slave answered with a mailbox error reply (type 0).
    #[error("mailbox error {0}")]
    Mailbox(MailboxErrorCode),
    /// The slave aborted an SDO transfer.
    #[error("SDO abort {index:#06x}:{subindex:02x}: {code}")]
    SdoAbort {
        /// Object index of the transfer.
        index: u16,
        /// Subindex of the transfer.
        subindex: u8,
        /// The abort code and its standard text.
        code: AbortCode,
    },
    /// The slave answered an SDO Information request with an error.
    #[error("SDO Information error: {0}")]
    SdoInfo(AbortCode),
    /// The slave answered an SDO Information request with an error reply too short to
    /// hold its abort code (some stacks declare a mailbox length of 6 and leave the code
    /// outside it).
    #[error("slave {station:#06x}: SDO Information error (abort code missing)")]
    SdoInfoAbortMissing {
        /// Station address.
        station: u16,
    },
    /// The slave answered an SoE request with an error.
    #[error("SoE error on drive {drive} {idn}: {:#06x} {}", u16::from(*code), code.description())]
    Soe {
        /// Drive number.
        drive: u8,
        /// The IDN.
        idn: Idn,
        /// The error code.
        code: SoeError,
    },
    /// The slave ended an FoE transfer with an error.
    #[error("FoE error {:#06x} {}{}", u32::from(*code), code.description(), foe_text(*code, text))]
    Foe {
        /// The slave's error code.
        code: FoeError,
        /// The slave's error text (may be empty).
        text: String,
    },
    /// The slave answered an EoE request with a result other than success.
    #[error("EoE result {:#06x} {}", u16::from(*.0), .0.description())]
    Eoe(EoeResult),
    /// More data than the engine accepts (a value announced by the slave, or given by the
    /// caller).
    #[error("{what}: {size} bytes exceed the limit of {limit}")]
    TooLarge {
        /// What was too large.
        what: &'static str,
        /// Its size.
        size: usize,
        /// The limit.
        limit: usize,
    },
    /// The slave's answer does not follow the protocol (wrong toggle, wrong packet number,
    /// a response that cannot be parsed, a size that does not add up).
    #[error("slave {station:#06x}: protocol violation: {reason}")]
    Protocol {
        /// Station address.
        station: u16,
        /// What was wrong.
        reason: &'static str,
    },
    /// The request could not be encoded (a caller's value the wire format refuses).
    #[error("invalid request: {0}")]
    Invalid(WireError),
}

/// Result of a mailbox operation.
pub type Result<T> = core::result::Result<T, MailboxError>;

/// The slave's own words after an FoE error's standard text, unless they only repeat it
/// (a slave commonly sends the code's name as the text: "Not found: Not found" says nothing).
fn foe_text(code: FoeError, text: &str) -> String {
    let text = text.trim();
    if text.is_empty() || text.eq_ignore_ascii_case(code.description()) {
        String::new()
    } else {
        format!(": {text}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_foe_error_shows_the_slave_s_text_only_when_it_adds_something() {
        let err = |text: &str| {
            MailboxError::Foe {
                code: FoeError::NotFound,
                text: text.into(),
            }
            .to_string()
        };
        assert_eq!(err("Not found"), "FoE error 0x8001 Not found");
        assert_eq!(err(""), "FoE error 0x8001 Not found");
        assert_eq!(
            err("no file firmware.bin"),
            "FoE error 0x8001 Not found: no file firmware.bin"
        );
    }
}
