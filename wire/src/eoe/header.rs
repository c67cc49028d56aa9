//! The 4-byte EoE header (ETG.1000.6, spec-notes §eoe) and its code points.
//!
//! ```text
//! byte 0  bits 0-3 frame type, bits 4-7 port
//! byte 1  bit 0 last fragment, bit 1 time appended, bit 2 time request, bits 3-7 reserved
//! 2..4    u16, frame types 0/1: bits 0-5 fragment number, bits 6-11 size (fragment 0) or
//!         offset (others) in 32-byte units, bits 12-15 frame number;
//!         other frame types: result (responses) or 0 (requests)
//! 4..     frame-type dependent body
//! ```

use crate::error::{Result, need};
use crate::field::{self, Field, Rest};
use crate::macros::enum_with_unknown;

mod fields {
    use super::{Field, Rest};
    pub const TYPE_PORT: usize = 0;
    pub const FLAGS: usize = 1;
    pub const INFO: Field = 2..4;
    pub const PAYLOAD: Rest = 4..;

    pub const LAST_FRAGMENT: u8 = 0x01;
    pub const TIME_APPENDED: u8 = 0x02;
    pub const TIME_REQUEST: u8 = 0x04;
    pub const RESERVED_FLAGS: u8 = 0xF8;

    pub const FRAGMENT_MASK: u16 = 0x3F;
    pub const OFFSET_SHIFT: u32 = 6;
    pub const OFFSET_MASK: u16 = 0x3F;
    pub const FRAME_SHIFT: u32 = 12;
}

/// Size of the EoE header in bytes.
pub const HEADER_LEN: usize = fields::PAYLOAD.start;

/// Largest fragment number (6 bits).
pub const MAX_FRAGMENT_NUMBER: u8 = 63;
/// Largest size/offset field value (6 bits, in 32-byte units).
pub const MAX_OFFSET_FIELD: u8 = 63;
/// Largest frame number (4 bits).
pub const MAX_FRAME_NUMBER: u8 = 15;
/// Largest port (4 bits).
pub const MAX_PORT: u8 = 15;
/// The unit of the size/offset field.
pub const OFFSET_UNIT: usize = 32;

enum_with_unknown! {
    /// EoE frame type (byte 0 bits 0-3, ETG.1000.6, spec-notes §eoe).
    pub enum EoeFrameType(u8) {
        /// Ethernet frame fragment.
        Fragment = 0,
        /// Timestamp response.
        TimestampResponse = 1,
        /// Set IP parameter request ("init request").
        SetIpRequest = 2,
        /// Set IP parameter response.
        SetIpResponse = 3,
        /// Set address filter request.
        SetAddressFilterRequest = 4,
        /// Set address filter response.
        SetAddressFilterResponse = 5,
        /// Get IP parameter request.
        GetIpRequest = 6,
        /// Get IP parameter response.
        GetIpResponse = 7,
        /// Get address filter request.
        GetAddressFilterRequest = 8,
        /// Get address filter response.
        GetAddressFilterResponse = 9,
    }
}

impl EoeFrameType {
    /// Short name for logs.
    pub fn name(self) -> &'static str {
        match self {
            EoeFrameType::Fragment => "frag",
            EoeFrameType::TimestampResponse => "timestamp",
            EoeFrameType::SetIpRequest => "set-IP",
            EoeFrameType::SetIpResponse => "set-IP resp",
            EoeFrameType::SetAddressFilterRequest => "set-filter",
            EoeFrameType::SetAddressFilterResponse => "set-filter resp",
            EoeFrameType::GetIpRequest => "get-IP",
            EoeFrameType::GetIpResponse => "get-IP resp",
            EoeFrameType::GetAddressFilterRequest => "get-filter",
            EoeFrameType::GetAddressFilterResponse => "get-filter resp",
            EoeFrameType::Unknown(_) => "type",
        }
    }
}

enum_with_unknown! {
    /// EoE result code of a response (bytes 2-3, ETG.1000.6, spec-notes §eoe).
    pub enum EoeResult(u16) {
        /// Success.
        Success = 0x0000,
        /// Unspecified error.
        UnspecifiedError = 0x0001,
        /// Unsupported frame type.
        UnsupportedFrameType = 0x0002,
        /// No IP support.
        NoIpSupport = 0x0201,
        /// DHCP not supported.
        DhcpNotSupported = 0x0202,
        /// No (address) filter support.
        NoFilterSupport = 0x0401,
    }
}

impl EoeResult {
    /// The text of the result code.
    pub fn description(self) -> &'static str {
        match self {
            EoeResult::Success => "Success",
            EoeResult::UnspecifiedError => "Unspecified error",
            EoeResult::UnsupportedFrameType => "Unsupported frame type",
            EoeResult::NoIpSupport => "No IP support",
            EoeResult::DhcpNotSupported => "DHCP not supported",
            EoeResult::NoFilterSupport => "No filter support",
            EoeResult::Unknown(_) => "Unknown result",
        }
    }
}

/// A read/write view of an EoE message (mailbox data).
#[derive(Debug, Clone)]
pub struct EoePacket<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> EoePacket<T> {
    /// Wraps a buffer without checking it; accessors may panic until [`Self::check_len`] passed.
    pub const fn new_unchecked(buffer: T) -> Self {
        EoePacket { buffer }
    }

    /// Wraps a buffer and checks that the 4-byte header is present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let packet = Self::new_unchecked(buffer);
        packet.check_len()?;
        Ok(packet)
    }

    /// Checks that the header is present. The bodies have no length field of their own;
    /// the frame-type parsers check them.
    pub fn check_len(&self) -> Result<()> {
        need("EoE header", self.buffer.as_ref(), HEADER_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// A reference to the underlying buffer.
    pub fn as_bytes(&self) -> &T {
        &self.buffer
    }

    /// Frame type.
    pub fn frame_type(&self) -> EoeFrameType {
        EoeFrameType::from(self.buffer.as_ref()[fields::TYPE_PORT] & 0x0F)
    }

    /// Port (0 = unspecified).
    pub fn port(&self) -> u8 {
        self.buffer.as_ref()[fields::TYPE_PORT] >> 4
    }

    /// Last-fragment bit.
    pub fn last_fragment(&self) -> bool {
        self.buffer.as_ref()[fields::FLAGS] & fields::LAST_FRAGMENT != 0
    }

    /// Time-appended bit: a u32 timestamp follows the data.
    pub fn time_appended(&self) -> bool {
        self.buffer.as_ref()[fields::FLAGS] & fields::TIME_APPENDED != 0
    }

    /// Time-request bit: the sender asks for a timestamp response.
    pub fn time_request(&self) -> bool {
        self.buffer.as_ref()[fields::FLAGS] & fields::TIME_REQUEST != 0
    }

    /// The reserved bits 3-7 of byte 1.
    pub fn reserved_flags(&self) -> u8 {
        self.buffer.as_ref()[fields::FLAGS] & fields::RESERVED_FLAGS
    }

    /// The raw u16 at bytes 2-3.
    pub fn info(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::INFO.start)
    }

    /// Fragment number (frame types 0/1).
    pub fn fragment_number(&self) -> u8 {
        (self.info() & fields::FRAGMENT_MASK) as u8
    }

    /// Size (fragment 0) or offset (others) in 32-byte units (frame types 0/1).
    pub fn offset_field(&self) -> u8 {
        ((self.info() >> fields::OFFSET_SHIFT) & fields::OFFSET_MASK) as u8
    }

    /// Frame number (frame types 0/1).
    pub fn frame_number(&self) -> u8 {
        (self.info() >> fields::FRAME_SHIFT) as u8
    }

    /// Result code (responses of frame types other than 0/1).
    pub fn result(&self) -> EoeResult {
        EoeResult::from(self.info())
    }

    /// Everything after the header.
    pub fn payload(&self) -> &[u8] {
        &self.buffer.as_ref()[fields::PAYLOAD]
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> EoePacket<T> {
    /// Sets frame type and port (each masked to 4 bits; the reprs check ranges first).
    pub fn set_type_port(&mut self, frame_type: EoeFrameType, port: u8) {
        self.buffer.as_mut()[fields::TYPE_PORT] = (u8::from(frame_type) & 0x0F) | (port << 4);
    }

    /// Sets byte 1 (reserved bits cleared).
    pub fn set_flags(&mut self, last_fragment: bool, time_appended: bool, time_request: bool) {
        let mut b = 0;
        if last_fragment {
            b |= fields::LAST_FRAGMENT;
        }
        if time_appended {
            b |= fields::TIME_APPENDED;
        }
        if time_request {
            b |= fields::TIME_REQUEST;
        }
        self.buffer.as_mut()[fields::FLAGS] = b;
    }

    /// Sets the raw u16 at bytes 2-3.
    pub fn set_info(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::INFO.start, value)
    }

    /// Sets fragment number, size/offset field and frame number (masked to their widths).
    pub fn set_fragment_info(&mut self, fragment_number: u8, offset_field: u8, frame_number: u8) {
        let value = (u16::from(fragment_number) & fields::FRAGMENT_MASK)
            | ((u16::from(offset_field) & fields::OFFSET_MASK) << fields::OFFSET_SHIFT)
            | (u16::from(frame_number & 0x0F) << fields::FRAME_SHIFT);
        self.set_info(value)
    }

    /// Mutable payload.
    pub fn payload_mut(&mut self) -> &mut [u8] {
        &mut self.buffer.as_mut()[fields::PAYLOAD]
    }
}

/// The payload of a view over a borrowed buffer, with the buffer's lifetime (not the view's).
pub(crate) fn payload_of<'a, T: AsRef<[u8]> + ?Sized>(packet: &EoePacket<&'a T>) -> &'a [u8] {
    let buf: &'a [u8] = AsRef::<[u8]>::as_ref(packet.buffer);
    buf.get(fields::PAYLOAD).unwrap_or(&[])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::WireError;

    #[test]
    fn c13_header_fields() {
        // ETG.1000.6, spec-notes §eoe: `00 | 01 | 00 31`.
        let bytes = [0x00, 0x01, 0x00, 0x31];
        let p = EoePacket::new_checked(&bytes[..]).unwrap();
        assert_eq!(p.frame_type(), EoeFrameType::Fragment);
        assert_eq!(p.port(), 0);
        assert!(p.last_fragment() && !p.time_appended() && !p.time_request());
        assert_eq!(p.fragment_number(), 0);
        assert_eq!(p.offset_field(), 4);
        assert_eq!(p.frame_number(), 3);
        let mut out = [0xa5u8; 4];
        let mut v = EoePacket::new_unchecked(&mut out[..]);
        v.set_type_port(EoeFrameType::Fragment, 0);
        v.set_flags(true, false, false);
        v.set_fragment_info(0, 4, 3);
        assert_eq!(out, bytes);
    }

    #[test]
    fn truncated_header() {
        assert!(matches!(
            EoePacket::new_checked(&[0u8; 3][..]),
            Err(WireError::Truncated {
                need: 4,
                have: 3,
                ..
            })
        ));
    }

    #[test]
    fn names() {
        assert_eq!(EoeFrameType::from(2).name(), "set-IP");
        assert_eq!(EoeResult::from(0x0401).description(), "No filter support");
    }
}
