//! The one error type of both APIs, mapped once to gRPC codes and HTTP statuses, carrying
//! the protocol's own error code (CoE abort code, SoE/FoE error, AL status code) and text.

use master_core::mailbox::MailboxError;
use master_core::master::MasterError;

/// The class of a failure; decides the gRPC code and the HTTP status.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// Malformed request.
    InvalidArgument,
    /// No such slave (or object).
    NotFound,
    /// The slave cannot do this now (no mailbox in INIT, protocol not supported).
    FailedPrecondition,
    /// The slave refused: SDO abort, SoE/FoE error, state refused.
    Aborted,
    /// No credentials.
    Unauthenticated,
    /// Credentials without the needed role.
    PermissionDenied,
    /// A queue is full or a size limit was hit.
    ResourceExhausted,
    /// No answer in time.
    DeadlineExceeded,
    /// The bus or master is not available.
    Unavailable,
    /// A bug or an unexpected failure.
    Internal,
}

impl ErrorKind {
    /// The gRPC status code.
    pub fn grpc(self) -> tonic::Code {
        use tonic::Code;
        match self {
            ErrorKind::InvalidArgument => Code::InvalidArgument,
            ErrorKind::NotFound => Code::NotFound,
            ErrorKind::FailedPrecondition => Code::FailedPrecondition,
            ErrorKind::Aborted => Code::Aborted,
            ErrorKind::Unauthenticated => Code::Unauthenticated,
            ErrorKind::PermissionDenied => Code::PermissionDenied,
            ErrorKind::ResourceExhausted => Code::ResourceExhausted,
            ErrorKind::DeadlineExceeded => Code::DeadlineExceeded,
            ErrorKind::Unavailable => Code::Unavailable,
            ErrorKind::Internal => Code::Internal,
        }
    }

    /// The HTTP status.
    pub fn http(self) -> u16 {
        match self {
            ErrorKind::InvalidArgument => 400,
            ErrorKind::NotFound => 404,
            ErrorKind::FailedPrecondition | ErrorKind::Aborted => 409,
            ErrorKind::Unauthenticated => 401,
            ErrorKind::PermissionDenied => 403,
            ErrorKind::ResourceExhausted => 429,
            ErrorKind::DeadlineExceeded => 504,
            ErrorKind::Unavailable => 503,
            ErrorKind::Internal => 500,
        }
    }
}

/// A failed request: what class, a stable tag, the message and the protocol's own code.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct ApiError {
    /// The class.
    pub kind: ErrorKind,
    /// Stable machine-readable tag (`sdo_abort`, `soe_error`, `unknown_slave`, ...).
    pub tag: &'static str,
    /// Human-readable message.
    pub message: String,
    /// The protocol's error code, if any.
    pub code: Option<u32>,
    /// The standard text of `code`.
    pub code_text: String,
}

impl ApiError {
    fn new(kind: ErrorKind, tag: &'static str, message: impl Into<String>) -> ApiError {
        ApiError {
            kind,
            tag,
            message: message.into(),
            code: None,
            code_text: String::new(),
        }
    }

    fn with_code(mut self, code: u32, text: &str) -> ApiError {
        self.code = Some(code);
        self.code_text = text.to_owned();
        self
    }

    /// A malformed request.
    pub fn invalid(message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::InvalidArgument, "invalid_argument", message)
    }

    /// A request without credentials.
    pub fn unauthenticated(message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::Unauthenticated, "unauthenticated", message)
    }

    /// Credentials without the needed role.
    pub fn permission_denied(message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::PermissionDenied, "permission_denied", message)
    }

    /// The service is not ready.
    pub fn unavailable(message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::Unavailable, "unavailable", message)
    }

    /// A fault of ecatd itself (a task that died), not of the request.
    pub fn internal(message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::Internal, "internal", message)
    }

    /// A request too large.
    pub fn too_large(message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::ResourceExhausted, "too_large", message)
    }
}

impl From<MasterError> for ApiError {
    fn from(err: MasterError) -> ApiError {
        let message = err.to_string();
        match err {
            MasterError::UnknownSlave(_) => {
                ApiError::new(ErrorKind::NotFound, "unknown_slave", message)
            }
            MasterError::StateRefused { code, .. } => {
                ApiError::new(ErrorKind::Aborted, "state_refused", message)
                    .with_code(u32::from(u16::from(code)), code.description())
            }
            MasterError::StateTimeout { .. } => {
                ApiError::new(ErrorKind::DeadlineExceeded, "state_timeout", message)
            }
            MasterError::InvalidState(_) | MasterError::InvalidArgument(_) => {
                ApiError::invalid(message)
            }
            MasterError::NoMailbox { .. } => {
                ApiError::new(ErrorKind::FailedPrecondition, "no_mailbox", message)
            }
            MasterError::Stopped => ApiError::unavailable(message),
            MasterError::Bus { .. } => ApiError::new(ErrorKind::Unavailable, "bus", message),
            MasterError::Eeprom { .. } | MasterError::Malformed { .. } => {
                ApiError::new(ErrorKind::Aborted, "slave_failure", message)
            }
            _ => ApiError::new(ErrorKind::Internal, "internal", message),
        }
    }
}

impl From<MailboxError> for ApiError {
    fn from(err: MailboxError) -> ApiError {
        let message = err.to_string();
        match err {
            MailboxError::UnknownSlave(_) => {
                ApiError::new(ErrorKind::NotFound, "unknown_slave", message)
            }
            MailboxError::Unsupported { .. } => {
                ApiError::new(ErrorKind::FailedPrecondition, "unsupported", message)
            }
            MailboxError::QueueFull(_) => {
                ApiError::new(ErrorKind::ResourceExhausted, "queue_full", message)
            }
            MailboxError::TooLarge { .. } => ApiError::too_large(message),
            MailboxError::Cancelled | MailboxError::Shutdown => ApiError::unavailable(message),
            MailboxError::Timeout { .. } => {
                ApiError::new(ErrorKind::DeadlineExceeded, "timeout", message)
            }
            MailboxError::Bus(_) => ApiError::new(ErrorKind::Unavailable, "bus", message),
            MailboxError::Mailbox(code) => {
                ApiError::new(ErrorKind::Aborted, "mailbox_error", message)
                    .with_code(u32::from(u16::from(code)), code.name())
            }
            MailboxError::SdoAbort { code, .. } | MailboxError::SdoInfo(code) => {
                ApiError::new(ErrorKind::Aborted, "sdo_abort", message)
                    .with_code(u32::from(code), code.description())
            }
            MailboxError::SdoInfoAbortMissing { .. } => {
                ApiError::new(ErrorKind::Aborted, "sdo_info_error", message)
            }
            MailboxError::Soe { code, .. } => {
                ApiError::new(ErrorKind::Aborted, "soe_error", message)
                    .with_code(u32::from(u16::from(code)), code.description())
            }
            MailboxError::Foe { code, .. } => {
                ApiError::new(ErrorKind::Aborted, "foe_error", message)
                    .with_code(u32::from(code), code.description())
            }
            MailboxError::Eoe(result) => ApiError::new(ErrorKind::Aborted, "eoe_error", message)
                .with_code(u32::from(u16::from(result)), result.description()),
            MailboxError::Invalid(_) => ApiError::invalid(message),
            MailboxError::Protocol { .. } => {
                ApiError::new(ErrorKind::Internal, "protocol_violation", message)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use master_core::wire::coe::AbortCode;

    use super::*;

    #[test]
    fn sdo_abort_keeps_code_and_text() {
        let code = AbortCode::ObjectDoesNotExist;
        let err = ApiError::from(MailboxError::SdoAbort {
            index: 0x6000,
            subindex: 1,
            code,
        });
        assert_eq!(err.kind.grpc(), tonic::Code::Aborted);
        assert_eq!(err.kind.http(), 409);
        assert_eq!(err.code, Some(0x0602_0000));
        assert_eq!(err.code_text, code.description());
    }
}
