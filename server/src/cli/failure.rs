//! Why a command failed: one class per thing a script does about it, each with its own exit
//! status (`docs/operations.md`, "Exit status"), the message, and what ecatd said (the gRPC
//! code, the `google.rpc.ErrorInfo` reason and the protocol's own code: the CoE abort code,
//! SoE or FoE error, AL status code). `--json` prints it as one object on standard error.

use std::fmt;

use serde_json::{Value, json};
use tonic::{Code, Status};
use tonic_types::StatusExt;

/// The class of a failure, which decides the exit status.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    /// Anything else: a fault of ecatd, a local file or standard output.
    Other,
    /// The command line is wrong (clap's own status 2), or ecatd refused an argument.
    Usage,
    /// ecatd does not know the slave, entry or route named.
    NotFound,
    /// The slave refused: an SDO abort, an SoE, FoE or EoE error, an AL state refused.
    Refused,
    /// No answer in time.
    Timeout,
    /// ecatd cannot be reached (no connection), or it cannot reach the bus or the slave now.
    Unreachable,
    /// No token, or one without the role the command needs.
    Permission,
}

impl Class {
    /// Every class, in the order of their exit status (the documentation's table).
    pub const ALL: [Class; 7] = [
        Class::Other,
        Class::Usage,
        Class::NotFound,
        Class::Refused,
        Class::Timeout,
        Class::Unreachable,
        Class::Permission,
    ];

    /// The exit status.
    pub fn exit_code(self) -> u8 {
        match self {
            Class::Other => 1,
            Class::Usage => 2,
            Class::NotFound => 3,
            Class::Refused => 4,
            Class::Timeout => 5,
            Class::Unreachable => 6,
            Class::Permission => 7,
        }
    }

    /// The name `--json` prints.
    pub fn name(self) -> &'static str {
        match self {
            Class::Other => "other",
            Class::Usage => "usage",
            Class::NotFound => "not_found",
            Class::Refused => "refused",
            Class::Timeout => "timeout",
            Class::Unreachable => "unreachable",
            Class::Permission => "permission",
        }
    }

    /// The exit status table `ecat --help` ends with.
    pub fn table() -> String {
        let mut text = String::from("Exit status:\n  0  success\n");
        for class in Class::ALL {
            text.push_str(&format!("  {}  {}\n", class.exit_code(), class.name()));
        }
        text
    }
}

/// The ErrorInfo reasons of a slave's own refusal (`docs/call-it.md`, "Errors").
const REFUSALS: [&str; 7] = [
    "SDO_ABORT",
    "SDO_INFO_ERROR",
    "SOE_ERROR",
    "FOE_ERROR",
    "EOE_ERROR",
    "MAILBOX_ERROR",
    "STATE_REFUSED",
];

/// A failed command.
#[derive(Debug, Clone)]
pub struct Failure {
    /// The class.
    pub class: Class,
    /// What went wrong, for a human.
    pub message: String,
    /// The gRPC code ecatd answered, if the failure came from ecatd.
    pub status: Option<Code>,
    /// The `ErrorInfo` reason (`SDO_ABORT`).
    pub reason: Option<String>,
    /// The protocol's own code: CoE abort code, SoE/FoE error, AL status code.
    pub protocol_code: Option<u32>,
}

impl Failure {
    /// A failure of `class` that did not come from ecatd.
    pub fn new(class: Class, message: impl Into<String>) -> Failure {
        Failure {
            class,
            message: message.into(),
            status: None,
            reason: None,
            protocol_code: None,
        }
    }

    /// A failure of the local side (a file, standard output).
    pub fn other(message: impl Into<String>) -> Failure {
        Failure::new(Class::Other, message)
    }

    /// ecatd cannot be reached.
    pub fn unreachable(message: impl Into<String>) -> Failure {
        Failure::new(Class::Unreachable, message)
    }

    /// The same failure with `prefix` before its message (which object it was about).
    pub fn context(mut self, prefix: impl fmt::Display) -> Failure {
        self.message = format!("{prefix}: {}", self.message);
        self
    }

    /// The `--json` form: `class`, `exit_code`, `message`, and when known `status` (the
    /// gRPC code's name), `reason` and `abort_code` (`"0x06020000"`).
    pub fn json(&self) -> Value {
        let mut value = json!({
            "class": self.class.name(),
            "exit_code": self.class.exit_code(),
            "message": self.message,
        });
        if let Some(code) = self.status {
            value["status"] = json!(grpc_name(code));
            value["grpc_code"] = json!(code as i32);
        }
        if let Some(reason) = &self.reason {
            value["reason"] = json!(reason);
        }
        if let Some(code) = self.protocol_code {
            value["abort_code"] = json!(format!("0x{code:08X}"));
        }
        value
    }
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.status {
            // The code's name first, as ecat always printed it (`NotFound: SDO abort ...`).
            Some(code) => write!(f, "{code:?}: {}", self.message),
            None => f.write_str(&self.message),
        }
    }
}

/// An argument the command line cannot use: a usage error.
impl From<String> for Failure {
    fn from(message: String) -> Failure {
        Failure::new(Class::Usage, message)
    }
}

/// An argument the command line cannot use: a usage error.
impl From<&str> for Failure {
    fn from(message: &str) -> Failure {
        Failure::new(Class::Usage, message)
    }
}

/// What ecatd answered, classed by its gRPC code and `ErrorInfo`.
impl From<Status> for Failure {
    fn from(status: Status) -> Failure {
        let info = status.get_details_error_info();
        let reason = info.as_ref().map(|info| info.reason.clone());
        let protocol_code = info
            .as_ref()
            .and_then(|info| info.metadata.get("code"))
            .and_then(|code| u32::from_str_radix(code.trim_start_matches("0x"), 16).ok());
        Failure {
            class: classify(status.code(), reason.as_deref(), protocol_code),
            message: status.message().to_owned(),
            status: Some(status.code()),
            reason,
            protocol_code,
        }
    }
}

/// The class of an answer: credentials and time first (an SDO abort 0x05040000 is a
/// timeout), then a refusal the slave answered, then the gRPC code's own class.
fn classify(code: Code, reason: Option<&str>, protocol_code: Option<u32>) -> Class {
    match code {
        Code::Unauthenticated | Code::PermissionDenied => Class::Permission,
        Code::DeadlineExceeded => Class::Timeout,
        _ if protocol_code.is_some() || reason.is_some_and(|r| REFUSALS.contains(&r)) => {
            Class::Refused
        }
        Code::NotFound => Class::NotFound,
        Code::InvalidArgument | Code::OutOfRange => Class::Usage,
        Code::Unavailable => Class::Unreachable,
        _ => Class::Other,
    }
}

/// The gRPC code's name as the protocol spells it (`NOT_FOUND`).
fn grpc_name(code: Code) -> &'static str {
    match code {
        Code::Ok => "OK",
        Code::Cancelled => "CANCELLED",
        Code::Unknown => "UNKNOWN",
        Code::InvalidArgument => "INVALID_ARGUMENT",
        Code::DeadlineExceeded => "DEADLINE_EXCEEDED",
        Code::NotFound => "NOT_FOUND",
        Code::AlreadyExists => "ALREADY_EXISTS",
        Code::PermissionDenied => "PERMISSION_DENIED",
        Code::ResourceExhausted => "RESOURCE_EXHAUSTED",
        Code::FailedPrecondition => "FAILED_PRECONDITION",
        Code::Aborted => "ABORTED",
        Code::OutOfRange => "OUT_OF_RANGE",
        Code::Unimplemented => "UNIMPLEMENTED",
        Code::Internal => "INTERNAL",
        Code::Unavailable => "UNAVAILABLE",
        Code::DataLoss => "DATA_LOSS",
        Code::Unauthenticated => "UNAUTHENTICATED",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_class_has_its_own_exit_status() {
        let mut codes: Vec<u8> = Class::ALL.iter().map(|c| c.exit_code()).collect();
        codes.sort_unstable();
        codes.dedup();
        assert_eq!(codes.len(), Class::ALL.len());
        assert!(!codes.contains(&0));
    }

    #[test]
    fn a_slave_abort_is_a_refusal_with_its_code_but_a_timeout_stays_a_timeout() {
        assert_eq!(
            classify(Code::NotFound, Some("SDO_ABORT"), Some(0x0602_0000)),
            Class::Refused
        );
        assert_eq!(
            classify(Code::NotFound, Some("UNKNOWN_SLAVE"), None),
            Class::NotFound
        );
        assert_eq!(
            classify(Code::DeadlineExceeded, Some("SDO_ABORT"), Some(0x0504_0000)),
            Class::Timeout
        );
        assert_eq!(
            classify(Code::Unauthenticated, None, None),
            Class::Permission
        );
        assert_eq!(classify(Code::Internal, None, None), Class::Other);
    }
}
