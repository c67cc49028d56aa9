//! The ETG.8200 mailbox-gateway message (spec-notes §gateway): an EtherCAT header of type 5
//! (mailbox) followed by one complete mailbox message, as carried in a UDP datagram (port
//! 0x88A4) or on a TCP stream.
//!
//! ```text
//! offset 0  u16  EtherCAT header: bits 0-10 length = 6 + mailbox length, bit 11 reserved,
//!                bits 12-15 type = 5
//! offset 2  6    mailbox header (ETG.1000.4, spec-notes §mbx.header)
//! offset 8  n    mailbox data
//! ```
//!
//! The 2-byte EtherCAT header is the same header as in `frame.rs` (spec-notes §frame); it is encoded here
//! directly so that this module does not depend on the frame codec (to be deduplicated).

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field::{self, Rest};
use crate::frame::{self, Frame, FrameType};
use crate::mailbox::{self, Mailbox, MailboxHeader};

mod fields {
    use super::Rest;
    pub const MAILBOX: Rest = super::frame::HEADER_LEN..;
}

/// Size of the EtherCAT header in bytes (the same header as a frame's, [`frame::HEADER_LEN`]).
pub const ECAT_HEADER_LEN: usize = fields::MAILBOX.start;

/// The smallest gateway message: EtherCAT header + mailbox header.
pub const MIN_LEN: usize = ECAT_HEADER_LEN + mailbox::HEADER_LEN;

/// EtherCAT header type of a mailbox message (ETG.1000.4, spec-notes §frame).
pub const ECAT_TYPE_MAILBOX: u8 = 5;

/// The largest mailbox message (header + data) whose size fits the 11-bit EtherCAT length.
pub const MAX_MAILBOX_LEN: usize = frame::MAX_LENGTH as usize;

/// A read/write view of a gateway message.
#[derive(Debug, Clone)]
pub struct GatewayMessage<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> GatewayMessage<T> {
    /// Wraps a buffer without checking it; accessors may panic until [`Self::check_len`] passed.
    pub const fn new_unchecked(buffer: T) -> Self {
        GatewayMessage { buffer }
    }

    /// Wraps a buffer and validates it (see [`Self::check_len`]).
    pub fn new_checked(buffer: T) -> Result<Self> {
        let message = Self::new_unchecked(buffer);
        message.check_len()?;
        Ok(message)
    }

    /// Validates a received message, in this order (the gateway checks of spec-notes §gateway):
    ///
    /// 1. at least 2 + 6 bytes, else `Truncated`;
    /// 2. EtherCAT type 5, else `UnknownType` — checked before any length because the
    ///    meaning of the lengths depends on the type;
    /// 3. reserved bit 11 clear, else `ReservedBits`;
    /// 4. 6 + mailbox length ≤ bytes − 2, else `BadLength`; trailing bytes beyond the mailbox
    ///    are ignored (IgH does the same; a UDP client may pad);
    /// 5. EtherCAT length == 6 + mailbox length, else `BadLength`. IgH does not check this,
    ///    but the two lengths describe the same bytes, a mismatch means a client framing bug,
    ///    and on TCP the EtherCAT length is what delimits messages — so we refuse it rather
    ///    than guess which one is right.
    pub fn check_len(&self) -> Result<()> {
        let buf = self.buffer.as_ref();
        need("ETG.8200 message", buf, MIN_LEN)?;
        if self.ecat_type() != ECAT_TYPE_MAILBOX {
            return Err(WireError::UnknownType {
                what: "ETG.8200 EtherCAT header type",
                value: u32::from(self.ecat_type()),
            });
        }
        if self.ecat_reserved() {
            return Err(WireError::ReservedBits {
                what: "ETG.8200 EtherCAT header",
                value: u32::from(self.header_view().header() & frame::RESERVED_BIT),
            });
        }
        let mailbox_len = self.mailbox_len();
        let available = buf.len() - ECAT_HEADER_LEN;
        if mailbox_len > available {
            return Err(WireError::BadLength {
                what: "ETG.8200 mailbox length",
                declared: mailbox_len,
                available,
            });
        }
        if usize::from(self.ecat_length()) != mailbox_len {
            return Err(WireError::BadLength {
                what: "ETG.8200 EtherCAT length",
                declared: usize::from(self.ecat_length()),
                available: mailbox_len,
            });
        }
        Ok(())
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// The EtherCAT header, read through the frame codec that owns its layout.
    fn header_view(&self) -> Frame<&[u8]> {
        Frame::new_unchecked(self.buffer.as_ref())
    }

    /// EtherCAT header length (bits 0-10): 6 + mailbox data length.
    pub fn ecat_length(&self) -> u16 {
        self.header_view().length()
    }

    /// EtherCAT header reserved bit 11.
    pub fn ecat_reserved(&self) -> bool {
        self.header_view().reserved_bit()
    }

    /// EtherCAT header type (bits 12-15); 5 for a gateway message.
    pub fn ecat_type(&self) -> u8 {
        u8::from(self.header_view().frame_type())
    }

    /// Size of the mailbox message (6 + the mailbox header's length field).
    pub fn mailbox_len(&self) -> usize {
        let buf = self.buffer.as_ref();
        mailbox::HEADER_LEN + usize::from(field::u16_le(buf, fields::MAILBOX.start))
    }

    /// The mailbox message bytes (header + data, without trailing bytes), for forwarding
    /// unchanged.
    pub fn mailbox_bytes(&self) -> &[u8] {
        let start = fields::MAILBOX.start;
        &self.buffer.as_ref()[start..start + self.mailbox_len()]
    }

    /// A mailbox view over exactly the mailbox message (its length was validated by
    /// [`Self::check_len`], so the view's accessors cannot panic).
    pub fn mailbox(&self) -> Mailbox<&[u8]> {
        Mailbox::new_unchecked(self.mailbox_bytes())
    }

    /// Total size of the message (EtherCAT header + mailbox), excluding trailing bytes.
    pub fn total_len(&self) -> usize {
        ECAT_HEADER_LEN + self.mailbox_len()
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> GatewayMessage<T> {
    /// Sets the EtherCAT header to type 5 with the given length (masked to 11 bits; emit
    /// checks the range first).
    pub fn set_ecat_header(&mut self, length: u16) {
        Frame::new_unchecked(self.buffer.as_mut()).set_length_type(length, FrameType::Mailbox)
    }

    /// Everything after the EtherCAT header, mutable (where the mailbox goes).
    pub fn mailbox_buffer_mut(&mut self) -> &mut [u8] {
        &mut self.buffer.as_mut()[fields::MAILBOX]
    }
}

/// A parsed gateway message: the mailbox header and the mailbox data it carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct GatewayRepr<'a> {
    /// The mailbox header (`header.length == data.len()`).
    pub header: MailboxHeader,
    /// The mailbox data (protocol header + payload).
    pub data: &'a [u8],
}

impl<'a> GatewayRepr<'a> {
    /// Parses a checked gateway view.
    pub fn parse<T: AsRef<[u8]> + ?Sized>(message: &GatewayMessage<&'a T>) -> Result<Self> {
        message.check_len()?;
        // Copy the `&'a T` out of the view so the data borrow the buffer, not the view.
        let buf: &'a [u8] = AsRef::<[u8]>::as_ref(message.buffer);
        let start = fields::MAILBOX.start;
        let mbx = Mailbox::new_checked(&buf[start..start + message.mailbox_len()])?;
        let header = MailboxHeader::parse(&mbx)?;
        let data = &buf[start + mailbox::HEADER_LEN..start + message.mailbox_len()];
        Ok(GatewayRepr { header, data })
    }

    /// Bytes needed on the wire: 2 + 6 + data.
    pub fn buffer_len(&self) -> usize {
        MIN_LEN + self.data.len()
    }

    /// Writes EtherCAT header and mailbox into the start of `message`'s buffer.
    ///
    /// Refuses (writing nothing) a header whose length differs from `data.len()` and a
    /// mailbox too long for the 11-bit EtherCAT length (more than 2047 − 6 data bytes).
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(
        &self,
        message: &mut GatewayMessage<T>,
    ) -> Result<()> {
        room(
            "ETG.8200 message",
            message.buffer.as_ref(),
            self.buffer_len(),
        )?;
        if usize::from(self.header.length) != self.data.len() {
            return Err(WireError::Invalid {
                what: "ETG.8200 message",
                reason: "mailbox header length differs from the data length",
            });
        }
        let mailbox_len = mailbox::HEADER_LEN + self.data.len();
        if mailbox_len > MAX_MAILBOX_LEN {
            return Err(WireError::BadLength {
                what: "ETG.8200 EtherCAT length",
                declared: mailbox_len,
                available: MAX_MAILBOX_LEN,
            });
        }
        let mbx_buf = &mut message.mailbox_buffer_mut()[..mailbox_len];
        let mut mbx = Mailbox::new_unchecked(&mut mbx_buf[..]);
        // The header's own range checks run before anything is written.
        self.header.emit(&mut mbx)?;
        mbx.data_mut().copy_from_slice(self.data);
        // mailbox_len ≤ 2047 was checked above.
        message.set_ecat_header(mailbox_len as u16);
        Ok(())
    }
}

impl fmt::Display for GatewayRepr<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ETG.8200 {} addr={:#06x} len={}",
            self.header.mailbox_type.name(),
            self.header.address,
            self.header.length
        )?;
        if let crate::mailbox::MailboxType::Unknown(raw) = self.header.mailbox_type {
            write!(f, " (type {raw:#x})")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mailbox::MailboxType;
    use proptest::prelude::*;

    // ETG.8200, spec-notes §gateway (IgH README): CoE upload of 0x1018:01 from slave address 4.
    static REQUEST: [u8; 18] = [
        0x10, 0x50, 0x0a, 0x00, 0x04, 0x00, 0x00, 0x03, 0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0x00,
        0x00, 0x00, 0x00,
    ];
    static REPLY: [u8; 18] = [
        0x10, 0x50, 0x0a, 0x00, 0x04, 0x00, 0x00, 0x23, 0x00, 0x30, 0x43, 0x18, 0x10, 0x01, 0x02,
        0x00, 0x00, 0x00,
    ];

    fn case(bytes: &[u8], counter: u8) {
        let msg = GatewayMessage::new_checked(bytes).unwrap();
        assert_eq!(msg.ecat_length(), 16);
        assert_eq!(msg.ecat_type(), 5);
        assert_eq!(msg.mailbox_bytes(), &bytes[2..]);
        let repr = GatewayRepr::parse(&msg).unwrap();
        assert_eq!(
            repr.header,
            MailboxHeader {
                length: 10,
                address: 4,
                channel: 0,
                priority: 0,
                mailbox_type: MailboxType::Coe,
                counter,
            }
        );
        assert_eq!(repr.data, &bytes[8..]);
        assert_eq!(repr.to_string(), "ETG.8200 CoE addr=0x0004 len=10");
        let mut out = vec![0xa5u8; bytes.len()];
        repr.emit(&mut GatewayMessage::new_unchecked(&mut out[..]))
            .unwrap();
        assert_eq!(out, bytes);
    }

    #[test]
    fn c16_request() {
        case(&REQUEST, 0);
    }

    #[test]
    fn c16_reply() {
        case(&REPLY, 2);
    }

    #[test]
    fn twinsafe_trace() {
        // ETG.8200, spec-notes §gateway: TwinSAFE Loader → IgH, slave "1001" = 0x03E9, CoE, Cnt 2.
        let bytes = [
            0x10, 0x50, 0x0a, 0x00, 0xe9, 0x03, 0x00, 0x23, 0x00, 0x20, 0x41, 0x80, 0xf9, 0x02,
            0x00, 0x00, 0x00, 0x00,
        ];
        let repr = GatewayRepr::parse(&GatewayMessage::new_checked(&bytes[..]).unwrap()).unwrap();
        assert_eq!(repr.header.address, 0x03e9);
        assert_eq!(repr.header.counter, 2);
        assert_eq!(repr.to_string(), "ETG.8200 CoE addr=0x03e9 len=10");
    }

    #[test]
    fn long_reply_header() {
        // spec-notes §gateway trace: a 250-byte mailbox data reply has EtherCAT header `00 51`.
        let data = [0u8; 250];
        let repr = GatewayRepr {
            header: MailboxHeader {
                length: 250,
                address: 0x03e9,
                channel: 0,
                priority: 0,
                mailbox_type: MailboxType::Coe,
                counter: 1,
            },
            data: &data,
        };
        let mut out = vec![0u8; repr.buffer_len()];
        repr.emit(&mut GatewayMessage::new_unchecked(&mut out[..]))
            .unwrap();
        assert_eq!(out[..2], [0x00, 0x51]);
    }

    #[test]
    fn wrong_type_is_refused() {
        let mut bytes = REQUEST;
        bytes[1] = 0x10; // type 1 (datagrams)
        assert_eq!(
            GatewayMessage::new_checked(&bytes[..]).unwrap_err(),
            WireError::UnknownType {
                what: "ETG.8200 EtherCAT header type",
                value: 1
            }
        );
    }

    #[test]
    fn reserved_bit_is_refused() {
        let mut bytes = REQUEST;
        bytes[1] = 0x58;
        assert!(matches!(
            GatewayMessage::new_checked(&bytes[..]),
            Err(WireError::ReservedBits { .. })
        ));
    }

    #[test]
    fn truncated() {
        assert!(matches!(
            GatewayMessage::new_checked(&REQUEST[..7]),
            Err(WireError::Truncated {
                need: 8,
                have: 7,
                ..
            })
        ));
    }

    #[test]
    fn mailbox_longer_than_bytes() {
        assert_eq!(
            GatewayMessage::new_checked(&REQUEST[..17]).unwrap_err(),
            WireError::BadLength {
                what: "ETG.8200 mailbox length",
                declared: 16,
                available: 15
            }
        );
    }

    #[test]
    fn ecat_length_mismatch() {
        let mut bytes = REQUEST;
        bytes[0] = 0x11;
        assert_eq!(
            GatewayMessage::new_checked(&bytes[..]).unwrap_err(),
            WireError::BadLength {
                what: "ETG.8200 EtherCAT length",
                declared: 17,
                available: 16
            }
        );
    }

    #[test]
    fn trailing_bytes_are_ignored() {
        let mut bytes = REQUEST.to_vec();
        bytes.extend_from_slice(&[0xee; 5]);
        let msg = GatewayMessage::new_checked(&bytes[..]).unwrap();
        assert_eq!(msg.total_len(), 18);
        let repr = GatewayRepr::parse(&msg).unwrap();
        assert_eq!(repr.data, &REQUEST[8..]);
    }

    #[test]
    fn emit_refusals() {
        let data = [0u8; 3];
        let header = MailboxHeader {
            length: 2,
            address: 0,
            channel: 0,
            priority: 0,
            mailbox_type: MailboxType::Voe,
            counter: 0,
        };
        let mut out = [0u8; 11];
        let mismatch = GatewayRepr {
            header,
            data: &data,
        };
        assert!(
            mismatch
                .emit(&mut GatewayMessage::new_unchecked(&mut out[..]))
                .is_err()
        );
        let bad_counter = GatewayRepr {
            header: MailboxHeader {
                length: 3,
                counter: 9,
                ..header
            },
            data: &data,
        };
        assert!(
            bad_counter
                .emit(&mut GatewayMessage::new_unchecked(&mut out[..]))
                .is_err()
        );
        assert_eq!(out, [0u8; 11], "a refused emit writes nothing");
        let big = [0u8; 2042];
        let too_long = GatewayRepr {
            header: MailboxHeader {
                length: 2042,
                ..header
            },
            data: &big,
        };
        let mut out = vec![0u8; too_long.buffer_len()];
        assert!(matches!(
            too_long.emit(&mut GatewayMessage::new_unchecked(&mut out[..])),
            Err(WireError::BadLength {
                declared: 2048,
                available: 2047,
                ..
            })
        ));
    }

    proptest! {
        #[test]
        fn round_trip(address in any::<u16>(), channel in 0u8..64, priority in 0u8..4,
                      ty in 0u8..16, counter in 0u8..8,
                      data in proptest::collection::vec(any::<u8>(), 0..64)) {
            let header = MailboxHeader {
                length: data.len() as u16,
                address,
                channel,
                priority,
                mailbox_type: MailboxType::from(ty),
                counter,
            };
            let repr = GatewayRepr { header, data: &data };
            let mut buf = vec![0u8; repr.buffer_len()];
            repr.emit(&mut GatewayMessage::new_unchecked(&mut buf[..])).unwrap();
            let msg = GatewayMessage::new_checked(&buf[..]).unwrap();
            prop_assert_eq!(GatewayRepr::parse(&msg).unwrap(), repr);
        }

        #[test]
        fn never_panics(len in 0u16..40, mut bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
            // Mostly well-typed headers so that the later checks are reached too.
            if bytes.len() >= 2 && bytes[0] & 1 == 0 {
                bytes[..2].copy_from_slice(&(0x5000 | len).to_le_bytes());
            }
            if let Ok(msg) = GatewayMessage::new_checked(&bytes[..]) {
                let _ = msg.mailbox().data();
                if let Ok(repr) = GatewayRepr::parse(&msg) {
                    let _ = repr.to_string();
                }
            }
        }
    }
}
