//! Transfers: what a forwarded message makes the slave do, from what the request asks
//! (`ask`): how many messages it answers with ([`Ask::expect`]) and whether the client is in
//! the middle of a multi-message transfer afterwards ([`Ask::after`]; the slave stays
//! reserved for it, see `session`).
//!
//! The gateway forwards bytes; it looks into them only this far:
//! - CoE SDO: segmented uploads and downloads span several requests; an abort from the
//!   client gets no answer. SDO Information: the slave may answer with several fragments.
//! - SoE: a read may be answered in fragments; a write fragment with "incomplete" set gets
//!   no answer (only the last does).
//! - FoE: a read or write spans many requests; the client's last ACK of a read and any
//!   ERROR from the client get no answer.
//! - EoE: frame fragments get no answer; the IP and filter services do.
//! - Everything else: one answer.
//!
//! It also tells which messages may go to every slave at once ([`Ask::broadcastable`]): not
//! the steps that continue a transfer.

use crate::wire::coe::SdoPayload;
use crate::wire::coe::info::SdoInfoFrame;
use crate::wire::coe::{SdoFrame, SdoResponse};
use crate::wire::foe::{self, FoeOpcode, FoePacket, FoeRepr};
use crate::wire::mailbox::MailboxType;
use crate::wire::soe::{SoeOpcode, SoePacket};

use super::ask::{Ask, FoeStep, SdoStep, What};

/// How the slave answers a message.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Expect {
    /// One message.
    Reply,
    /// One message and those that follow while the function says so of the last one's
    /// mailbox data.
    Replies(fn(&[u8]) -> bool),
    /// Nothing.
    Nothing,
}

/// A multi-message transfer a client is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Transfer {
    /// A segmented SDO upload or download.
    Sdo,
    /// An FoE read; `last` once the slave sent the short packet (the client's ACK of it
    /// ends the transfer and gets no answer).
    FoeRead { last: bool },
    /// An FoE write.
    FoeWrite,
    /// An SoE write sent in fragments.
    SoeWrite,
}

/// Mailbox sizes of the slave (SM0, SM1), for FoE's "short packet ends the file".
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sizes {
    pub write: usize,
    pub read: usize,
}

impl Ask {
    /// What the slave will answer to the request, given the client's transfer in progress.
    pub(crate) fn expect(&self, transfer: Option<Transfer>) -> Expect {
        match &self.what {
            What::SdoInfo => Expect::Replies(sdo_info_follows),
            // The client's abort (command specifier 4).
            What::Sdo { specifier: 4, .. } => Expect::Nothing,
            What::Soe {
                opcode: SoeOpcode::WriteRequest,
                incomplete: true,
                ..
            } => Expect::Nothing,
            What::Soe {
                opcode: SoeOpcode::ReadRequest,
                ..
            } => Expect::Replies(soe_follows),
            What::Foe {
                step: Some(FoeStep::Error),
                ..
            } => Expect::Nothing,
            What::Foe {
                step: Some(FoeStep::Ack),
                ..
            } if transfer == Some(Transfer::FoeRead { last: true }) => Expect::Nothing,
            What::Eoe { answered: false } => Expect::Nothing,
            _ => Expect::Reply,
        }
    }

    /// Whether the request may be broadcast (address 0xFFFF): a message that stands alone
    /// or opens a transfer. A message that continues one — an SDO download or upload
    /// segment, the client's SDO abort, an FoE DATA, ACK, ERROR or BUSY, an SoE write
    /// fragment with more to come — only means something in the transfer that one slave is
    /// in with the client (ETG.1000.6: SDO segments and FoE packets follow their initiate or
    /// request with the same slave, CiA 301's SDO protocol between one client and one
    /// server); sent to every slave it would be out of place in each slave not in that
    /// transfer, or step into another client's (spec-notes §gateway.broadcast). EoE and VoE
    /// are not followed by the gateway and pass.
    pub(crate) fn broadcastable(&self) -> bool {
        match &self.what {
            // The client's command specifiers (ETG.1000.6 §5.6.2): 0 download segment,
            // 3 upload segment and 4 abort continue a transfer; 1 and 2 initiate one.
            What::Sdo { specifier, .. } => !matches!(specifier, 0 | 3 | 4),
            What::Foe { opcode, .. } => !matches!(
                opcode,
                FoeOpcode::Data | FoeOpcode::Ack | FoeOpcode::Error | FoeOpcode::Busy
            ),
            What::Soe {
                opcode, incomplete, ..
            } => !(*opcode == SoeOpcode::WriteRequest && *incomplete),
            _ => true,
        }
    }

    /// The transfer the client is in after the request was answered with `reply` (mailbox
    /// data of the first answer, if any; `reply_ty` its type).
    pub(crate) fn after(
        &self,
        reply: Option<(MailboxType, &[u8])>,
        transfer: Option<Transfer>,
        sizes: Sizes,
    ) -> Option<Transfer> {
        let reply = reply
            .filter(|(reply_ty, _)| *reply_ty == self.ty)
            .map(|(_, d)| d);
        match &self.what {
            What::Sdo {
                step: Some(step), ..
            } => sdo_after(*step, reply?).then_some(Transfer::Sdo),
            What::Soe {
                opcode: SoeOpcode::WriteRequest,
                incomplete: true,
                ..
            } => Some(Transfer::SoeWrite),
            What::Foe {
                step: Some(step), ..
            } => foe_after(*step, reply, transfer, sizes),
            _ => None,
        }
    }
}

fn foe_repr(data: &[u8]) -> Option<FoeRepr<'_>> {
    FoePacket::new_checked(data)
        .and_then(|p| FoeRepr::parse(&p))
        .ok()
}

fn foe_after(
    request: FoeStep,
    reply: Option<&[u8]>,
    transfer: Option<Transfer>,
    sizes: Sizes,
) -> Option<Transfer> {
    let reply = reply.and_then(foe_repr);
    let full_read = foe::max_data(sizes.read);
    match (request, reply) {
        (FoeStep::Error, _) | (_, Some(FoeRepr::Error { .. })) => None,
        (FoeStep::ReadRequest | FoeStep::Ack, Some(FoeRepr::Data { data, .. })) => {
            Some(Transfer::FoeRead {
                last: data.len() < full_read,
            })
        }
        (FoeStep::Ack, None) => None,
        (FoeStep::WriteRequest, Some(FoeRepr::Ack { .. } | FoeRepr::Busy { .. })) => {
            Some(Transfer::FoeWrite)
        }
        (FoeStep::Data { len }, Some(FoeRepr::Ack { .. })) => {
            // A packet shorter than the slave's receive mailbox holds is the last.
            let full_write = foe::max_data(sizes.write);
            (len >= full_write).then_some(Transfer::FoeWrite)
        }
        // A BUSY: the client sends the same packet again.
        (_, Some(FoeRepr::Busy { .. })) => transfer,
        _ => None,
    }
}

/// Whether an SDO request step answered with `reply` leaves a segmented transfer open.
fn sdo_after(request: SdoStep, reply: &[u8]) -> bool {
    let Some(response) = SdoFrame::new_checked(reply)
        .ok()
        .and_then(|frame| SdoResponse::parse(&frame).ok())
    else {
        return false;
    };
    match (request, response) {
        (
            SdoStep::Upload,
            SdoResponse::InitiateUpload {
                payload:
                    SdoPayload::Normal {
                        complete_size,
                        data,
                    },
                ..
            },
        ) => (data.len() as u64) < u64::from(complete_size),
        (SdoStep::UploadSegment, SdoResponse::UploadSegment { last, .. }) => !last,
        (SdoStep::Download { segmented }, SdoResponse::InitiateDownload { .. }) => segmented,
        (SdoStep::DownloadSegment { last }, SdoResponse::DownloadSegment { .. }) => !last,
        _ => false,
    }
}

fn sdo_info_follows(data: &[u8]) -> bool {
    SdoInfoFrame::new_checked(data).is_ok_and(|f| f.incomplete())
}

fn soe_follows(data: &[u8]) -> bool {
    SoePacket::new_checked(data).is_ok_and(|p| p.incomplete())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Emit;
    use crate::wire::coe::SdoRequest;

    fn expect(ty: MailboxType, data: &[u8], transfer: Option<Transfer>) -> Expect {
        Ask::read(ty, data).expect(transfer)
    }

    fn broadcastable(ty: MailboxType, data: &[u8]) -> bool {
        Ask::read(ty, data).broadcastable()
    }

    fn after(
        ty: MailboxType,
        request: &[u8],
        reply: Option<(MailboxType, &[u8])>,
        transfer: Option<Transfer>,
        sizes: Sizes,
    ) -> Option<Transfer> {
        Ask::read(ty, request).after(reply, transfer, sizes)
    }

    fn foe(repr: FoeRepr<'_>) -> Vec<u8> {
        repr.to_vec().unwrap()
    }

    const SIZES: Sizes = Sizes {
        write: 128,
        read: 128,
    };

    #[test]
    fn an_foe_read_ends_with_the_short_packet_and_an_unanswered_ack() {
        let rrq = foe(FoeRepr::ReadRequest {
            password: 0,
            file_name: b"f",
        });
        let full = vec![1u8; foe::max_data(128)];
        let data1 = foe(FoeRepr::Data {
            packet: 1,
            data: &full,
        });
        let t = after(
            MailboxType::Foe,
            &rrq,
            Some((MailboxType::Foe, &data1)),
            None,
            SIZES,
        );
        assert_eq!(t, Some(Transfer::FoeRead { last: false }));
        let ack = foe(FoeRepr::Ack { packet: 1 });
        assert!(matches!(expect(MailboxType::Foe, &ack, t), Expect::Reply));
        let data2 = foe(FoeRepr::Data {
            packet: 2,
            data: &[1, 2],
        });
        let t = after(
            MailboxType::Foe,
            &ack,
            Some((MailboxType::Foe, &data2)),
            t,
            SIZES,
        );
        assert_eq!(t, Some(Transfer::FoeRead { last: true }));
        let ack2 = foe(FoeRepr::Ack { packet: 2 });
        assert!(matches!(
            expect(MailboxType::Foe, &ack2, t),
            Expect::Nothing
        ));
        assert_eq!(after(MailboxType::Foe, &ack2, None, t, SIZES), None);
    }

    #[test]
    fn an_foe_write_ends_with_the_acked_short_packet() {
        let wrq = foe(FoeRepr::WriteRequest {
            password: 0,
            file_name: b"f",
        });
        let ack0 = foe(FoeRepr::Ack { packet: 0 });
        let t = after(
            MailboxType::Foe,
            &wrq,
            Some((MailboxType::Foe, &ack0)),
            None,
            SIZES,
        );
        assert_eq!(t, Some(Transfer::FoeWrite));
        let full = vec![0u8; foe::max_data(128)];
        let d1 = foe(FoeRepr::Data {
            packet: 1,
            data: &full,
        });
        let ack1 = foe(FoeRepr::Ack { packet: 1 });
        let t = after(
            MailboxType::Foe,
            &d1,
            Some((MailboxType::Foe, &ack1)),
            t,
            SIZES,
        );
        assert_eq!(t, Some(Transfer::FoeWrite));
        let d2 = foe(FoeRepr::Data {
            packet: 2,
            data: &[9],
        });
        let ack2 = foe(FoeRepr::Ack { packet: 2 });
        assert_eq!(
            after(
                MailboxType::Foe,
                &d2,
                Some((MailboxType::Foe, &ack2)),
                t,
                SIZES
            ),
            None
        );
    }

    #[test]
    fn soe_write_fragments_get_no_answer_and_hold_the_slave() {
        // Write request, incomplete, 2 fragments left.
        let fragment = [0x0B, 0x40, 0x02, 0x00, 1, 2, 3, 4];
        assert!(matches!(
            expect(MailboxType::Soe, &fragment, None),
            Expect::Nothing
        ));
        assert_eq!(
            after(MailboxType::Soe, &fragment, None, None, SIZES),
            Some(Transfer::SoeWrite)
        );
        let read = [0x01, 0x40, 0x20, 0x00];
        assert!(matches!(
            expect(MailboxType::Soe, &read, None),
            Expect::Replies(_)
        ));
    }

    #[test]
    fn only_messages_that_stand_alone_or_open_a_transfer_are_broadcast() {
        let sdo = |r: SdoRequest<'_>| r.to_vec().unwrap();
        let upload = sdo(SdoRequest::InitiateUpload {
            index: 0x1018,
            subindex: 1,
            complete_access: false,
        });
        let download = sdo(SdoRequest::InitiateDownload {
            index: 0x2000,
            subindex: 0,
            complete_access: false,
            payload: SdoPayload::Expedited(&[1]),
        });
        let download_segment = sdo(SdoRequest::DownloadSegment {
            toggle: false,
            last: true,
            data: &[1, 2, 3],
        });
        let upload_segment = sdo(SdoRequest::UploadSegment { toggle: true });
        let abort = [0x00, 0x20, 0x80, 0x00, 0x20, 0x00, 0, 0, 0, 0x08];
        let info = [0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00];
        assert!(broadcastable(MailboxType::Coe, &upload));
        assert!(broadcastable(MailboxType::Coe, &download));
        assert!(broadcastable(MailboxType::Coe, &info));
        assert!(!broadcastable(MailboxType::Coe, &download_segment));
        assert!(!broadcastable(MailboxType::Coe, &upload_segment));
        assert!(!broadcastable(MailboxType::Coe, &abort));

        let rrq = foe(FoeRepr::ReadRequest {
            password: 0,
            file_name: b"f",
        });
        let wrq = foe(FoeRepr::WriteRequest {
            password: 0,
            file_name: b"f",
        });
        assert!(broadcastable(MailboxType::Foe, &rrq));
        assert!(broadcastable(MailboxType::Foe, &wrq));
        for step in [
            FoeRepr::Data {
                packet: 1,
                data: &[1],
            },
            FoeRepr::Ack { packet: 1 },
            FoeRepr::Error {
                code: foe::FoeError::NotDefined,
                text: b"",
            },
            FoeRepr::Busy {
                done: 1,
                entire: 2,
                text: b"",
            },
        ] {
            assert!(!broadcastable(MailboxType::Foe, &foe(step)), "{step:?}");
        }

        // SoE: a read and a whole write go; a write fragment with more to come does not.
        assert!(broadcastable(MailboxType::Soe, &[0x01, 0x40, 0x20, 0x00]));
        assert!(broadcastable(
            MailboxType::Soe,
            &[0x03, 0x40, 0x20, 0x00, 1, 0]
        ));
        assert!(!broadcastable(
            MailboxType::Soe,
            &[0x0B, 0x40, 0x02, 0x00, 1, 2, 3, 4]
        ));
        assert!(broadcastable(MailboxType::Voe, &[0x64, 0x11, 0, 0, 1, 0]));
    }
}
