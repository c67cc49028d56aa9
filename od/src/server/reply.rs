//! Emitting replies through the codec into a reused buffer and handing them to the
//! caller's sink, fragmenting SDO Information answers that do not fit SM1.

use ecat_wire::coe::AbortCode;
use ecat_wire::coe::info::{SDO_INFO_HEADER_LEN, SdoInfoFrame, SdoInfoRepr, SdoInfoService};
use ecat_wire::coe::sdo::SdoFrame;
use ecat_wire::coe::sdo_response::SdoResponse;

/// The reply side of one request.
pub(super) struct Replies<'a> {
    buf: &'a mut Vec<u8>,
    sink: &'a mut dyn FnMut(&[u8]),
    /// Most bytes of mailbox data one reply may have (SM1 size − 6).
    capacity: usize,
    count: usize,
}

impl<'a> Replies<'a> {
    pub(super) fn new(
        buf: &'a mut Vec<u8>,
        sink: &'a mut dyn FnMut(&[u8]),
        capacity: usize,
    ) -> Self {
        Replies {
            buf,
            sink,
            capacity,
            count: 0,
        }
    }

    /// Replies sent so far.
    pub(super) fn count(&self) -> usize {
        self.count
    }

    /// Most bytes of mailbox data one reply may have.
    pub(super) fn capacity(&self) -> usize {
        self.capacity
    }

    fn send(&mut self) {
        (self.sink)(self.buf);
        self.count += 1;
    }

    /// Sends an SDO response. Emit cannot fail for the responses the server builds (they
    /// are sized from the mailbox); should it, the client gets a general-error abort rather
    /// than nothing.
    pub(super) fn sdo(&mut self, response: &SdoResponse<'_>) {
        let fallback = SdoResponse::Abort {
            index: 0,
            subindex: 0,
            code: AbortCode::GeneralError,
        };
        if self.emit_sdo(response) || self.emit_sdo(&fallback) {
            self.send();
        }
    }

    fn emit_sdo(&mut self, response: &SdoResponse<'_>) -> bool {
        let len = response.buffer_len();
        if len > self.capacity {
            return false;
        }
        self.buf.clear();
        self.buf.resize(len, 0);
        response
            .emit(&mut SdoFrame::new_unchecked(&mut self.buf[..]))
            .is_ok()
    }

    /// Sends an SDO abort.
    pub(super) fn abort(&mut self, index: u16, subindex: u8, code: AbortCode) {
        self.sdo(&SdoResponse::Abort {
            index,
            subindex,
            code,
        });
    }

    /// Sends an SDO Info error (opcode 7).
    pub(super) fn info_error(&mut self, code: AbortCode) {
        self.info(SdoInfoService::Error { code });
    }

    /// Sends an SDO Information answer, in fragments if it exceeds the mailbox
    /// (spec-notes §coe.info): each fragment carries the next piece of the service data, all but the last
    /// have Incomplete set, and Fragments-left counts down to 0. Pieces have an even size
    /// so that clients reading OD-list words fragment by fragment never see a split word.
    pub(super) fn info(&mut self, service: SdoInfoService<'_>) {
        let repr = SdoInfoRepr {
            incomplete: false,
            fragments_left: 0,
            service,
        };
        let len = repr.buffer_len();
        self.buf.clear();
        self.buf.resize(len, 0);
        if repr
            .emit(&mut SdoInfoFrame::new_unchecked(&mut self.buf[..]))
            .is_err()
        {
            return self.info_error(AbortCode::GeneralError);
        }
        if len <= self.capacity {
            return self.send();
        }
        let piece = self.capacity.saturating_sub(SDO_INFO_HEADER_LEN) & !1;
        let data_len = len - SDO_INFO_HEADER_LEN;
        let fragments = data_len.div_ceil(piece.max(1));
        if piece == 0 || fragments - 1 > usize::from(u16::MAX) {
            return self.info_error(AbortCode::ObjectTooLong);
        }
        let opcode = repr.service.opcode();
        let whole = std::mem::take(self.buf);
        let (header, data) = whole.split_at(SDO_INFO_HEADER_LEN);
        for (k, chunk) in data.chunks(piece).enumerate() {
            let left = (fragments - 1 - k) as u16;
            self.buf.clear();
            self.buf.extend_from_slice(header);
            self.buf.resize(SDO_INFO_HEADER_LEN + chunk.len(), 0);
            let mut frame = SdoInfoFrame::new_unchecked(&mut self.buf[..]);
            frame.set_opcode(opcode, left > 0);
            frame.set_fragments_left(left);
            frame.data_mut().copy_from_slice(chunk);
            self.send();
        }
        // Keep the larger allocation for the next request.
        *self.buf = whole;
    }
}
