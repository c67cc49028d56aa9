//! A whole mailbox message, decoded according to its type: the entry point for anything read
//! from a slave's SM1 or received by the ETG.8200 gateway.

use core::fmt;

use crate::coe::{CoeFrame, CoeRepr};
use crate::eoe::{EoePacket, EoeRepr};
use crate::error::{Result, WireError, room};
use crate::foe::{FoePacket, FoeRepr};
use crate::mailbox::{ErrorReply, ErrorReplyRepr, HEADER_LEN, Mailbox, MailboxHeader, MailboxType};
use crate::soe::{SoePacket, SoeRepr};
use crate::voe::{VoePacket, VoeRepr};

/// The protocol part of a mailbox message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MailboxPayload<'a> {
    /// Mailbox error reply (type 0).
    Error(ErrorReplyRepr),
    /// CANopen over EtherCAT.
    Coe(CoeRepr<'a>),
    /// Ethernet over EtherCAT.
    Eoe(EoeRepr<'a>),
    /// File access over EtherCAT.
    Foe(FoeRepr<'a>),
    /// Servo drive profile over EtherCAT.
    Soe(SoeRepr<'a>),
    /// Vendor specific.
    Voe(VoeRepr<'a>),
    /// AoE or a type this version does not decode: the raw data, kept so it can be forwarded.
    Raw(&'a [u8]),
}

impl MailboxPayload<'_> {
    /// Bytes of mailbox data this payload occupies when emitted.
    pub fn buffer_len(&self) -> usize {
        match self {
            MailboxPayload::Error(r) => r.buffer_len(),
            MailboxPayload::Coe(r) => r.buffer_len(),
            MailboxPayload::Eoe(r) => r.buffer_len(),
            MailboxPayload::Foe(r) => r.buffer_len(),
            MailboxPayload::Soe(r) => r.buffer_len(),
            MailboxPayload::Voe(r) => r.buffer_len(),
            MailboxPayload::Raw(data) => data.len(),
        }
    }

    /// The mailbox type this payload travels under.
    pub fn natural_type(&self) -> Option<MailboxType> {
        Some(match self {
            MailboxPayload::Error(_) => MailboxType::Error,
            MailboxPayload::Coe(_) => MailboxType::Coe,
            MailboxPayload::Eoe(_) => MailboxType::Eoe,
            MailboxPayload::Foe(_) => MailboxType::Foe,
            MailboxPayload::Soe(_) => MailboxType::Soe,
            MailboxPayload::Voe(_) => MailboxType::Voe,
            MailboxPayload::Raw(_) => return None,
        })
    }
}

/// A mailbox message: its header and its decoded payload.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MailboxMessage<'a> {
    /// The header as received. On emit, `length` is recomputed from the payload and the type
    /// must match the payload's protocol.
    pub header: MailboxHeader,
    /// The decoded protocol data.
    pub payload: MailboxPayload<'a>,
}

impl<'a> MailboxMessage<'a> {
    /// Parses a mailbox message (header + `length` data bytes; trailing bytes, e.g. the rest
    /// of an SM1 buffer, are ignored).
    pub fn parse(bytes: &'a [u8]) -> Result<Self> {
        let mailbox = Mailbox::new_checked(bytes)?;
        let header = MailboxHeader::parse(&mailbox)?;
        let end = mailbox.total_len();
        // `check_len` guarantees `end <= bytes.len()`; re-slice from the original borrow so the
        // payload lives as long as `bytes`.
        let data: &'a [u8] = &bytes[HEADER_LEN..end];
        let payload = match header.mailbox_type {
            MailboxType::Error => {
                MailboxPayload::Error(ErrorReplyRepr::parse(&ErrorReply::new_checked(data)?)?)
            }
            MailboxType::Coe => MailboxPayload::Coe(CoeRepr::parse(&CoeFrame::new_checked(data)?)?),
            MailboxType::Eoe => {
                MailboxPayload::Eoe(EoeRepr::parse(&EoePacket::new_checked(data)?)?)
            }
            MailboxType::Foe => {
                MailboxPayload::Foe(FoeRepr::parse(&FoePacket::new_checked(data)?)?)
            }
            MailboxType::Soe => {
                MailboxPayload::Soe(SoeRepr::parse(&SoePacket::new_checked(data)?)?)
            }
            MailboxType::Voe => {
                MailboxPayload::Voe(VoeRepr::parse(&VoePacket::new_checked(data)?)?)
            }
            MailboxType::Aoe | MailboxType::Unknown(_) => MailboxPayload::Raw(data),
        };
        Ok(MailboxMessage { header, payload })
    }

    /// Size of the emitted message (header + payload).
    pub fn buffer_len(&self) -> usize {
        HEADER_LEN + self.payload.buffer_len()
    }

    /// Writes header and payload into `buf` and returns the message length. The header's
    /// `length` is set from the payload; a header type that disagrees with the payload's
    /// protocol is refused.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        let len = self.buffer_len();
        room("mailbox message", buf, len)?;
        if let Some(natural) = self.payload.natural_type()
            && natural != self.header.mailbox_type
        {
            return Err(WireError::Invalid {
                what: "mailbox message",
                reason: "header type does not match the payload's protocol",
            });
        }
        let data_len =
            u16::try_from(self.payload.buffer_len()).map_err(|_| WireError::BadLength {
                what: "mailbox message",
                declared: self.payload.buffer_len(),
                available: usize::from(u16::MAX),
            })?;
        let header = MailboxHeader {
            length: data_len,
            ..self.header
        };
        let (head, rest) = buf[..len].split_at_mut(HEADER_LEN);
        header.emit(&mut Mailbox::new_unchecked(head))?;
        match &self.payload {
            MailboxPayload::Error(r) => r.emit(&mut ErrorReply::new_unchecked(rest))?,
            MailboxPayload::Coe(r) => r.emit(&mut CoeFrame::new_unchecked(rest))?,
            MailboxPayload::Eoe(r) => r.emit(&mut EoePacket::new_unchecked(rest))?,
            MailboxPayload::Foe(r) => r.emit(&mut FoePacket::new_unchecked(rest))?,
            MailboxPayload::Soe(r) => r.emit(&mut SoePacket::new_unchecked(rest))?,
            MailboxPayload::Voe(r) => r.emit(&mut VoePacket::new_unchecked(rest))?,
            MailboxPayload::Raw(data) => rest.copy_from_slice(data),
        }
        Ok(len)
    }
}

impl fmt::Display for MailboxPayload<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MailboxPayload::Error(r) => r.fmt(f),
            MailboxPayload::Coe(r) => r.fmt(f),
            MailboxPayload::Eoe(r) => r.fmt(f),
            MailboxPayload::Foe(r) => r.fmt(f),
            MailboxPayload::Soe(r) => r.fmt(f),
            MailboxPayload::Voe(r) => r.fmt(f),
            MailboxPayload::Raw(data) => write!(f, "{} raw bytes", data.len()),
        }
    }
}

impl fmt::Display for MailboxMessage<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.header, self.payload)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Emit;
    use proptest::prelude::*;

    // spec-notes §coe.sdo, response read from SM1 (with the rest of a 128-byte SM1 after it).
    static C6_RESPONSE: [u8; 16] = [
        0x0a, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x30, 0x43, 0x18, 0x10, 0x01, 0x02, 0x00, 0x00,
        0x00,
    ];
    // ETG.1000.4, spec-notes §mbx.error: mailbox error reply, unsupported protocol.
    static C11: [u8; 10] = [0x04, 0x00, 0x00, 0x00, 0x00, 0x10, 0x01, 0x00, 0x02, 0x00];
    // ETG.1000.6, spec-notes §foe: FoE ACK 0.
    static C12_ACK: [u8; 12] = [
        0x06, 0x00, 0x00, 0x00, 0x00, 0x14, 0x04, 0x00, 0x00, 0x00, 0x00, 0x00,
    ];
    // ETG.1000.6, spec-notes §soe: SoE "no IDN" error reply.
    static C15_ERROR: [u8; 12] = [
        0x06, 0x00, 0x00, 0x00, 0x00, 0x15, 0x12, 0x40, 0x18, 0x00, 0x01, 0x10,
    ];

    fn round_trip_exact(bytes: &[u8]) -> MailboxMessage<'_> {
        let message = MailboxMessage::parse(bytes).unwrap();
        let mut out = vec![0xa5u8; message.buffer_len()];
        assert_eq!(message.emit(&mut out).unwrap(), bytes.len());
        assert_eq!(out, bytes);
        message
    }

    #[test]
    fn dispatches_by_type_and_round_trips() {
        let mut sm1 = C6_RESPONSE.to_vec();
        sm1.resize(128, 0);
        let coe = MailboxMessage::parse(&sm1).unwrap();
        assert!(matches!(coe.payload, MailboxPayload::Coe(_)));
        assert_eq!(coe.header.counter, 1);
        round_trip_exact(&C6_RESPONSE);

        let error = round_trip_exact(&C11);
        assert_eq!(
            error.to_string().split(": ").next(),
            Some("MBX ERR len=4 addr=0x0000 cnt=1")
        );
        assert!(matches!(error.payload, MailboxPayload::Error(_)));
        assert!(matches!(
            round_trip_exact(&C12_ACK).payload,
            MailboxPayload::Foe(FoeRepr::Ack { packet: 0 })
        ));
        assert!(matches!(
            round_trip_exact(&C15_ERROR).payload,
            MailboxPayload::Soe(_)
        ));
    }

    #[test]
    fn aoe_and_unknown_types_are_kept_raw() {
        let bytes = [0x02, 0x00, 0x00, 0x00, 0x00, 0x11, 0xde, 0xad];
        let message = round_trip_exact(&bytes);
        assert_eq!(message.payload, MailboxPayload::Raw(&[0xde, 0xad]));
        let unknown = [0x01, 0x00, 0x00, 0x00, 0x00, 0x1c, 0x42];
        assert_eq!(
            round_trip_exact(&unknown).payload,
            MailboxPayload::Raw(&[0x42])
        );
    }

    #[test]
    fn a_payload_under_the_wrong_type_is_refused() {
        let mut message = MailboxMessage::parse(&C12_ACK).unwrap();
        message.header.mailbox_type = MailboxType::Coe;
        let mut out = [0u8; 32];
        assert!(message.emit(&mut out).is_err());
    }

    #[test]
    fn a_bad_payload_is_an_error_not_a_panic() {
        // CoE type, but only one data byte: the CoE header needs two.
        let bytes = [0x01, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00];
        assert!(matches!(
            MailboxMessage::parse(&bytes),
            Err(WireError::Truncated { .. })
        ));
    }

    proptest! {
        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..160)) {
            if let Ok(message) = MailboxMessage::parse(&bytes) {
                let _ = message.to_string();
            }
        }

        // Whatever parses re-emits, and re-parses to the same message (tolerated short forms
        // are re-emitted in their standard form, so the bytes may differ, the meaning not).
        #[test]
        fn reparse_is_stable(ty in prop_oneof![Just(0u8), Just(2), Just(3), Just(4), Just(5), Just(15)],
                             counter in 0u8..8,
                             data in proptest::collection::vec(any::<u8>(), 0..120)) {
            let mut bytes = vec![0u8; HEADER_LEN + data.len()];
            bytes[0..2].copy_from_slice(&(data.len() as u16).to_le_bytes());
            bytes[5] = ty | (counter << 4);
            bytes[HEADER_LEN..].copy_from_slice(&data);
            if let Ok(message) = MailboxMessage::parse(&bytes) {
                let out = message.to_vec().unwrap();
                let again = MailboxMessage::parse(&out).unwrap();
                prop_assert_eq!(again.payload, message.payload);
            }
        }
    }
}
