//! Log lines for mailbox failures: every failed request and every reply dropped as
//! unexpected leaves a `tracing` line with the slave, the protocol, what was addressed and
//! the code, so a failure is never visible only as a counter.
//!
//! Aborts and error replies are the slave's own answers and come at most once per request:
//! debug. Timeouts and protocol violations point at a broken slave or link: warn. Those and
//! the unexpected replies a broken slave can produce without limit go through a small token
//! bucket per slave ([`LogLimit`]); what it holds back is counted and reported with the
//! next line that passes.

use std::fmt;
use std::time::Instant;

pub(crate) use crate::log_limit::LogLimit;

use crate::mailbox::error::MailboxError;
use crate::wire::mailbox::MailboxType;
use crate::wire::soe::Idn;

/// What a request addressed, for its log line.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub(crate) enum Subject {
    /// Nothing in particular (a raw message, VoE, EoE).
    #[default]
    None,
    /// An object entry (SDO transfers, SDO Information).
    Object {
        /// Index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
    /// An IDN of a drive (SoE).
    Idn {
        /// Drive number.
        drive: u8,
        /// The IDN.
        idn: Idn,
    },
    /// A file (FoE).
    File(String),
    /// A raw message of this type (the gateway's), whatever it addresses.
    Raw(MailboxType),
}

impl fmt::Display for Subject {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Subject::None => f.write_str("-"),
            Subject::Object { index, subindex } => write!(f, "{index:#06x}:{subindex:02x}"),
            Subject::Idn { drive, idn } => write!(f, "drive {drive} {idn}"),
            Subject::File(name) => write!(f, "file {name:?}"),
            Subject::Raw(_) => f.write_str("raw message"),
        }
    }
}

fn protocol_name(protocol: Option<MailboxType>, subject: &Subject) -> &'static str {
    match (protocol, subject) {
        (Some(protocol), _) | (None, &Subject::Raw(protocol)) => protocol.name(),
        (None, _) => "-",
    }
}

/// The slave's own code in an error, if it carries one.
fn code_of(err: &MailboxError) -> Option<u32> {
    match err {
        MailboxError::SdoAbort { code, .. } | MailboxError::SdoInfo(code) => Some(u32::from(*code)),
        MailboxError::Soe { code, .. } => Some(u32::from(u16::from(*code))),
        MailboxError::Foe { code, .. } => Some(u32::from(*code)),
        MailboxError::Mailbox(code) => Some(u32::from(u16::from(*code))),
        MailboxError::Eoe(result) => Some(u32::from(u16::from(*result))),
        _ => None,
    }
}

/// Logs a failed request of slave `station`.
pub(crate) fn failure(
    limit: &LogLimit,
    station: u16,
    protocol: Option<MailboxType>,
    subject: &Subject,
    err: &MailboxError,
) {
    let protocol = protocol_name(protocol, subject);
    let code = code_of(err).map(|c| format!("{c:#010x}"));
    let code = code.as_deref().unwrap_or("-");
    let station = format_args!("{station:#06x}");
    match err {
        // The caller went away: nothing failed on the slave's side.
        MailboxError::Cancelled | MailboxError::Shutdown => {}
        MailboxError::Timeout { .. }
        | MailboxError::Protocol { .. }
        | MailboxError::NotSent { .. } => {
            if let Some(suppressed) = limit.admit(Instant::now()) {
                tracing::warn!(
                    %station, protocol, object = %subject, code, suppressed,
                    error = %err, "mailbox request failed"
                );
            }
        }
        _ => tracing::debug!(
            %station, protocol, object = %subject, code, error = %err,
            "mailbox request failed"
        ),
    }
}

/// Logs a reply of slave `station` dropped because no request waits for it.
pub(crate) fn unexpected(limit: &LogLimit, station: u16, protocol: MailboxType, why: &str) {
    if let Some(suppressed) = limit.admit(Instant::now()) {
        tracing::debug!(
            station = %format_args!("{station:#06x}"),
            protocol = protocol.name(),
            suppressed,
            "unexpected mailbox reply dropped: {why}"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subjects_read_as_addresses() {
        let object = Subject::Object {
            index: 0x6040,
            subindex: 1,
        };
        assert_eq!(object.to_string(), "0x6040:01");
        assert_eq!(
            Subject::File("fw.bin".into()).to_string(),
            "file \"fw.bin\""
        );
        assert_eq!(Subject::None.to_string(), "-");
    }
}
