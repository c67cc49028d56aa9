//! How other slave stacks' CoE servers differ from ours on the wire, switched on per slave
//! so that tests keep a master honest about them (all off by default):
//!
//! - SDO aborts in CoE service 2: ETG.1000.6 §5.6.2.7 calls the abort "Abort SDO Transfer
//!   Request", and SOES sends every abort with the request service;
//! - abort command bytes with the request's low bits left set (0x8b, 0x8f, 0x91 instead of
//!   0x80), only the command specifier (bits 5-7 = 4) marking the abort;
//! - SDO Information error replies whose mailbox length is 6, the abort code left outside;
//! - complete access refused with abort 0x08000000 (a stack built without it);
//! - every wrong-length download aborted with 0x06070010 (SOES), not 0x06070012/0x06070013.

use ecat_wire::Emit;
use ecat_wire::coe::AbortCode;
use ecat_wire::coe::sdo::SdoFrame;
use ecat_wire::coe::sdo_response::SdoResponse;
use ecat_wire::coe::{CoeFrame, CoeService, SdoInfoFrame};

/// Command specifier of an abort (bits 5-7).
const ABORT_SPECIFIER: u8 = 4;
/// Client command specifiers of initiate download (1) and initiate upload (2).
const INITIATE: [u8; 2] = [1, 2];
/// Command bit 4 of an initiate: complete access.
const COMPLETE_ACCESS: u8 = 0x10;
/// SDO Information opcode of an error reply (bits 0-6).
const INFO_ERROR: u8 = 7;
/// Mailbox length of an SDO Information error without its code: CoE header, opcode,
/// reserved byte, fragments left.
const SHORT_INFO_ERROR_LEN: usize = 6;

/// The CoE behaviours of other stacks a simulated slave shows.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CoeQuirks {
    /// SDO aborts go out in CoE service 2 (SDO request), as SOES sends them.
    pub abort_in_request_service: bool,
    /// An abort's command byte keeps the low 5 bits of the request's (0x80 | bits).
    pub abort_keeps_command_bits: bool,
    /// SDO Information errors declare a mailbox length of 6, the abort code outside.
    pub short_info_errors: bool,
    /// Complete access is refused with abort 0x08000000.
    pub refuse_complete_access: bool,
    /// A download of the wrong length is aborted with 0x06070010 ("length does not
    /// match"), whether too long or too short.
    pub length_mismatch_only: bool,
}

impl CoeQuirks {
    /// The abort (CoE mailbox data) that refuses `request`, if it asks for complete
    /// access and this slave refuses that.
    pub fn refusal(&self, request: &[u8]) -> Option<Vec<u8>> {
        if !self.refuse_complete_access {
            return None;
        }
        let frame = SdoFrame::new_checked(request).ok()?;
        let initiate = INITIATE.contains(&frame.specifier());
        if frame.service() != CoeService::SdoRequest
            || !initiate
            || frame.command() & COMPLETE_ACCESS == 0
        {
            return None;
        }
        let abort = SdoResponse::Abort {
            index: frame.index(),
            subindex: frame.subindex(),
            code: AbortCode::GeneralError,
        };
        abort.to_vec().ok()
    }

    /// Rewrites one reply (CoE mailbox data) of the server to `request` the way this
    /// slave's stack would have sent it.
    pub fn apply(&self, request: &[u8], reply: &mut Vec<u8>) {
        let Ok(frame) = CoeFrame::new_checked(&reply[..]) else {
            return;
        };
        match frame.service() {
            CoeService::SdoResponse => self.rewrite_abort(request, reply),
            CoeService::SdoInfo if self.short_info_errors => {
                let is_error = SdoInfoFrame::new_checked(&reply[..])
                    .is_ok_and(|f| u8::from(f.opcode()) & 0x7f == INFO_ERROR);
                if is_error {
                    reply.truncate(SHORT_INFO_ERROR_LEN);
                }
            }
            _ => {}
        }
    }

    fn rewrite_abort(&self, request: &[u8], reply: &mut [u8]) {
        let is_abort = SdoFrame::new_checked(&reply[..])
            .is_ok_and(|f| f.specifier() == ABORT_SPECIFIER && f.any_abort().is_some());
        if !is_abort {
            return;
        }
        if self.length_mismatch_only {
            let code = u32::from_le_bytes([reply[6], reply[7], reply[8], reply[9]]);
            let code = AbortCode::from(code);
            if matches!(code, AbortCode::LengthTooHigh | AbortCode::LengthTooLow) {
                reply[6..10].copy_from_slice(&u32::from(AbortCode::LengthMismatch).to_le_bytes());
            }
        }
        if self.abort_in_request_service {
            // CoE header byte 1: service in bits 4-7 (number bits 8 and up are 0).
            reply[1] = (reply[1] & 0x0f) | (u8::from(CoeService::SdoRequest) << 4);
        }
        if self.abort_keeps_command_bits
            && let Some(command) = request.get(2)
        {
            reply[2] = (ABORT_SPECIFIER << 5) | (command & 0x1f);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Upload request 0x2000:01 with complete access (0x50) and its server's abort.
    const CA_UPLOAD: [u8; 10] = [0x00, 0x20, 0x50, 0x00, 0x20, 0x01, 0, 0, 0, 0];
    const ABORT: [u8; 10] = [0x00, 0x30, 0x80, 0x00, 0x20, 0x01, 0x00, 0x00, 0x02, 0x06];

    #[test]
    fn aborts_as_soes_sends_them() {
        let quirks = CoeQuirks {
            abort_in_request_service: true,
            abort_keeps_command_bits: true,
            ..CoeQuirks::default()
        };
        let mut reply = ABORT.to_vec();
        quirks.apply(&CA_UPLOAD, &mut reply);
        assert_eq!(
            reply,
            [0x00, 0x20, 0x90, 0x00, 0x20, 0x01, 0x00, 0x00, 0x02, 0x06]
        );
        // Without switches nothing changes; other replies are never touched.
        let mut plain = ABORT.to_vec();
        CoeQuirks::default().apply(&CA_UPLOAD, &mut plain);
        assert_eq!(plain, ABORT);
        let mut upload = vec![0x00, 0x30, 0x4f, 0x00, 0x20, 0x01, 7, 0, 0, 0];
        quirks.apply(&CA_UPLOAD, &mut upload);
        assert_eq!(upload, [0x00, 0x30, 0x4f, 0x00, 0x20, 0x01, 7, 0, 0, 0]);
    }

    #[test]
    fn wrong_lengths_are_one_mismatch() {
        let quirks = CoeQuirks {
            length_mismatch_only: true,
            ..CoeQuirks::default()
        };
        let mut too_short = vec![0x00, 0x30, 0x80, 0x00, 0x20, 0x01, 0x13, 0x00, 0x07, 0x06];
        quirks.apply(&[], &mut too_short);
        assert_eq!(too_short[6..], [0x10, 0x00, 0x07, 0x06]);
        let mut missing = ABORT.to_vec();
        quirks.apply(&[], &mut missing);
        assert_eq!(missing, ABORT);
    }

    #[test]
    fn short_info_errors_lose_their_code() {
        let quirks = CoeQuirks {
            short_info_errors: true,
            ..CoeQuirks::default()
        };
        let mut error = vec![0x00, 0x80, 0x07, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x06];
        quirks.apply(&[], &mut error);
        assert_eq!(error, [0x00, 0x80, 0x07, 0x00, 0x00, 0x00]);
    }

    #[test]
    fn complete_access_refused_with_a_general_error() {
        let quirks = CoeQuirks {
            refuse_complete_access: true,
            ..CoeQuirks::default()
        };
        let refusal = quirks.refusal(&CA_UPLOAD).unwrap();
        assert_eq!(
            refusal,
            [0x00, 0x30, 0x80, 0x00, 0x20, 0x01, 0x00, 0x00, 0x00, 0x08]
        );
        let plain = [0x00, 0x20, 0x40, 0x00, 0x20, 0x01, 0, 0, 0, 0];
        assert_eq!(quirks.refusal(&plain), None);
        assert_eq!(CoeQuirks::default().refusal(&CA_UPLOAD), None);
    }
}
