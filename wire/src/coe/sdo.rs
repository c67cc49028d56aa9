//! The SDO frame (ETG.1000.6, spec-notes §coe.sdo): the view shared by requests and responses, the
//! command-byte bit layout, and the payload rules of initiate and segment frames.
//!
//! ```text
//! mailbox data offset 0  u16  CoE header (service 2 = request, 3 = response)
//!                     2  u8   command specifier byte
//!   initiate/abort:   3  u16  index
//!                     5  u8   subindex
//!                     6  4    data field: expedited value, complete size, abort code or 0
//!                    10  n    further data of a normal transfer
//!   segments:         3  n    segment data (padded to 7 bytes; see below)
//! ```
//!
//! The view wraps the mailbox *data*, so its buffer length **is** the mailbox length, which
//! the segment rule needs: with mailbox length 10 the segment carries `7 − unused` bytes
//! (unused = command bits 1-3), otherwise `length − 3` bytes.
//!
//! Tolerated deviations (spec-notes §coe.sdo-short; the gateway relies on them), accepted by parse but
//! never produced by emit:
//! - an initiate frame shorter than 10 bytes whose data field is not needed (upload request
//!   of 8 bytes);
//! - a download (or upload response) with command bits 0-1 clear (0x20) and 1-4 data bytes
//!   in a frame of at most 10 bytes: expedited, size taken from the bytes present.

use crate::coe::abort::AbortCode;
use crate::coe::header::CoeService;
use crate::error::{Result, WireError, need};
use crate::field::{self, Field, Rest};

mod fields {
    use super::{Field, Rest};
    pub const COE_HEADER: Field = 0..2;
    pub const COMMAND: usize = 2;
    pub const INDEX: Field = 3..5;
    pub const SUBINDEX: usize = 5;
    pub const DATA_FIELD: Field = 6..10;
    pub const EXTRA: Rest = 10..;
    pub const SEGMENT: Rest = 3..;
}

/// Offset of the 4-byte data field in the mailbox data.
pub const SDO_DATA_FIELD_OFFSET: usize = fields::DATA_FIELD.start;
/// Smallest SDO frame this view accepts: CoE header, command, index, subindex.
pub const SDO_MIN_LEN: usize = fields::SUBINDEX + 1;
/// Mailbox length of an initiate, abort, or padded segment frame (CoE header + 8 bytes).
pub const SDO_INITIATE_LEN: usize = fields::DATA_FIELD.end;
/// Bytes of data in the minimum (padded) segment.
pub const SEGMENT_MIN_DATA: usize = SDO_INITIATE_LEN - fields::SEGMENT.start;
/// Bytes in front of the segment data (CoE header + command byte).
pub const SEGMENT_HEADER_LEN: usize = fields::SEGMENT.start;

/// Command specifier of an abort in either direction (bits 5-7 of the command byte).
const ABORT_SPECIFIER: u8 = 4;

/// Command byte bits (ETG.1000.6, spec-notes §coe.sdo).
pub(crate) mod cmd {
    /// Bits 5-7: client/server command specifier.
    pub const SPECIFIER_SHIFT: u8 = 5;
    /// Initiate: bit 0, size indicated.
    pub const SIZE_INDICATED: u8 = 0x01;
    /// Initiate: bit 1, expedited.
    pub const EXPEDITED: u8 = 0x02;
    /// Initiate: bits 2-3, unused bytes of the expedited value.
    pub const EXPEDITED_UNUSED_SHIFT: u8 = 2;
    /// Initiate: bit 4, complete access.
    pub const COMPLETE_ACCESS: u8 = 0x10;
    /// Segment: bit 0, last segment.
    pub const LAST: u8 = 0x01;
    /// Segment: bits 1-3, unused bytes of the 7-byte minimum segment.
    pub const SEGMENT_UNUSED_SHIFT: u8 = 1;
    /// Segment: bit 4, toggle.
    pub const TOGGLE: u8 = 0x10;
    /// Abort: full command byte.
    pub const ABORT: u8 = 0x80;
}

/// Most data bytes an initiate (normal) frame carries in a mailbox of `mailbox_size` bytes
/// (the SyncManager length): M − 16 = 6 mailbox + 2 CoE + 8 SDO header (spec-notes §coe.sdo).
pub const fn max_initiate_data(mailbox_size: usize) -> usize {
    mailbox_size.saturating_sub(crate::mailbox::HEADER_LEN + SDO_INITIATE_LEN)
}

/// Most data bytes a segment frame carries in a mailbox of `mailbox_size` bytes:
/// M − 9 = 6 mailbox + 2 CoE + 1 command byte (ETG.1000.6, spec-notes §coe.sdo).
pub const fn max_segment_data(mailbox_size: usize) -> usize {
    mailbox_size.saturating_sub(crate::mailbox::HEADER_LEN + SEGMENT_HEADER_LEN)
}

/// A view of an SDO request or response (mailbox data starting with the CoE header).
#[derive(Debug, Clone)]
pub struct SdoFrame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> SdoFrame<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        SdoFrame { buffer }
    }

    /// Wraps a buffer and checks the minimum length.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let frame = Self::new_unchecked(buffer);
        frame.check_len()?;
        Ok(frame)
    }

    /// Checks that CoE header, command, index and subindex are present (6 bytes).
    ///
    /// Every standard SDO frame has at least 10 bytes (segments are padded); 6 is the least
    /// that still lets every accessor here work, which admits the tolerated short forms. The
    /// data field and further data are returned as (possibly short or empty) slices.
    pub fn check_len(&self) -> Result<()> {
        need("SDO frame", self.buffer.as_ref(), SDO_MIN_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// The mailbox length (= buffer length).
    pub fn mailbox_len(&self) -> usize {
        self.buffer.as_ref().len()
    }

    /// CoE service from the CoE header (2 = request, 3 = response).
    pub fn service(&self) -> CoeService {
        CoeService::from(self.buffer.as_ref()[fields::COE_HEADER.end - 1] >> 4)
    }

    /// The command specifier byte.
    pub fn command(&self) -> u8 {
        self.buffer.as_ref()[fields::COMMAND]
    }

    /// The command specifier (bits 5-7 of the command byte).
    pub fn specifier(&self) -> u8 {
        self.command() >> cmd::SPECIFIER_SHIFT
    }

    /// Index (initiate and abort frames).
    pub fn index(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::INDEX.start)
    }

    /// Subindex (initiate and abort frames).
    pub fn subindex(&self) -> u8 {
        self.buffer.as_ref()[fields::SUBINDEX]
    }

    /// The 4-byte data field, or as much of it as the frame holds.
    pub fn data_field(&self) -> &[u8] {
        let buf = self.buffer.as_ref();
        let end = buf.len().min(fields::DATA_FIELD.end);
        &buf[fields::DATA_FIELD.start..end]
    }

    /// The data field as a u32 (complete size or abort code), if all 4 bytes are present.
    pub fn data_field_u32(&self) -> Option<u32> {
        let f = self.data_field();
        (f.len() == 4).then(|| field::u32_le(f, 0))
    }

    /// Index, subindex and abort code of an abort frame, which has the same layout in both
    /// directions (ETG.1000.6, spec-notes §coe.sdo, command specifier 4).
    pub fn abort_fields(&self) -> Result<(u16, u8, AbortCode)> {
        need("SDO abort", self.buffer.as_ref(), SDO_INITIATE_LEN)?;
        let code = AbortCode::from(self.data_field_u32().unwrap_or(0));
        Ok((self.index(), self.subindex(), code))
    }

    /// Index, subindex and abort code if this frame is an SDO abort as any server may send
    /// it: CoE service 2 (ETG.1000.6 §5.6.2.7 names it "Abort SDO Transfer Request", and
    /// SOES sends every abort that way) or 3, recognised by the command specifier alone
    /// (bits 5-7 = 4), whatever the low bits (some stacks leave the request's there: 0x8b,
    /// 0x8f, 0x91). `None` for anything else, and for an abort too short to carry its code.
    pub fn any_abort(&self) -> Option<(u16, u8, AbortCode)> {
        let service = self.service();
        let sdo = matches!(service, CoeService::SdoRequest | CoeService::SdoResponse);
        if !sdo || self.specifier() != ABORT_SPECIFIER {
            return None;
        }
        self.abort_fields().ok()
    }

    /// The bytes after the 8-byte SDO header (data of a normal initiate frame).
    pub fn extra(&self) -> &[u8] {
        self.buffer.as_ref().get(fields::EXTRA).unwrap_or(&[])
    }

    /// The data of a segment frame, by the 7-byte minimum rule (ETG.1000.6, spec-notes §coe.sdo).
    pub fn segment_data(&self) -> &[u8] {
        segment_data_of(self.buffer.as_ref())
    }
}

impl<'a> SdoFrame<&'a [u8]> {
    /// The whole frame with the lifetime of the underlying buffer (for borrowing parses).
    pub fn bytes(&self) -> &'a [u8] {
        self.buffer
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> SdoFrame<T> {
    /// Sets the command byte.
    pub fn set_command(&mut self, value: u8) {
        self.buffer.as_mut()[fields::COMMAND] = value
    }

    /// Sets the index.
    pub fn set_index(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::INDEX.start, value)
    }

    /// Sets the subindex.
    pub fn set_subindex(&mut self, value: u8) {
        self.buffer.as_mut()[fields::SUBINDEX] = value
    }

    /// The whole mutable buffer (emit writes the CoE header and the frame through it).
    pub fn buffer_mut(&mut self) -> &mut [u8] {
        self.buffer.as_mut()
    }
}

/// Segment data of a frame by the 7-byte minimum rule; the caller checked `len >= 3`.
fn segment_data_of(buf: &[u8]) -> &[u8] {
    let start = fields::SEGMENT.start;
    if buf.len() == SDO_INITIATE_LEN {
        let unused = usize::from((buf[fields::COMMAND] >> cmd::SEGMENT_UNUSED_SHIFT) & 0x07);
        &buf[start..SDO_INITIATE_LEN - unused]
    } else {
        buf.get(start..).unwrap_or(&[])
    }
}

impl<'a> SdoFrame<&'a [u8]> {
    /// The data field (possibly short) with the lifetime of the underlying buffer.
    pub fn data_field_ref(&self) -> &'a [u8] {
        let end = self.buffer.len().min(fields::DATA_FIELD.end);
        self.buffer
            .get(fields::DATA_FIELD.start..end)
            .unwrap_or(&[])
    }

    /// Further data (after the 8-byte SDO header) with the lifetime of the buffer.
    pub fn extra_ref(&self) -> &'a [u8] {
        self.buffer.get(fields::EXTRA).unwrap_or(&[])
    }

    /// Segment data with the lifetime of the underlying buffer.
    pub fn segment_data_ref(&self) -> &'a [u8] {
        segment_data_of(self.buffer)
    }
}

/// Writes an initiate or abort frame: CoE header, command, index, subindex, data field and
/// further data. The caller validated the values and checked the room.
pub(crate) fn write_initiate(
    buf: &mut [u8],
    service: CoeService,
    command: u8,
    index: u16,
    subindex: u8,
    data_field: [u8; 4],
    extra: &[u8],
) {
    super::header::put_header(buf, service);
    let mut frame = SdoFrame::new_unchecked(&mut *buf);
    frame.set_command(command);
    frame.set_index(index);
    frame.set_subindex(subindex);
    buf[fields::DATA_FIELD].copy_from_slice(&data_field);
    buf[fields::EXTRA.start..fields::EXTRA.start + extra.len()].copy_from_slice(extra);
}

/// Frame length of a segment carrying `n` data bytes (padded to the 7-byte minimum).
pub(crate) const fn segment_len(n: usize) -> usize {
    if n < SEGMENT_MIN_DATA {
        SDO_INITIATE_LEN
    } else {
        SEGMENT_HEADER_LEN + n
    }
}

/// Writes a segment frame: `command` carries specifier, toggle and last; the unused count
/// (bits 1-3) is added here when `data` is shorter than 7 bytes, and the padding is zeroed.
pub(crate) fn write_segment(buf: &mut [u8], service: CoeService, command: u8, data: &[u8]) {
    super::header::put_header(buf, service);
    let unused = SEGMENT_MIN_DATA.saturating_sub(data.len()) as u8;
    buf[fields::COMMAND] = command | (unused << cmd::SEGMENT_UNUSED_SHIFT);
    let start = fields::SEGMENT.start;
    buf[start..start + data.len()].copy_from_slice(data);
    buf[start + data.len()..segment_len(data.len())].fill(0);
}

/// Writes a frame with only a command byte and 7 zero bytes (upload segment request,
/// download segment response).
pub(crate) fn write_bare(buf: &mut [u8], service: CoeService, command: u8) {
    super::header::put_header(buf, service);
    buf[fields::COMMAND] = command;
    buf[fields::SEGMENT.start..SDO_INITIATE_LEN].fill(0);
}

/// Refuses an SDO frame whose CoE service is not `expected`.
pub(crate) fn expect_service(
    what: &'static str,
    frame: &SdoFrame<&[u8]>,
    expected: CoeService,
) -> Result<()> {
    let service = frame.service();
    if service != expected {
        return Err(WireError::UnknownType {
            what,
            value: u32::from(u8::from(service)),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coe::sdo_payload::SdoPayload;
    use proptest::prelude::*;

    #[test]
    fn an_abort_in_either_service_with_any_low_bits() {
        // Service 3 with 0x80, service 2 (SOES) with 0x80 and with the request's low bits.
        for (service, command) in [(0x30, 0x80), (0x20, 0x80), (0x20, 0x8b), (0x30, 0x91)] {
            let f = [
                0x00, service, command, 0x00, 0x20, 0x01, 0x00, 0x00, 0x02, 0x06,
            ];
            let frame = SdoFrame::new_checked(&f[..]).unwrap();
            assert_eq!(
                frame.any_abort(),
                Some((0x2000, 1, AbortCode::ObjectDoesNotExist)),
                "service {service:#x} command {command:#x}"
            );
        }
        // Not an abort: another specifier, another service, or the code cut off.
        let upload = [0x00, 0x30, 0x4f, 0x00, 0x20, 0x01, 1, 0, 0, 0];
        assert_eq!(
            SdoFrame::new_checked(&upload[..]).unwrap().any_abort(),
            None
        );
        let info = [0x00, 0x80, 0x80, 0x00, 0x20, 0x01, 0, 0, 2, 6];
        assert_eq!(SdoFrame::new_checked(&info[..]).unwrap().any_abort(), None);
        let short = [0x00, 0x20, 0x80, 0x00, 0x20, 0x01, 0, 0];
        assert_eq!(SdoFrame::new_checked(&short[..]).unwrap().any_abort(), None);
    }

    #[test]
    fn size_helpers_match_c9() {
        // ETG.1000.6, spec-notes §coe.sdo: M = 24 → 8 bytes in the initiate frame, 15 per segment.
        assert_eq!(max_initiate_data(24), 8);
        assert_eq!(max_segment_data(24), 15);
        // 128-byte mailbox (ETG.1000.4, spec-notes §esc.sm): 112 / 119.
        assert_eq!(max_initiate_data(128), 112);
        assert_eq!(max_segment_data(128), 119);
        assert_eq!(max_initiate_data(10), 0);
    }

    #[test]
    fn segment_rule() {
        // Length 10, unused 5 → 2 bytes (ETG.1000.6, spec-notes §coe.sdo last segment).
        let f = [0x00, 0x20, 0x0b, 0xd8, 0xd9, 0, 0, 0, 0, 0];
        assert_eq!(
            SdoFrame::new_checked(&f[..]).unwrap().segment_data(),
            &[0xd8, 0xd9]
        );
        // Length 12: 9 bytes, unused bits ignored.
        let f = [0x00, 0x20, 0x0e, 1, 2, 3, 4, 5, 6, 7, 8, 9];
        assert_eq!(
            SdoFrame::new_checked(&f[..]).unwrap().segment_data().len(),
            9
        );
        // Length 10, unused 7 → no data.
        let f = [0x00, 0x20, 0x0f, 0, 0, 0, 0, 0, 0, 0];
        assert!(
            SdoFrame::new_checked(&f[..])
                .unwrap()
                .segment_data()
                .is_empty()
        );
    }

    #[test]
    fn view_is_short_safe() {
        assert!(SdoFrame::new_checked(&[0x00, 0x20, 0x40, 0x18, 0x10][..]).is_err());
        let f = SdoFrame::new_checked(&[0x00, 0x20, 0x40, 0x18, 0x10, 0x01][..]).unwrap();
        assert_eq!((f.index(), f.subindex()), (0x1018, 1));
        assert!(f.data_field().is_empty() && f.extra().is_empty());
        assert_eq!(f.data_field_u32(), None);
    }

    proptest! {
        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..32)) {
            if let Ok(f) = SdoFrame::new_checked(&bytes[..]) {
                let _ = (f.service(), f.specifier(), f.index(), f.subindex());
                let _ = (f.data_field(), f.data_field_u32(), f.extra(), f.segment_data());
                let _ = SdoPayload::decode("test", &f);
            }
        }
    }
}
