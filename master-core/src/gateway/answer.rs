//! The gateway's own error answers (spec-notes §gateway.dialect, docs/gateway.md): what a client
//! gets when its request never reached a slave, in the protocol it spoke.
//!
//! | fault | CoE | SoE | FoE | other types |
//! |---|---|---|---|---|
//! | unknown address | abort 0x06020000 | error 0x1001 (no IDN) | error 0x8001 (not found) | mailbox error 0x0002 |
//! | protocol not served | abort 0x06010000 | error 0x1009 | error 0x8002 (access denied) | mailbox error 0x0002 |
//! | mailbox not running (INIT) | abort 0x08000022 | error 0x1009 | error 0x8002 | mailbox error 0x0002 |
//! | timeout | abort 0x05040000 | — | error 0x8000 "timeout" | — |
//! | busy (also a slave a broadcast skips: held for another client's transfer) | mailbox error 0x0009 | same | same | same |
//! | larger than the mailbox | mailbox error 0x0008 | same | same | same |
//! | other failure | abort 0x08000000 | — | error 0x8000 | — |
//! | a `read` client's write | abort 0x06010002 | error 0x7004 (read only) | error 0x8002 (access denied) | mailbox error 0x0004 |
//! | a step that continues a transfer, sent to 0xFFFF | mailbox error 0x0004 | same | same | same |
//!
//! CoE aborts name the request's index and subindex; an SDO Information request gets an
//! SDO Information error with the same code. "—": no answer (the protocol has no way to say
//! it), the failure is only counted. Requests in the compatibility layout get the codes
//! of `compat::errors` instead.

use crate::wire::Emit;
use crate::wire::coe::info::{SdoInfoRepr, SdoInfoService};
use crate::wire::coe::{AbortCode, sdo_abort};
use crate::wire::foe::{FoeError, FoeRepr};
use crate::wire::mailbox::{MailboxErrorCode, MailboxType, error_reply};
use crate::wire::soe::{IdnOrFragments, SoeError, SoeOpcode, SoeRepr};

use super::ask::{Ask, What};
use super::stats::FailureReason;

/// Why the gateway answers a request itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Fault {
    /// No slave at the address.
    UnknownAddress,
    /// The protocol is not served at the address.
    Unsupported,
    /// The slave's mailbox is not running in its state.
    NotRunning,
    /// The slave did not answer in time.
    Timeout,
    /// The slave did not answer the master's last look: it is not asked at all.
    Absent,
    /// Too many requests in flight.
    Busy,
    /// Larger than the slave's receive mailbox.
    Oversized,
    /// A write from a client whose role is `read`.
    Denied,
    /// A message that continues a transfer, sent to every slave (`Ask::broadcastable`).
    NotBroadcast,
    /// Anything else.
    Other,
}

impl Fault {
    /// The statistics reason this fault counts under.
    pub fn reason(self) -> FailureReason {
        match self {
            Fault::UnknownAddress => FailureReason::UnknownAddress,
            Fault::Unsupported | Fault::NotRunning => FailureReason::UnsupportedProtocol,
            Fault::Timeout | Fault::Absent => FailureReason::Timeout,
            Fault::Busy => FailureReason::Busy,
            Fault::Oversized => FailureReason::Oversized,
            Fault::Denied => FailureReason::Denied,
            Fault::NotBroadcast | Fault::Other => FailureReason::Other,
        }
    }
}

/// The answer to the request that asks `request` and failed with `fault`: the type and data
/// of the reply message, or `None` if the protocol cannot say it.
pub(crate) fn answer(request: &Ask, fault: Fault) -> Option<(MailboxType, Vec<u8>)> {
    match fault {
        Fault::Busy => return Some(mailbox_error(MailboxErrorCode::ServiceInWork)),
        Fault::Oversized => return Some(mailbox_error(MailboxErrorCode::InvalidSize)),
        // The service (this step of the protocol) is not one the broadcast address serves,
        // whatever the protocol (ETG.1000.4 §5.6, spec-notes §mbx.error, §gateway.broadcast).
        Fault::NotBroadcast => {
            return Some(mailbox_error(MailboxErrorCode::ServiceNotSupported));
        }
        _ => {}
    }
    match request.ty {
        MailboxType::Coe => coe_answer(request, coe_code(fault)),
        MailboxType::Soe => soe_answer(request, soe_code(fault)?),
        MailboxType::Foe => foe_answer(foe_code(fault)),
        _ => match fault {
            Fault::UnknownAddress | Fault::Unsupported | Fault::NotRunning => {
                Some(mailbox_error(MailboxErrorCode::UnsupportedProtocol))
            }
            Fault::Denied => Some(mailbox_error(MailboxErrorCode::ServiceNotSupported)),
            _ => None,
        },
    }
}

fn coe_code(fault: Fault) -> AbortCode {
    match fault {
        Fault::UnknownAddress => AbortCode::ObjectDoesNotExist,
        Fault::Unsupported => AbortCode::UnsupportedAccess,
        Fault::NotRunning => AbortCode::DeviceState,
        // What the client's own master would see from a slave that does not answer,
        // given at once (spec-notes §gateway.absent).
        Fault::Timeout | Fault::Absent => AbortCode::Timeout,
        Fault::Denied => AbortCode::ReadOnly,
        Fault::Busy | Fault::Oversized | Fault::NotBroadcast | Fault::Other => {
            AbortCode::GeneralError
        }
    }
}

fn soe_code(fault: Fault) -> Option<SoeError> {
    match fault {
        Fault::UnknownAddress => Some(SoeError::NoIdn),
        Fault::Unsupported | Fault::NotRunning => Some(SoeError::InvalidAccessElement1),
        // ETG.1000.6 §5.7 error codes (IEC 61800-7-304): operation data read only.
        Fault::Denied => Some(SoeError::DataReadOnly),
        _ => None,
    }
}

fn foe_code(fault: Fault) -> (FoeError, &'static [u8]) {
    match fault {
        Fault::UnknownAddress => (FoeError::NotFound, b""),
        Fault::Unsupported | Fault::NotRunning | Fault::Denied => (FoeError::AccessDenied, b""),
        Fault::Timeout => (FoeError::NotDefined, b"timeout"),
        Fault::Absent => (FoeError::NotDefined, b"slave absent"),
        _ => (FoeError::NotDefined, b""),
    }
}

/// A mailbox error reply (type 0).
pub(crate) fn mailbox_error(code: MailboxErrorCode) -> (MailboxType, Vec<u8>) {
    (MailboxType::Error, error_reply(code))
}

/// The CoE answer with `code` to `request`: an SDO Information error for an SDO Information
/// request, else an SDO abort naming the request's index and subindex (0:00 for a request
/// that names none).
pub(crate) fn coe_answer(request: &Ask, code: AbortCode) -> Option<(MailboxType, Vec<u8>)> {
    let (index, subindex) = match request.what {
        What::SdoInfo => return Some((MailboxType::Coe, sdo_info_error(code)?)),
        What::Sdo {
            index, subindex, ..
        } => (index, subindex),
        _ => (0, 0),
    };
    Some((MailboxType::Coe, sdo_abort(index, subindex, code)))
}

fn sdo_info_error(code: AbortCode) -> Option<Vec<u8>> {
    let repr = SdoInfoRepr {
        incomplete: false,
        fragments_left: 0,
        service: SdoInfoService::Error { code },
    };
    repr.to_vec().ok()
}

/// The SoE answer with `code` to `request`: the response of the request's kind with the
/// error bit set, naming its drive, elements and IDN.
pub(crate) fn soe_answer(request: &Ask, code: SoeError) -> Option<(MailboxType, Vec<u8>)> {
    let What::Soe {
        opcode,
        idn,
        drive,
        elements,
        ..
    } = request.what
    else {
        return None;
    };
    let opcode = match opcode {
        SoeOpcode::WriteRequest => SoeOpcode::WriteResponse,
        _ => SoeOpcode::ReadResponse,
    };
    let repr = SoeRepr {
        opcode,
        drive,
        elements,
        idn_or_fragments: IdnOrFragments::Idn(idn),
        error: Some(code),
        data: &[],
    };
    Some((MailboxType::Soe, repr.to_vec().ok()?))
}

/// An FoE ERROR with `code` and `text`.
pub(crate) fn foe_answer((code, text): (FoeError, &[u8])) -> Option<(MailboxType, Vec<u8>)> {
    let repr = FoeRepr::Error { code, text };
    Some((MailboxType::Foe, repr.to_vec().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn answer_to(ty: MailboxType, data: &[u8], fault: Fault) -> Option<(MailboxType, Vec<u8>)> {
        answer(&Ask::read(ty, data), fault)
    }
    use crate::wire::coe::{SdoFrame, SdoRequest, SdoResponse};
    use crate::wire::foe::FoePacket;
    use crate::wire::mailbox::{ErrorReply, ErrorReplyRepr};
    use crate::wire::soe::SoePacket;

    fn upload(index: u16, subindex: u8) -> Vec<u8> {
        let req = SdoRequest::InitiateUpload {
            index,
            subindex,
            complete_access: false,
        };
        req.to_vec().unwrap()
    }

    #[test]
    fn coe_faults_are_aborts_naming_the_object() {
        let (ty, data) =
            answer_to(MailboxType::Coe, &upload(0x6040, 2), Fault::UnknownAddress).unwrap();
        assert_eq!(ty, MailboxType::Coe);
        let frame = SdoFrame::new_checked(&data[..]).unwrap();
        assert_eq!(
            SdoResponse::parse(&frame).unwrap(),
            SdoResponse::Abort {
                index: 0x6040,
                subindex: 2,
                code: AbortCode::ObjectDoesNotExist
            }
        );
    }

    #[test]
    fn busy_is_a_mailbox_error_and_voe_timeouts_are_silent() {
        let (ty, data) = answer_to(MailboxType::Voe, &[], Fault::Busy).unwrap();
        assert_eq!(ty, MailboxType::Error);
        let reply = ErrorReplyRepr::parse(&ErrorReply::new_checked(&data[..]).unwrap()).unwrap();
        assert_eq!(reply.detail, MailboxErrorCode::ServiceInWork);
        assert_eq!(answer_to(MailboxType::Voe, &[], Fault::Timeout), None);
    }

    #[test]
    fn foe_and_soe_use_their_own_errors() {
        let (_, data) = answer_to(MailboxType::Foe, &[], Fault::Unsupported).unwrap();
        let packet = FoePacket::new_checked(&data[..]).unwrap();
        assert_eq!(
            FoeRepr::parse(&packet).unwrap(),
            FoeRepr::Error {
                code: FoeError::AccessDenied,
                text: b""
            }
        );
        let read = [0x01, 0x40, 0x20, 0x00];
        let (_, data) = answer_to(MailboxType::Soe, &read, Fault::Unsupported).unwrap();
        let packet = SoePacket::new_checked(&data[..]).unwrap();
        let repr = SoeRepr::parse(&packet).unwrap();
        assert_eq!(repr.opcode, SoeOpcode::ReadResponse);
        assert_eq!(repr.error, Some(SoeError::from(0x1009)));
    }
}
