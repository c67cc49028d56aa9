//! The one error type of both APIs, mapped once to gRPC codes and HTTP statuses, carrying
//! the protocol's own error code (CoE abort code, SoE/FoE error, AL status code) and text.
//!
//! A protocol error is classed by what a client should do about it (`docs/call-it.md`,
//! "Errors"): an unknown object is NOT_FOUND, a bad value, type or size INVALID_ARGUMENT, a
//! read-only object or a wrong state FAILED_PRECONDITION, a busy slave UNAVAILABLE, a timeout
//! DEADLINE_EXCEEDED; only a transfer that broke on the way (toggle bit, CRC, sequence) is
//! ABORTED, the one class a client should retry as is.

use master_core::mailbox::MailboxError;
use master_core::master::MasterError;
use master_core::wire::coe::AbortCode;
use master_core::wire::foe::FoeError;
use master_core::wire::mailbox::MailboxErrorCode;
use master_core::wire::soe::SoeError;

/// The class of a failure; decides the gRPC code and the HTTP status.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// Malformed request.
    InvalidArgument,
    /// No such slave (or object).
    NotFound,
    /// The slave cannot do this now (no mailbox in INIT, protocol not supported).
    FailedPrecondition,
    /// A transfer broke on the way (toggle bit, CRC, sequence): retrying may succeed.
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
    /// The slave is known but did not answer the master's last look: HTTP 404 (nothing
    /// answers at that address now) and gRPC UNAVAILABLE (it may come back; retry later).
    Absent,
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
            ErrorKind::Unavailable | ErrorKind::Absent => Code::Unavailable,
            ErrorKind::Internal => Code::Internal,
        }
    }

    /// The HTTP status.
    pub fn http(self) -> u16 {
        match self {
            ErrorKind::InvalidArgument => 400,
            ErrorKind::NotFound | ErrorKind::Absent => 404,
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
    /// Stable machine-readable tag (`sdo_abort`, `soe_error`, `unknown_slave`, ...); the
    /// gRPC `ErrorInfo` reason is its upper-case form ([`ApiError::reason`]).
    pub tag: &'static str,
    /// The request field at fault, for an invalid argument.
    pub field: Option<&'static str>,
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
            field: None,
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

    /// The protocol's code in hex at its own width, as the protocol's documents and IgH print
    /// it: a CoE abort code or FoE error code (32 bits) as `0x06020000` (`0x%08X`), an AL
    /// status, mailbox, SoE or EoE code (16 bits) as `0x001B`.
    pub fn code_hex(&self) -> Option<String> {
        let code = self.code?;
        Some(match self.tag {
            "sdo_abort" | "foe_error" => format!("0x{code:08X}"),
            _ => format!("0x{code:04X}"),
        })
    }

    /// The `google.rpc.ErrorInfo` reason: the tag in UPPER_SNAKE_CASE (`SDO_ABORT`).
    pub fn reason(&self) -> String {
        self.tag.to_ascii_uppercase()
    }

    /// Names the request field an invalid argument came from (a BadRequest violation in
    /// gRPC, `field` in a problem document), unless it names one already.
    pub fn in_field(mut self, field: &'static str) -> ApiError {
        if self.kind == ErrorKind::InvalidArgument && self.field.is_none() {
            self.field = Some(field);
        }
        self
    }

    /// A cut asked of a simulated segment that is not wired as a ring.
    pub fn not_a_ring(message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::FailedPrecondition, "not_a_ring", message)
    }

    /// A malformed request field.
    pub fn invalid_field(field: &'static str, message: impl Into<String>) -> ApiError {
        let mut err = ApiError::invalid(message);
        err.field = Some(field);
        err
    }

    /// The outputs are owned by an application (a force without `override`).
    pub fn outputs_owned(message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::FailedPrecondition, "outputs_owned", message)
    }

    /// The slave maps no such process-data entry.
    pub fn unknown_entry(message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::NotFound, "unknown_entry", message)
    }

    /// No slave answers to the name.
    pub fn unknown_slave(message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::NotFound, "unknown_slave", message)
    }

    /// A request refused before it reached the core, for its form (a body, path or query
    /// that does not parse, a route or parameter the API does not have, a cross-site or
    /// foreign-Host request): `tag` says which (docs/call-it.md, "Errors").
    pub fn invalid_request(tag: &'static str, message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::InvalidArgument, tag, message)
    }

    /// A route (or a method on it) the API does not have.
    pub fn unknown_route(tag: &'static str, message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::NotFound, tag, message)
    }

    /// A request a browser page could have sent behind the operator's back.
    pub fn cross_site(tag: &'static str, message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::PermissionDenied, tag, message)
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

    /// A request that ran past its time limit in ecatd.
    pub fn timeout(message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::DeadlineExceeded, "timeout", message)
    }

    /// A request too large.
    pub fn too_large(message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::ResourceExhausted, "too_large", message)
    }

    /// A connection over a `[limits]` connection cap.
    pub fn too_many_connections(message: impl Into<String>) -> ApiError {
        ApiError::new(ErrorKind::Unavailable, "too_many_connections", message)
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
                ApiError::new(ErrorKind::FailedPrecondition, "state_refused", message)
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
            MasterError::Absent { .. } => ApiError::new(ErrorKind::Absent, "slave_absent", message),
            MasterError::Stopped => ApiError::unavailable(message),
            MasterError::Bus { .. } => ApiError::new(ErrorKind::Unavailable, "bus", message),
            MasterError::Eeprom { .. } => {
                ApiError::new(ErrorKind::Unavailable, "eeprom_busy", message)
            }
            MasterError::Malformed { .. } => {
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
            MailboxError::NotSent { .. } => {
                ApiError::new(ErrorKind::Unavailable, "slave_busy", message)
            }
            MailboxError::TooLarge { .. } => ApiError::too_large(message),
            MailboxError::Cancelled | MailboxError::Shutdown => ApiError::unavailable(message),
            MailboxError::Timeout { .. } => {
                ApiError::new(ErrorKind::DeadlineExceeded, "timeout", message)
            }
            MailboxError::Bus(_) => ApiError::new(ErrorKind::Unavailable, "bus", message),
            MailboxError::Mailbox(code) => {
                ApiError::new(mailbox_class(code), "mailbox_error", message)
                    .with_code(u32::from(u16::from(code)), code.name())
            }
            MailboxError::SdoAbort { code, .. } | MailboxError::SdoInfo(code) => {
                ApiError::new(sdo_class(code), "sdo_abort", message)
                    .with_code(u32::from(code), code.description())
            }
            MailboxError::SdoInfoAbortMissing { .. } => {
                ApiError::new(ErrorKind::Aborted, "sdo_info_error", message)
            }
            MailboxError::Soe { code, .. } => ApiError::new(soe_class(code), "soe_error", message)
                .with_code(u32::from(u16::from(code)), code.description()),
            MailboxError::Foe { code, .. } => ApiError::new(foe_class(code), "foe_error", message)
                .with_code(u32::from(code), code.description()),
            MailboxError::Eoe(result) => {
                ApiError::new(ErrorKind::FailedPrecondition, "eoe_error", message)
                    .with_code(u32::from(u16::from(result)), result.description())
            }
            MailboxError::Invalid(_) => ApiError::invalid(message),
            MailboxError::Protocol { .. } => {
                ApiError::new(ErrorKind::Internal, "protocol_violation", message)
            }
        }
    }
}

/// The class of an SDO abort code (ETG.1000.6, spec-notes §coe.abort).
fn sdo_class(code: AbortCode) -> ErrorKind {
    match u32::from(code) {
        0x0602_0000 | 0x0609_0011 | 0x0800_0023 => ErrorKind::NotFound,
        0x0601_0005 | 0x0604_0041..=0x0604_0047 | 0x0607_0010..=0x0607_0013 => {
            ErrorKind::InvalidArgument
        }
        0x0609_0030..=0x0609_0036 => ErrorKind::InvalidArgument,
        0x0504_0000 => ErrorKind::DeadlineExceeded,
        0x0504_0005 | 0x060A_0023 => ErrorKind::Unavailable,
        0x0503_0000 | 0x0504_0001..=0x0504_0004 => ErrorKind::Aborted,
        // Access (read-only, write-only, complete access), hardware, local control, state,
        // no data, general error and codes without a name: the slave will refuse again.
        _ => ErrorKind::FailedPrecondition,
    }
}

/// The class of an SoE error code (ETG.1000.6, spec-notes §soe): the low nibble says what is wrong with the element (1 absent, 2/3 too short/long, 4/5 read-only
/// or write-protected), 0x7006-0x7008 a value out of range.
fn soe_class(code: SoeError) -> ErrorKind {
    let raw = u16::from(code);
    match raw {
        0x1001 | 0x800A => ErrorKind::NotFound,
        0x7006..=0x7008 | 0x7013 => ErrorKind::InvalidArgument,
        0x7010 | 0x7011 => ErrorKind::Unavailable,
        0x1000..=0x7005 | 0x8001..=0x8004 => match raw & 0xF {
            1 => ErrorKind::NotFound,
            2 | 3 => ErrorKind::InvalidArgument,
            _ => ErrorKind::FailedPrecondition,
        },
        _ => ErrorKind::FailedPrecondition,
    }
}

/// The class of an FoE error code (ETG.1000.6, spec-notes §foe).
fn foe_class(code: FoeError) -> ErrorKind {
    match code {
        FoeError::NotFound => ErrorKind::NotFound,
        FoeError::PacketNumberWrong | FoeError::Illegal => ErrorKind::Aborted,
        FoeError::ChecksumError => ErrorKind::InvalidArgument,
        _ => ErrorKind::FailedPrecondition,
    }
}

/// The class of a mailbox error reply (ETG.1000.4, spec-notes §mbx.error).
fn mailbox_class(code: MailboxErrorCode) -> ErrorKind {
    match code {
        MailboxErrorCode::NoMoreMemory => ErrorKind::Unavailable,
        MailboxErrorCode::SizeTooShort | MailboxErrorCode::InvalidHeader => {
            ErrorKind::InvalidArgument
        }
        _ => ErrorKind::FailedPrecondition,
    }
}

#[cfg(test)]
mod tests {
    use master_core::wire::soe::Idn;

    use super::*;

    fn sdo(code: AbortCode) -> ApiError {
        ApiError::from(MailboxError::SdoAbort {
            index: 0x6000,
            subindex: 1,
            code,
        })
    }

    #[test]
    fn sdo_abort_keeps_code_and_text() {
        let code = AbortCode::ObjectDoesNotExist;
        let err = sdo(code);
        assert_eq!(err.kind.grpc(), tonic::Code::NotFound);
        assert_eq!(err.kind.http(), 404);
        assert_eq!(err.reason(), "SDO_ABORT");
        assert_eq!(err.code, Some(0x0602_0000));
        assert_eq!(err.code_text, code.description());
    }

    #[test]
    fn an_absent_slave_is_not_found_over_http_and_unavailable_over_grpc() {
        let err = ApiError::from(MasterError::Absent {
            position: 2,
            station: 0x03eb,
        });
        assert_eq!(err.tag, "slave_absent");
        assert_eq!(
            (err.kind.grpc(), err.kind.http()),
            (tonic::Code::Unavailable, 404)
        );
        assert!(err.message.contains("absent"), "{}", err.message);
    }

    /// The table of `docs/call-it.md`, "Errors".
    #[test]
    fn each_class_has_its_code() {
        use tonic::Code;
        let table = [
            (AbortCode::ObjectDoesNotExist, Code::NotFound, 404),
            (AbortCode::SubindexDoesNotExist, Code::NotFound, 404),
            (AbortCode::LengthTooHigh, Code::InvalidArgument, 400),
            (AbortCode::ValueTooHigh, Code::InvalidArgument, 400),
            (AbortCode::ReadOnly, Code::FailedPrecondition, 409),
            (AbortCode::DeviceState, Code::FailedPrecondition, 409),
            (AbortCode::ResourceUnavailable, Code::Unavailable, 503),
            (AbortCode::Timeout, Code::DeadlineExceeded, 504),
            (AbortCode::ToggleBit, Code::Aborted, 409),
        ];
        for (code, grpc, http) in table {
            let err = sdo(code);
            assert_eq!((err.kind.grpc(), err.kind.http()), (grpc, http), "{code:?}");
        }
        let soe = |code| {
            ApiError::from(MailboxError::Soe {
                drive: 0,
                idn: Idn::from_raw(0x8064),
                code,
            })
        };
        assert_eq!(soe(SoeError::NoIdn).kind, ErrorKind::NotFound);
        assert_eq!(
            soe(SoeError::DataReadOnly).kind,
            ErrorKind::FailedPrecondition
        );
        assert_eq!(
            soe(SoeError::DataAboveMaximum).kind,
            ErrorKind::InvalidArgument
        );
        assert_eq!(soe(SoeError::DataTooLong).kind, ErrorKind::InvalidArgument);
        let foe = |code| {
            ApiError::from(MailboxError::Foe {
                code,
                text: String::new(),
            })
        };
        assert_eq!(foe(FoeError::NotFound).kind, ErrorKind::NotFound);
        assert_eq!(
            foe(FoeError::AccessDenied).kind,
            ErrorKind::FailedPrecondition
        );
    }
}
