//! The mailbox error reply (mailbox type 0, ETG.1000.4 "mailbox error", spec-notes §mbx.error).
//!
//! ```text
//! mailbox data offset 0  u16  type   = 0x0001 (mailbox command "error")
//!                     2  u16  detail = error code (MBXERR_*)
//! ```
//! The mailbox header carries length 4 and type 0. The view wraps the mailbox data.

use core::fmt;

use crate::Emit;
use crate::error::{Result, WireError, need, room};
use crate::field::{self, Field};
use crate::macros::enum_with_unknown;

mod fields {
    use super::Field;
    pub const TYPE: Field = 0..2;
    pub const DETAIL: Field = 2..4;
}

/// Size of the error reply's data (the mailbox length of an error reply).
pub const ERROR_REPLY_LEN: usize = fields::DETAIL.end;

/// The only defined value of the type word: mailbox command "error".
pub const ERROR_REPLY_TYPE: u16 = 0x0001;

enum_with_unknown! {
    /// Mailbox error code (the detail word, ETG.1000.4, spec-notes §mbx.error).
    pub enum MailboxErrorCode(u16) {
        /// 0x0001: syntax of the 6-byte mailbox header is wrong.
        Syntax = 0x0001,
        /// 0x0002: mailbox protocol type not supported.
        UnsupportedProtocol = 0x0002,
        /// 0x0003: channel field contains a wrong value.
        InvalidChannel = 0x0003,
        /// 0x0004: service in the protocol not supported.
        ServiceNotSupported = 0x0004,
        /// 0x0005: invalid protocol header (e.g. length 0, type 0).
        InvalidHeader = 0x0005,
        /// 0x0006: received mailbox data too short.
        SizeTooShort = 0x0006,
        /// 0x0007: slave out of memory.
        NoMoreMemory = 0x0007,
        /// 0x0008: length of data inconsistent.
        InvalidSize = 0x0008,
        /// 0x0009: service already in progress (KickCAT only; accepted, not required).
        ServiceInWork = 0x0009,
    }
}

impl MailboxErrorCode {
    /// The standard's constant name (`MBXERR_...`).
    pub fn name(self) -> &'static str {
        match self {
            MailboxErrorCode::Syntax => "MBXERR_SYNTAX",
            MailboxErrorCode::UnsupportedProtocol => "MBXERR_UNSUPPORTEDPROTOCOL",
            MailboxErrorCode::InvalidChannel => "MBXERR_INVALIDCHANNEL",
            MailboxErrorCode::ServiceNotSupported => "MBXERR_SERVICENOTSUPPORTED",
            MailboxErrorCode::InvalidHeader => "MBXERR_INVALIDHEADER",
            MailboxErrorCode::SizeTooShort => "MBXERR_SIZETOOSHORT",
            MailboxErrorCode::NoMoreMemory => "MBXERR_NOMOREMEMORY",
            MailboxErrorCode::InvalidSize => "MBXERR_INVALIDSIZE",
            MailboxErrorCode::ServiceInWork => "MBXERR_SERVICEINWORK",
            MailboxErrorCode::Unknown(_) => "MBXERR_UNKNOWN",
        }
    }

    /// The meaning of the code in words (ETG.1000.4, spec-notes §mbx.error).
    pub fn description(self) -> &'static str {
        match self {
            MailboxErrorCode::Syntax => "Syntax of the 6-byte mailbox header is wrong",
            MailboxErrorCode::UnsupportedProtocol => "Mailbox protocol type not supported",
            MailboxErrorCode::InvalidChannel => "Channel field contains wrong value",
            MailboxErrorCode::ServiceNotSupported => "Service in the protocol not supported",
            MailboxErrorCode::InvalidHeader => "Invalid protocol header",
            MailboxErrorCode::SizeTooShort => "Received mailbox data too short",
            MailboxErrorCode::NoMoreMemory => "Slave out of memory",
            MailboxErrorCode::InvalidSize => "Length of data inconsistent",
            MailboxErrorCode::ServiceInWork => "Service already in progress",
            MailboxErrorCode::Unknown(_) => "Unknown mailbox error code",
        }
    }
}

impl fmt::Display for MailboxErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:#06x} {}: {}",
            u16::from(*self),
            self.name(),
            self.description()
        )
    }
}

/// A view of the data of a type-0 mailbox.
#[derive(Debug, Clone)]
pub struct ErrorReply<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> ErrorReply<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        ErrorReply { buffer }
    }

    /// Wraps a buffer and checks that both words are present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let reply = Self::new_unchecked(buffer);
        reply.check_len()?;
        Ok(reply)
    }

    /// Checks that the 4 bytes are present (trailing bytes are allowed and ignored).
    pub fn check_len(&self) -> Result<()> {
        need("mailbox error reply", self.buffer.as_ref(), ERROR_REPLY_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// The type word (0x0001 for an error reply).
    pub fn reply_type(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::TYPE.start)
    }

    /// The error code.
    pub fn detail(&self) -> MailboxErrorCode {
        MailboxErrorCode::from(field::u16_le(self.buffer.as_ref(), fields::DETAIL.start))
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> ErrorReply<T> {
    /// Sets the type word.
    pub fn set_reply_type(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::TYPE.start, value)
    }

    /// Sets the error code.
    pub fn set_detail(&mut self, value: MailboxErrorCode) {
        field::set_u16_le(self.buffer.as_mut(), fields::DETAIL.start, value.into())
    }
}

/// A parsed mailbox error reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ErrorReplyRepr {
    /// The error code.
    pub detail: MailboxErrorCode,
}

impl ErrorReplyRepr {
    /// Parses the reply; a type word other than 0x0001 is an `UnknownType` error.
    pub fn parse<T: AsRef<[u8]>>(reply: &ErrorReply<T>) -> Result<Self> {
        reply.check_len()?;
        let ty = reply.reply_type();
        if ty != ERROR_REPLY_TYPE {
            return Err(WireError::UnknownType {
                what: "mailbox error reply type",
                value: u32::from(ty),
            });
        }
        Ok(ErrorReplyRepr {
            detail: reply.detail(),
        })
    }

    /// Size of the reply data (4); also the mailbox length to put in the header.
    pub const fn buffer_len(&self) -> usize {
        ERROR_REPLY_LEN
    }

    /// Writes type 0x0001 and the detail.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, reply: &mut ErrorReply<T>) -> Result<()> {
        room(
            "mailbox error reply",
            reply.buffer.as_ref(),
            ERROR_REPLY_LEN,
        )?;
        reply.set_reply_type(ERROR_REPLY_TYPE);
        reply.set_detail(self.detail);
        Ok(())
    }
}

/// The mailbox data of a mailbox error reply with `code` (ETG.1000.4 §5.6, the mailbox
/// error reply: type 0x0001, then the code; it goes in a message of type
/// [`MailboxType::Error`](crate::mailbox::MailboxType::Error)).
pub fn error_reply(code: MailboxErrorCode) -> Vec<u8> {
    let repr = ErrorReplyRepr { detail: code };
    // `to_vec` sizes the buffer and every code fits: never the empty default.
    repr.to_vec().unwrap_or_default()
}

impl fmt::Display for ErrorReplyRepr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "MBX error {}", self.detail)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mailbox::{HEADER_LEN, Mailbox, MailboxHeader, MailboxType};
    use proptest::prelude::*;

    // ETG.1000.4, spec-notes §mbx.error, with slave counter 1: unsupported protocol.
    static C11: [u8; 10] = [0x04, 0x00, 0x00, 0x00, 0x00, 0x10, 0x01, 0x00, 0x02, 0x00];

    #[test]
    fn error_reply_is_the_mailbox_data_of_the_reply() {
        assert_eq!(
            error_reply(MailboxErrorCode::UnsupportedProtocol),
            C11[HEADER_LEN..]
        );
    }

    #[test]
    fn parse_c11() {
        let mbx = Mailbox::new_checked(&C11[..]).unwrap();
        let header = MailboxHeader::parse(&mbx).unwrap();
        assert_eq!(header.mailbox_type, MailboxType::Error);
        assert_eq!(header.length, 4);
        assert_eq!(header.counter, 1);
        let reply = ErrorReplyRepr::parse(&ErrorReply::new_checked(mbx.data()).unwrap()).unwrap();
        assert_eq!(reply.detail, MailboxErrorCode::UnsupportedProtocol);
    }

    #[test]
    fn emit_c11() {
        let mut bytes = [0xa5u8; 10];
        let reply = ErrorReplyRepr {
            detail: MailboxErrorCode::UnsupportedProtocol,
        };
        let header = MailboxHeader {
            length: reply.buffer_len() as u16,
            address: 0,
            channel: 0,
            priority: 0,
            mailbox_type: MailboxType::Error,
            counter: 1,
        };
        let mut mbx = Mailbox::new_unchecked(&mut bytes[..]);
        header.emit(&mut mbx).unwrap();
        reply
            .emit(&mut ErrorReply::new_unchecked(mbx.data_mut()))
            .unwrap();
        assert_eq!(bytes, C11);
    }

    #[test]
    fn codes_and_texts() {
        assert_eq!(
            MailboxErrorCode::from(0x0009),
            MailboxErrorCode::ServiceInWork
        );
        assert_eq!(
            MailboxErrorCode::from(0x000A),
            MailboxErrorCode::Unknown(0x000A)
        );
        for raw in 1u16..=9 {
            let code = MailboxErrorCode::from(raw);
            assert!(!matches!(code, MailboxErrorCode::Unknown(_)));
            assert!(code.name().starts_with("MBXERR_"));
        }
        let reply = ErrorReplyRepr {
            detail: MailboxErrorCode::InvalidHeader,
        };
        assert_eq!(
            reply.to_string(),
            "MBX error 0x0005 MBXERR_INVALIDHEADER: Invalid protocol header"
        );
    }

    #[test]
    fn errors() {
        assert!(matches!(
            ErrorReply::new_checked(&[0x01, 0x00, 0x02][..]),
            Err(WireError::Truncated { .. })
        ));
        let wrong_type = [0x02, 0x00, 0x02, 0x00];
        assert_eq!(
            ErrorReplyRepr::parse(&ErrorReply::new_unchecked(&wrong_type[..])),
            Err(WireError::UnknownType {
                what: "mailbox error reply type",
                value: 2
            })
        );
        let mut short = [0u8; 3];
        let reply = ErrorReplyRepr {
            detail: MailboxErrorCode::Syntax,
        };
        assert!(
            reply
                .emit(&mut ErrorReply::new_unchecked(&mut short[..]))
                .is_err()
        );
        assert_eq!(short, [0; 3]);
    }

    proptest! {
        #[test]
        fn round_trip(detail in any::<u16>()) {
            let repr = ErrorReplyRepr { detail: MailboxErrorCode::from(detail) };
            let mut out = [0u8; ERROR_REPLY_LEN];
            repr.emit(&mut ErrorReply::new_unchecked(&mut out[..])).unwrap();
            prop_assert_eq!(ErrorReplyRepr::parse(&ErrorReply::new_checked(&out[..]).unwrap()).unwrap(), repr);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..8)) {
            if let Ok(reply) = ErrorReply::new_checked(&bytes[..]) {
                let _ = ErrorReplyRepr::parse(&reply);
            }
        }
    }
}
