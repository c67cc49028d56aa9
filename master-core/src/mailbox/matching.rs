//! Which reply answers which request, for messages the engine forwards without running the
//! protocol itself (the gateway's raw path).
//!
//! A reply of the right mailbox type is not necessarily the answer: a slave that answered
//! late (after the previous request timed out) leaves that answer in its send mailbox, and
//! it must never be taken for the next request's. So a reply is checked against what the
//! request asked for, as far as the protocol lets one tell:
//! - SDO (ETG.1000.6 §5.6.2): an initiate is answered by the initiate response of the same
//!   kind for the same index and subindex (any subindex with complete access), a segment by
//!   the segment response of the same kind with the same toggle bit; an abort in either
//!   CoE service (§5.6.2.7) answers an initiate of its object and any segment;
//! - SDO Information (§5.6.3): the response opcode of the request, or its error; an object
//!   or entry description must describe the object asked for;
//! - SoE (ETG.1000.6 §5.7): the response opcode of the request for the same drive, and for
//!   a complete (not fragmented) answer the same IDN;
//! - anything else (FoE, VoE, EoE, other CoE services): any message of the type.
//!
//! A mailbox error reply (type 0) answers any request.

use crate::wire::coe::info::SdoInfoOpcode;
use crate::wire::coe::{CoeFrame, CoeService, SdoFrame, SdoInfoFrame};
use crate::wire::mailbox::MailboxType;
use crate::wire::soe::{SoeOpcode, SoePacket};

/// Client command specifiers of SDO requests (bits 5-7 of the command byte, service 2).
mod ccs {
    pub const DOWNLOAD_SEGMENT: u8 = 0;
    pub const INITIATE_DOWNLOAD: u8 = 1;
    pub const INITIATE_UPLOAD: u8 = 2;
    pub const UPLOAD_SEGMENT: u8 = 3;
}

/// Server command specifiers of SDO responses (service 3).
mod scs {
    pub const UPLOAD_SEGMENT: u8 = 0;
    pub const DOWNLOAD_SEGMENT: u8 = 1;
    pub const INITIATE_UPLOAD: u8 = 2;
    pub const INITIATE_DOWNLOAD: u8 = 3;
}

/// Command byte bit 4: complete access in an initiate, toggle in a segment.
const BIT4: u8 = 0x10;

/// Whether the first fragment's service data (`data`) of an SDO Information description
/// describes `about` (index, and subindex for an entry description): both descriptions start
/// with the index, an entry description has the subindex right behind it (ETG.1000.6
/// §5.6.3.5, §5.6.3.6).
pub(crate) fn describes(data: &[u8], about: Option<(u16, Option<u8>)>) -> bool {
    let Some((index, subindex)) = about else {
        return true;
    };
    let index_ok = data.get(..2).is_some_and(|b| b == index.to_le_bytes());
    let subindex_ok = subindex.is_none_or(|sub| data.get(2) == Some(&sub));
    index_ok && subindex_ok
}

/// Whether `reply` (mailbox data of a message of type `reply_type`) can be the answer to
/// `request` (mailbox data of a message of type `request_type`).
pub(crate) fn answers(
    request_type: MailboxType,
    request: &[u8],
    reply_type: MailboxType,
    reply: &[u8],
) -> bool {
    if reply_type == MailboxType::Error {
        return true;
    }
    if reply_type != request_type {
        return false;
    }
    match request_type {
        MailboxType::Coe => coe_answers(request, reply),
        MailboxType::Soe => soe_answers(request, reply),
        _ => true,
    }
}

fn coe_answers(request: &[u8], reply: &[u8]) -> bool {
    let Ok(asked) = CoeFrame::new_checked(request) else {
        return true;
    };
    match asked.service() {
        CoeService::SdoRequest => match SdoFrame::new_checked(request) {
            Ok(asked) => sdo_answers(&asked, reply),
            Err(_) => true,
        },
        CoeService::SdoInfo => match SdoInfoFrame::new_checked(request) {
            Ok(asked) => info_answers(&asked, reply),
            Err(_) => true,
        },
        _ => true,
    }
}

fn sdo_answers(asked: &SdoFrame<&[u8]>, reply: &[u8]) -> bool {
    let Ok(answer) = SdoFrame::new_checked(reply) else {
        return false;
    };
    let command = asked.command();
    let initiate = matches!(
        asked.specifier(),
        ccs::INITIATE_DOWNLOAD | ccs::INITIATE_UPLOAD
    );
    let complete_access = initiate && command & BIT4 != 0;
    let same_object = |index: u16, subindex: u8| {
        index == asked.index() && (complete_access || subindex == asked.subindex())
    };
    if let Some((index, subindex, _)) = answer.any_abort() {
        // During segments the abort may name the object or nothing; the request does not.
        return !initiate || same_object(index, subindex) || (index == 0 && subindex == 0);
    }
    if answer.service() != CoeService::SdoResponse {
        return false;
    }
    let toggle = |frame: &SdoFrame<&[u8]>| frame.command() & BIT4;
    match (asked.specifier(), answer.specifier()) {
        (ccs::INITIATE_UPLOAD, scs::INITIATE_UPLOAD)
        | (ccs::INITIATE_DOWNLOAD, scs::INITIATE_DOWNLOAD) => {
            same_object(answer.index(), answer.subindex())
        }
        (ccs::UPLOAD_SEGMENT, scs::UPLOAD_SEGMENT)
        | (ccs::DOWNLOAD_SEGMENT, scs::DOWNLOAD_SEGMENT) => toggle(asked) == toggle(&answer),
        // Block transfers and what else we do not know: not ours to judge.
        (specifier, _) if specifier > ccs::UPLOAD_SEGMENT => true,
        _ => false,
    }
}

fn info_answers(asked: &SdoInfoFrame<&[u8]>, reply: &[u8]) -> bool {
    let Ok(answer) = SdoInfoFrame::new_checked(reply) else {
        return false;
    };
    if answer.service() != CoeService::SdoInfo {
        return false;
    }
    let expect = match asked.opcode() {
        SdoInfoOpcode::OdListRequest => SdoInfoOpcode::OdListResponse,
        SdoInfoOpcode::ObjectDescriptionRequest => SdoInfoOpcode::ObjectDescriptionResponse,
        SdoInfoOpcode::EntryDescriptionRequest => SdoInfoOpcode::EntryDescriptionResponse,
        _ => return true,
    };
    let opcode = answer.opcode();
    if opcode == SdoInfoOpcode::Error {
        return true;
    }
    let request = asked.data();
    let about = match asked.opcode() {
        SdoInfoOpcode::ObjectDescriptionRequest => request
            .get(..2)
            .map(|b| (u16::from_le_bytes([b[0], b[1]]), None)),
        SdoInfoOpcode::EntryDescriptionRequest => request
            .get(..3)
            .map(|b| (u16::from_le_bytes([b[0], b[1]]), Some(b[2]))),
        _ => None,
    };
    opcode == expect && describes(answer.data(), about)
}

fn soe_answers(request: &[u8], reply: &[u8]) -> bool {
    let (Ok(asked), Ok(answer)) = (
        SoePacket::new_checked(request),
        SoePacket::new_checked(reply),
    ) else {
        return SoePacket::new_checked(request).is_err();
    };
    let expect = match asked.opcode() {
        SoeOpcode::ReadRequest => SoeOpcode::ReadResponse,
        SoeOpcode::WriteRequest => SoeOpcode::WriteResponse,
        _ => return true,
    };
    answer.opcode() == expect
        && answer.drive() == asked.drive()
        && (answer.incomplete() || answer.idn_or_fragments() == asked.idn_or_fragments())
}

#[cfg(test)]
mod tests {
    use super::*;

    const UPLOAD_6040: [u8; 10] = [0x00, 0x20, 0x40, 0x40, 0x60, 0x00, 0, 0, 0, 0];

    #[test]
    fn an_sdo_answer_for_another_object_is_not_the_answer() {
        let coe = MailboxType::Coe;
        let ours = [0x00, 0x30, 0x4b, 0x40, 0x60, 0x00, 0x0f, 0x00, 0, 0];
        let other_index = [0x00, 0x30, 0x4b, 0x41, 0x60, 0x00, 0x0f, 0x00, 0, 0];
        let other_sub = [0x00, 0x30, 0x4b, 0x40, 0x60, 0x01, 0x0f, 0x00, 0, 0];
        assert!(answers(coe, &UPLOAD_6040, coe, &ours));
        assert!(!answers(coe, &UPLOAD_6040, coe, &other_index));
        assert!(!answers(coe, &UPLOAD_6040, coe, &other_sub));
        // A download response is no answer to an upload.
        let ack = [0x00, 0x30, 0x60, 0x40, 0x60, 0x00, 0, 0, 0, 0];
        assert!(!answers(coe, &UPLOAD_6040, coe, &ack));
    }

    #[test]
    fn an_abort_in_service_2_with_low_bits_answers_its_object_only() {
        let coe = MailboxType::Coe;
        let abort = [0x00, 0x20, 0x8b, 0x40, 0x60, 0x00, 0x00, 0x00, 0x02, 0x06];
        let other = [0x00, 0x20, 0x80, 0x41, 0x60, 0x00, 0x00, 0x00, 0x02, 0x06];
        assert!(answers(coe, &UPLOAD_6040, coe, &abort));
        assert!(!answers(coe, &UPLOAD_6040, coe, &other));
        // A segment request carries no object: any abort ends it.
        let segment = [0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0];
        assert!(answers(coe, &segment, coe, &other));
    }

    #[test]
    fn segments_match_by_toggle_and_errors_answer_anything() {
        let coe = MailboxType::Coe;
        let segment = [0x00, 0x20, 0x70, 0, 0, 0, 0, 0, 0, 0];
        let toggled = [0x00, 0x30, 0x10, 1, 2, 3, 4, 5, 6, 7];
        let untoggled = [0x00, 0x30, 0x00, 1, 2, 3, 4, 5, 6, 7];
        assert!(answers(coe, &segment, coe, &toggled));
        assert!(!answers(coe, &segment, coe, &untoggled));
        assert!(answers(
            coe,
            &segment,
            MailboxType::Error,
            &[0x01, 0x00, 0x02, 0x00]
        ));
        assert!(!answers(coe, &segment, MailboxType::Soe, &toggled));
    }

    #[test]
    fn an_entry_description_of_another_entry_is_not_the_answer() {
        let coe = MailboxType::Coe;
        // Get Entry Description 0x1018:02, value info 0.
        let request = [0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x18, 0x10, 0x02, 0x00];
        let mut reply = vec![0x00, 0x80, 0x06, 0x00, 0x00, 0x00, 0x18, 0x10, 0x02, 0x00];
        reply.extend_from_slice(&[0x07, 0x00, 0x20, 0x00, 0x07, 0x00]);
        assert!(answers(coe, &request, coe, &reply));
        reply[8] = 0x01;
        assert!(!answers(coe, &request, coe, &reply));
        let error = [0x00, 0x80, 0x07, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x06];
        assert!(answers(coe, &request, coe, &error));
    }

    #[test]
    fn a_late_soe_answer_of_another_idn_or_opcode_is_not_the_answer() {
        let soe = MailboxType::Soe;
        // Read request, drive 0, value element, IDN S-0-0032.
        let read = [0x01, 0x40, 0x20, 0x00];
        let answer = [0x02, 0x40, 0x20, 0x00, 0x01, 0x00];
        let other_idn = [0x02, 0x40, 0x21, 0x00, 0x01, 0x00];
        let write_answer = [0x04, 0x40, 0x20, 0x00];
        assert!(answers(soe, &read, soe, &answer));
        assert!(!answers(soe, &read, soe, &other_idn));
        assert!(!answers(soe, &read, soe, &write_answer));
    }
}
