//! The 6-byte mailbox header (ETG.1000.4 mailbox header, spec-notes §mbx.header).
//!
//! ```text
//! offset 0  u16  length   bytes of mailbox data after this header
//! offset 2  u16  address  station address of the source (to a slave) or destination (from it)
//! offset 4  u8   bits 0-5 channel, bits 6-7 priority
//! offset 5  u8   bits 0-3 type, bits 4-6 counter, bit 7 reserved
//! ```

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field::{self, Field, Rest};
use crate::macros::enum_with_unknown;

mod fields {
    use super::{Field, Rest};
    pub const LENGTH: Field = 0..2;
    pub const ADDRESS: Field = 2..4;
    pub const CHANNEL_PRIORITY: usize = 4;
    pub const TYPE_COUNTER: usize = 5;
    pub const DATA: Rest = 6..;
}

/// Size of the mailbox header in bytes.
pub const HEADER_LEN: usize = fields::DATA.start;

enum_with_unknown! {
    /// Mailbox protocol type (header byte 5, bits 0-3).
    pub enum MailboxType(u8) {
        /// Mailbox error reply (ETG.1000.4, spec-notes §mbx.error).
        Error = 0x0,
        /// ADS over EtherCAT.
        Aoe = 0x1,
        /// Ethernet over EtherCAT.
        Eoe = 0x2,
        /// CANopen over EtherCAT.
        Coe = 0x3,
        /// File access over EtherCAT.
        Foe = 0x4,
        /// Servo drive profile over EtherCAT.
        Soe = 0x5,
        /// Vendor specific.
        Voe = 0xF,
    }
}

impl MailboxType {
    /// Short protocol name as used in logs and metrics labels.
    pub fn name(self) -> &'static str {
        match self {
            MailboxType::Error => "ERR",
            MailboxType::Aoe => "AoE",
            MailboxType::Eoe => "EoE",
            MailboxType::Coe => "CoE",
            MailboxType::Foe => "FoE",
            MailboxType::Soe => "SoE",
            MailboxType::Voe => "VoE",
            MailboxType::Unknown(_) => "unknown",
        }
    }
}

/// A read/write view of a mailbox message: the header and the data that follow it.
#[derive(Debug, Clone)]
pub struct Mailbox<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Mailbox<T> {
    /// Wraps a buffer without checking it; accessors may panic until [`Self::check_len`] passed.
    pub const fn new_unchecked(buffer: T) -> Self {
        Mailbox { buffer }
    }

    /// Wraps a buffer and checks that the header and the declared data are present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let mailbox = Self::new_unchecked(buffer);
        mailbox.check_len()?;
        Ok(mailbox)
    }

    /// Checks that the header is present and that `length` does not exceed the buffer.
    ///
    /// Trailing bytes beyond `length` are allowed: a mailbox read from SM1 always has the
    /// SyncManager's full size, padded with whatever the slave left there.
    pub fn check_len(&self) -> Result<()> {
        let buf = self.buffer.as_ref();
        need("mailbox header", buf, HEADER_LEN)?;
        let declared = usize::from(self.length());
        if HEADER_LEN + declared > buf.len() {
            return Err(WireError::BadLength {
                what: "mailbox length",
                declared,
                available: buf.len() - HEADER_LEN,
            });
        }
        Ok(())
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Length of the mailbox data following the header.
    pub fn length(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::LENGTH.start)
    }

    /// Station address of the source (requests) or destination (replies); 0 is the master.
    pub fn address(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::ADDRESS.start)
    }

    /// Channel (bits 0-5 of byte 4); reserved, normally 0.
    pub fn channel(&self) -> u8 {
        self.buffer.as_ref()[fields::CHANNEL_PRIORITY] & 0x3F
    }

    /// Priority 0 (lowest) to 3 (highest).
    pub fn priority(&self) -> u8 {
        self.buffer.as_ref()[fields::CHANNEL_PRIORITY] >> 6
    }

    /// Mailbox protocol type.
    pub fn mailbox_type(&self) -> MailboxType {
        MailboxType::from(self.buffer.as_ref()[fields::TYPE_COUNTER] & 0x0F)
    }

    /// Counter 0..7 (0 disables the slave's duplicate check).
    pub fn counter(&self) -> u8 {
        (self.buffer.as_ref()[fields::TYPE_COUNTER] >> 4) & 0x07
    }

    /// The reserved bit 7 of byte 5 (Wireshark: "unsupported protocol"); sent as 0.
    pub fn reserved_bit(&self) -> bool {
        self.buffer.as_ref()[fields::TYPE_COUNTER] & 0x80 != 0
    }

    /// The mailbox data: exactly `length` bytes after the header.
    pub fn data(&self) -> &[u8] {
        let end = HEADER_LEN + usize::from(self.length());
        &self.buffer.as_ref()[fields::DATA.start..end]
    }

    /// Total size of the message (header + declared data).
    pub fn total_len(&self) -> usize {
        HEADER_LEN + usize::from(self.length())
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Mailbox<T> {
    /// Sets the data length.
    pub fn set_length(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::LENGTH.start, value)
    }

    /// Sets the address field.
    pub fn set_address(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::ADDRESS.start, value)
    }

    /// Sets channel (6 bits) and priority (2 bits).
    pub fn set_channel_priority(&mut self, channel: u8, priority: u8) {
        self.buffer.as_mut()[fields::CHANNEL_PRIORITY] =
            (channel & 0x3F) | ((priority & 0x03) << 6);
    }

    /// Sets type and counter; the reserved bit is cleared.
    pub fn set_type_counter(&mut self, mailbox_type: MailboxType, counter: u8) {
        self.buffer.as_mut()[fields::TYPE_COUNTER] =
            (u8::from(mailbox_type) & 0x0F) | ((counter & 0x07) << 4);
    }

    /// Mutable mailbox data (`length` bytes after the header).
    pub fn data_mut(&mut self) -> &mut [u8] {
        let end = HEADER_LEN + usize::from(self.length());
        &mut self.buffer.as_mut()[fields::DATA.start..end]
    }
}

/// The parsed mailbox header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct MailboxHeader {
    /// Bytes of data after the header.
    pub length: u16,
    /// Source (to slave) or destination (from slave) station address; 0 = master.
    pub address: u16,
    /// Channel, 0..=63 (reserved, normally 0).
    pub channel: u8,
    /// Priority, 0..=3.
    pub priority: u8,
    /// Protocol.
    pub mailbox_type: MailboxType,
    /// Counter, 0..=7.
    pub counter: u8,
}

impl MailboxHeader {
    /// Parses the header of a checked mailbox view.
    ///
    /// The reserved bit is ignored on receive (spec-notes §mbx.header); a mailbox type that
    /// does not fit in 4 bits cannot occur.
    pub fn parse<T: AsRef<[u8]>>(mailbox: &Mailbox<T>) -> Result<Self> {
        mailbox.check_len()?;
        Ok(MailboxHeader {
            length: mailbox.length(),
            address: mailbox.address(),
            channel: mailbox.channel(),
            priority: mailbox.priority(),
            mailbox_type: mailbox.mailbox_type(),
            counter: mailbox.counter(),
        })
    }

    /// Size of the header on the wire.
    pub const fn buffer_len(&self) -> usize {
        HEADER_LEN
    }

    /// Writes the header into the first 6 bytes of `mailbox`'s buffer.
    ///
    /// Values wider than their field (channel > 63, priority > 3, counter > 7, a type > 15)
    /// are refused instead of being silently truncated.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, mailbox: &mut Mailbox<T>) -> Result<()> {
        room("mailbox header", mailbox.buffer.as_ref(), HEADER_LEN)?;
        if self.channel > 0x3F
            || self.priority > 3
            || self.counter > 7
            || u8::from(self.mailbox_type) > 0x0F
        {
            return Err(WireError::Invalid {
                what: "mailbox header",
                reason: "channel, priority, counter or type out of range",
            });
        }
        mailbox.set_length(self.length);
        mailbox.set_address(self.address);
        mailbox.set_channel_priority(self.channel, self.priority);
        mailbox.set_type_counter(self.mailbox_type, self.counter);
        Ok(())
    }
}

impl fmt::Display for MailboxHeader {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "MBX {} len={} addr={:#06x} cnt={}",
            self.mailbox_type.name(),
            self.length,
            self.address,
            self.counter
        )?;
        if self.priority != 0 || self.channel != 0 {
            write!(f, " prio={} ch={}", self.priority, self.channel)?;
        }
        if let MailboxType::Unknown(raw) = self.mailbox_type {
            write!(f, " (type {raw:#x})")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    // ETG.1000.4, spec-notes §mbx.header worked example: length 10, address 0, CoE, counter 2.
    static HEADER_BYTES: [u8; 6] = [0x0a, 0x00, 0x00, 0x00, 0x00, 0x23];

    fn repr() -> MailboxHeader {
        MailboxHeader {
            length: 10,
            address: 0,
            channel: 0,
            priority: 0,
            mailbox_type: MailboxType::Coe,
            counter: 2,
        }
    }

    #[test]
    fn parse_worked_example() {
        let mut bytes = HEADER_BYTES.to_vec();
        bytes.extend_from_slice(&[0u8; 10]);
        let mbx = Mailbox::new_checked(&bytes[..]).unwrap();
        assert_eq!(MailboxHeader::parse(&mbx).unwrap(), repr());
        assert_eq!(mbx.data().len(), 10);
    }

    #[test]
    fn emit_worked_example() {
        let mut bytes = [0xa5u8; 6];
        repr()
            .emit(&mut Mailbox::new_unchecked(&mut bytes[..]))
            .unwrap();
        assert_eq!(bytes, HEADER_BYTES);
    }

    #[test]
    fn length_beyond_buffer_is_an_error() {
        // Declares 10 data bytes, carries 2.
        let bytes = [0x0a, 0x00, 0x00, 0x00, 0x00, 0x23, 0x00, 0x20];
        assert_eq!(
            Mailbox::new_checked(&bytes[..]).unwrap_err(),
            WireError::BadLength {
                what: "mailbox length",
                declared: 10,
                available: 2
            }
        );
    }

    #[test]
    fn out_of_range_fields_are_refused_on_emit() {
        let mut bytes = [0u8; 6];
        let bad = MailboxHeader {
            counter: 8,
            ..repr()
        };
        assert!(
            bad.emit(&mut Mailbox::new_unchecked(&mut bytes[..]))
                .is_err()
        );
        assert_eq!(bytes, [0u8; 6], "a refused emit writes nothing");
    }

    #[test]
    fn display_is_readable() {
        assert_eq!(repr().to_string(), "MBX CoE len=10 addr=0x0000 cnt=2");
    }

    pub(crate) fn arb_header() -> impl Strategy<Value = MailboxHeader> {
        (any::<u16>(), any::<u16>(), 0u8..64, 0u8..4, 0u8..16, 0u8..8).prop_map(
            |(length, address, channel, priority, ty, counter)| MailboxHeader {
                length,
                address,
                channel,
                priority,
                mailbox_type: MailboxType::from(ty),
                counter,
            },
        )
    }

    proptest! {
        #[test]
        fn round_trip(header in arb_header()) {
            let mut bytes = vec![0u8; HEADER_LEN + usize::from(header.length)];
            header.emit(&mut Mailbox::new_unchecked(&mut bytes[..])).unwrap();
            let parsed = MailboxHeader::parse(&Mailbox::new_checked(&bytes[..]).unwrap()).unwrap();
            prop_assert_eq!(parsed, header);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            if let Ok(mbx) = Mailbox::new_checked(&bytes[..]) {
                let _ = MailboxHeader::parse(&mbx);
                let _ = mbx.data();
            }
        }
    }
}
