//! Sorting what comes out of a slave's send mailbox: the answer the waiting request asked
//! for, or a message the slave sent on its own (spec-notes §mbx.demux: one reader per mailbox, and every
//! message goes where it belongs — an EoE frame is never eaten by a CoE transfer, nor an
//! SDO answer by the EoE receiver).

use crate::wire::coe::{CoeFrame, CoeService, EmergencyFrame, EmergencyRepr};
use crate::wire::eoe::{EoeFrameType, EoePacket};
use crate::wire::mailbox::MailboxType;
use crate::wire::soe::{SoeOpcode, SoePacket};

/// What a request waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Want {
    /// A message of this mailbox type that is not unsolicited (or a mailbox error reply).
    Reply(MailboxType),
}

impl Want {
    /// Words for a timeout error.
    pub fn describe(self) -> &'static str {
        match self {
            Want::Reply(MailboxType::Coe) => "a CoE answer",
            Want::Reply(MailboxType::Soe) => "an SoE answer",
            Want::Reply(MailboxType::Foe) => "an FoE answer",
            Want::Reply(MailboxType::Voe) => "a VoE answer",
            Want::Reply(MailboxType::Eoe) => "an EoE answer",
            Want::Reply(_) => "a mailbox answer",
        }
    }
}

/// Where one message goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Route {
    /// The waiting request's answer.
    Request,
    /// A CoE emergency.
    Emergency(EmergencyRepr),
    /// An EoE fragment or timestamp: the EoE receiver.
    EoeFrame,
    /// An SoE notification or slave info.
    SoeNotification,
    /// Nobody waits for it.
    Unexpected,
    /// It does not parse.
    Malformed,
}

/// Routes a message of type `mailbox_type` with mailbox data `data`, while `want` waits.
pub(crate) fn route(mailbox_type: MailboxType, data: &[u8], want: Option<Want>) -> Route {
    let unsolicited = match mailbox_type {
        MailboxType::Coe => match CoeFrame::new_checked(data) {
            Err(_) => return Route::Malformed,
            Ok(frame) if frame.service() == CoeService::Emergency => {
                return match EmergencyFrame::new_checked(data)
                    .and_then(|e| EmergencyRepr::parse(&e))
                {
                    Ok(repr) => Route::Emergency(repr),
                    Err(_) => Route::Malformed,
                };
            }
            Ok(_) => false,
        },
        MailboxType::Eoe => match EoePacket::new_checked(data) {
            Err(_) => return Route::Malformed,
            Ok(packet) => matches!(
                packet.frame_type(),
                EoeFrameType::Fragment | EoeFrameType::TimestampResponse
            ),
        },
        MailboxType::Soe => match SoePacket::new_checked(data) {
            Err(_) => return Route::Malformed,
            Ok(packet) => matches!(
                packet.opcode(),
                SoeOpcode::Notification | SoeOpcode::SlaveInfo
            ),
        },
        _ => false,
    };
    if unsolicited {
        return match mailbox_type {
            MailboxType::Eoe => Route::EoeFrame,
            _ => Route::SoeNotification,
        };
    }
    match want {
        Some(Want::Reply(expected))
            if mailbox_type == expected || mailbox_type == MailboxType::Error =>
        {
            Route::Request
        }
        _ => Route::Unexpected,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const WANT_COE: Option<Want> = Some(Want::Reply(MailboxType::Coe));

    #[test]
    fn emergencies_never_reach_a_waiting_sdo_transfer() {
        let emergency = [0x00, 0x10, 0x10, 0x81, 0x11, 1, 2, 3, 4, 5];
        assert!(matches!(
            route(MailboxType::Coe, &emergency, WANT_COE),
            Route::Emergency(EmergencyRepr {
                error_code: 0x8110,
                error_register: 0x11,
                ..
            })
        ));
        let sdo_response = [0x00, 0x30, 0x60, 0x00, 0x10, 0x00, 0, 0, 0, 0];
        assert_eq!(
            route(MailboxType::Coe, &sdo_response, WANT_COE),
            Route::Request
        );
        assert_eq!(
            route(MailboxType::Coe, &sdo_response, None),
            Route::Unexpected
        );
    }

    #[test]
    fn eoe_fragments_go_to_the_receiver_and_responses_to_the_request() {
        let fragment = [0x00, 0x01, 0x02, 0x00, 0xAA];
        let want_eoe = Some(Want::Reply(MailboxType::Eoe));
        assert_eq!(
            route(MailboxType::Eoe, &fragment, want_eoe),
            Route::EoeFrame
        );
        assert_eq!(
            route(MailboxType::Eoe, &fragment, WANT_COE),
            Route::EoeFrame
        );
        let set_ip_response = [0x03, 0x00, 0x00, 0x00];
        assert_eq!(
            route(MailboxType::Eoe, &set_ip_response, want_eoe),
            Route::Request
        );
        assert_eq!(
            route(MailboxType::Eoe, &set_ip_response, WANT_COE),
            Route::Unexpected
        );
    }

    #[test]
    fn soe_notifications_and_mailbox_errors() {
        let notification = [0x05, 0x40, 0x20, 0x00];
        let want_soe = Some(Want::Reply(MailboxType::Soe));
        assert_eq!(
            route(MailboxType::Soe, &notification, want_soe),
            Route::SoeNotification
        );
        let error = [0x01, 0x00, 0x02, 0x00];
        assert_eq!(route(MailboxType::Error, &error, want_soe), Route::Request);
        assert_eq!(route(MailboxType::Error, &error, None), Route::Unexpected);
        assert_eq!(route(MailboxType::Coe, &[0x00], WANT_COE), Route::Malformed);
    }
}
