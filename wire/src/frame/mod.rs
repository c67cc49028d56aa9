//! The EtherCAT frame: 2-byte EtherCAT header plus payload (ETG.1000.4, spec-notes §frame).
//!
//! ```text
//! offset 0  u16 LE  bits 0-10 length (payload bytes after this header, padding excluded)
//!                   bit 11 reserved (0), bits 12-15 type (1 = datagrams)
//! offset 2  ...     payload: datagrams (type 1), network variables (4), mailbox (5)
//! ...               zero padding up to the Ethernet minimum, not counted in `length`
//! ```
//!
//! The same bytes are the Ethernet payload behind EtherType 0x88A4 and the UDP payload on
//! port 0x88A4 ([`Frame`]). [`EthercatFrame`] parses a whole Ethernet frame down to the
//! EtherCAT payload and iterates its datagrams. [`FrameBuilder`] (`builder`) packs
//! datagrams into a frame.

mod builder;

pub use builder::FrameBuilder;

use core::fmt;

use crate::datagram::{Datagram, Datagrams};
use crate::error::{Result, WireError, need, room};
use crate::ethernet::{ETHERTYPE_ETHERCAT, EthernetFrame, EthernetRepr};
use crate::field::{self, Field, Rest};
use crate::macros::enum_with_unknown;

mod fields {
    use super::{Field, Rest};
    pub const HEADER: Field = 0..2;
    pub const PAYLOAD: Rest = 2..;

    pub const LENGTH_MASK: u16 = 0x07FF;
    pub const RESERVED_MASK: u16 = 0x0800;
    pub const TYPE_SHIFT: u32 = 12;
}

/// Size of the EtherCAT header in bytes.
pub const HEADER_LEN: usize = fields::PAYLOAD.start;
/// Largest value of the 11-bit length field.
pub const MAX_LENGTH: u16 = fields::LENGTH_MASK;
/// The reserved bit 11 of the EtherCAT header (must be 0).
pub const RESERVED_BIT: u16 = fields::RESERVED_MASK;
/// Largest EtherCAT payload that fits a standard 1500-byte Ethernet MTU (spec-notes §datagram).
pub const MAX_PAYLOAD_LEN: usize = 1500 - HEADER_LEN;

enum_with_unknown! {
    /// EtherCAT header type, bits 12-15 (spec-notes §frame; names as Wireshark's frame dissector).
    pub enum FrameType(u8) {
        /// EtherCAT DLPDU: a chain of datagrams ("EtherCAT command").
        Datagrams = 1,
        /// ADS (Beckhoff specific, not used by ecatd).
        Ads = 2,
        /// RAW-IO (Beckhoff specific, not used by ecatd).
        RawIo = 3,
        /// Network variables (ETG.1000.4, spec-notes §frame).
        NetworkVariables = 4,
        /// Mailbox (ETG.8200 gateway over UDP, spec-notes §gateway).
        Mailbox = 5,
    }
}

impl FrameType {
    /// The type's name as Wireshark shows it.
    pub fn name(self) -> &'static str {
        match self {
            FrameType::Datagrams => "EtherCAT command",
            FrameType::Ads => "ADS",
            FrameType::RawIo => "RAW-IO",
            FrameType::NetworkVariables => "Network Variables",
            FrameType::Mailbox => "Mailbox",
            FrameType::Unknown(_) => "unknown",
        }
    }
}

/// A read/write view of an EtherCAT frame: header, payload and any padding after it.
#[derive(Debug, Clone)]
pub struct Frame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Frame<T> {
    /// Wraps a buffer without checking it; accessors may panic until [`Self::check_len`] passed.
    pub const fn new_unchecked(buffer: T) -> Self {
        Frame { buffer }
    }

    /// Wraps a buffer and checks that the header and the declared payload are present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let frame = Self::new_unchecked(buffer);
        frame.check_len()?;
        Ok(frame)
    }

    /// Checks that the header is present and that `length` does not exceed the buffer.
    ///
    /// Bytes after `length` are allowed and ignored: they are Ethernet padding (spec-notes §frame).
    /// The reserved bit is checked by [`FrameHeader::parse`], not here.
    pub fn check_len(&self) -> Result<()> {
        let buf = self.buffer.as_ref();
        need("EtherCAT header", buf, HEADER_LEN)?;
        let declared = usize::from(self.length());
        let available = buf.len() - HEADER_LEN;
        if declared > available {
            return Err(WireError::BadLength {
                what: "EtherCAT length",
                declared,
                available,
            });
        }
        Ok(())
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// The raw 16-bit header value.
    pub fn header(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::HEADER.start)
    }

    /// Payload length (bits 0-10).
    pub fn length(&self) -> u16 {
        self.header() & fields::LENGTH_MASK
    }

    /// The reserved bit 11 (must be 0).
    pub fn reserved_bit(&self) -> bool {
        self.header() & fields::RESERVED_MASK != 0
    }

    /// Payload type (bits 12-15).
    pub fn frame_type(&self) -> FrameType {
        FrameType::from((self.header() >> fields::TYPE_SHIFT) as u8)
    }

    /// The payload: exactly `length` bytes after the header.
    pub fn payload(&self) -> &[u8] {
        let end = HEADER_LEN + usize::from(self.length());
        &self.buffer.as_ref()[fields::PAYLOAD.start..end]
    }

    /// The bytes after the payload (padding), ignored by receivers.
    pub fn padding(&self) -> &[u8] {
        let end = HEADER_LEN + usize::from(self.length());
        &self.buffer.as_ref()[end..]
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Frame<T> {
    /// Sets the raw 16-bit header value.
    pub fn set_header(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::HEADER.start, value)
    }

    /// Sets length (masked to 11 bits) and type (masked to 4 bits); clears the reserved bit.
    pub fn set_length_type(&mut self, length: u16, frame_type: FrameType) {
        let ty = u16::from(u8::from(frame_type) & 0x0F);
        self.set_header((length & fields::LENGTH_MASK) | ty << fields::TYPE_SHIFT)
    }

    /// Mutable payload (`length` bytes after the header).
    pub fn payload_mut(&mut self) -> &mut [u8] {
        let end = HEADER_LEN + usize::from(self.length());
        &mut self.buffer.as_mut()[fields::PAYLOAD.start..end]
    }
}

/// The parsed EtherCAT header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FrameHeader {
    /// Payload bytes after the header (0..=2047; padding not counted).
    pub length: u16,
    /// Payload type.
    pub frame_type: FrameType,
}

impl FrameHeader {
    /// Parses the header of a checked view; the reserved bit 11 set is an error (Wireshark
    /// flags it as invalid, ETG.1000.4, spec-notes §frame).
    pub fn parse<T: AsRef<[u8]>>(frame: &Frame<T>) -> Result<Self> {
        frame.check_len()?;
        if frame.reserved_bit() {
            return Err(WireError::ReservedBits {
                what: "EtherCAT header",
                value: u32::from(fields::RESERVED_MASK),
            });
        }
        Ok(FrameHeader {
            length: frame.length(),
            frame_type: frame.frame_type(),
        })
    }

    /// Size of the header on the wire.
    pub const fn buffer_len(&self) -> usize {
        HEADER_LEN
    }

    /// The 16-bit header value, or an error if a field does not fit its bits.
    pub fn to_raw(&self) -> Result<u16> {
        if self.length > MAX_LENGTH {
            return Err(WireError::BadLength {
                what: "EtherCAT length",
                declared: usize::from(self.length),
                available: usize::from(MAX_LENGTH),
            });
        }
        let ty = u8::from(self.frame_type);
        if ty > 0x0F {
            return Err(WireError::Invalid {
                what: "EtherCAT header",
                reason: "type does not fit in 4 bits",
            });
        }
        Ok(self.length | u16::from(ty) << fields::TYPE_SHIFT)
    }

    /// Writes the header into the first 2 bytes of `frame`'s buffer.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, frame: &mut Frame<T>) -> Result<()> {
        room("EtherCAT header", frame.buffer.as_ref(), HEADER_LEN)?;
        let raw = self.to_raw()?;
        frame.set_header(raw);
        Ok(())
    }
}

impl fmt::Display for FrameHeader {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "ECAT {} len={}", self.frame_type.name(), self.length)?;
        if let FrameType::Unknown(raw) = self.frame_type {
            write!(f, " (type {raw:#x})")?;
        }
        Ok(())
    }
}

/// A whole Ethernet frame carrying EtherCAT, parsed down to the EtherCAT payload.
///
/// Accepts frames with or without padding (captures taken on the sending host lack it,
/// ETG.1000.4, spec-notes §frame) and with or without one 802.1Q tag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EthercatFrame<'a> {
    /// The Ethernet header.
    pub ethernet: EthernetRepr,
    /// The EtherCAT header.
    pub header: FrameHeader,
    /// Offset of the EtherCAT payload in the Ethernet frame (16, or 20 with a VLAN tag).
    pub payload_offset: usize,
    /// The EtherCAT payload: exactly `header.length` bytes, padding excluded.
    pub payload: &'a [u8],
}

impl<'a> EthercatFrame<'a> {
    /// Parses an Ethernet frame (without FCS).
    ///
    /// Errors: truncated Ethernet header, EtherType other than 0x88A4
    /// ([`WireError::UnknownType`]), truncated EtherCAT header, length beyond the bytes
    /// present ([`WireError::BadLength`]), reserved bit set ([`WireError::ReservedBits`]).
    pub fn parse(bytes: &'a [u8]) -> Result<Self> {
        let eth = EthernetFrame::new_checked(bytes)?;
        let ethernet = EthernetRepr::parse(&eth)?;
        if ethernet.ethertype != ETHERTYPE_ETHERCAT {
            return Err(WireError::UnknownType {
                what: "EtherType",
                value: u32::from(ethernet.ethertype),
            });
        }
        let ethernet_len = eth.header_len();
        // check_len guaranteed `ethernet_len` bytes, so the fallback is never taken.
        let frame = Frame::new_checked(eth.into_inner().get(ethernet_len..).unwrap_or_default())?;
        let header = FrameHeader::parse(&frame)?;
        let payload = frame
            .into_inner()
            .get(HEADER_LEN..HEADER_LEN + usize::from(header.length));
        Ok(EthercatFrame {
            ethernet,
            header,
            payload_offset: ethernet_len + HEADER_LEN,
            payload: payload.unwrap_or_default(),
        })
    }

    /// Iterates the datagram chain of a type-1 frame; other types are
    /// [`WireError::UnknownType`] since their payload holds no datagrams.
    pub fn datagrams(&self) -> Result<Datagrams<'a>> {
        match self.header.frame_type {
            FrameType::Datagrams => Ok(Datagrams::new(self.payload)),
            other => Err(WireError::UnknownType {
                what: "EtherCAT frame type for datagrams",
                value: u32::from(u8::from(other)),
            }),
        }
    }

    /// The datagram at `frame_offset` bytes from the start of the Ethernet frame, the offset
    /// [`crate::datagram::FrameBuilder::push`] returned when the frame was built.
    pub fn datagram_at(&self, frame_offset: usize) -> Result<Datagram<&'a [u8]>> {
        let rest = frame_offset
            .checked_sub(self.payload_offset)
            .and_then(|rel| self.payload.get(rel..))
            .ok_or(WireError::Invalid {
                what: "datagram offset",
                reason: "offset outside the EtherCAT payload",
            })?;
        Datagram::new_checked(rest)
    }
}

impl fmt::Display for EthercatFrame<'_> {
    /// The Ethernet and EtherCAT headers on one line, then one indented line per datagram.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}", self.ethernet, self.header)?;
        if let Ok(datagrams) = self.datagrams() {
            for item in datagrams {
                match item {
                    Ok(datagram) => write!(f, "\n  {datagram}")?,
                    Err(err) => write!(f, "\n  malformed: {err}")?,
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::command::Command;
    use crate::ethernet::BROADCAST;
    use proptest::prelude::*;

    // ETG.1000.4, spec-notes §commands: BRD count-slaves frame, 60 bytes without FCS.
    static C1_FRAME: [u8; 60] = [
        0xff, 0xff, 0xff, 0xff, 0xff, 0xff, // destination
        0x02, 0x00, 0x00, 0x00, 0x00, 0x01, // source
        0x88, 0xa4, // EtherType
        0x0e, 0x10, // EtherCAT header 0x100E
        0x07, 0x01, 0x00, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, // BRD idx 1 ADO 0 len 2
        0x00, 0x00, // data
        0x00, 0x00, // WKC
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        0, // 30 bytes padding
    ];

    // spec-notes §capture: the EtherCAT header of the first frame, value 0x100d.
    static SEED_HEADER: [u8; 2] = [0x0d, 0x10];

    #[test]
    fn parse_c1_frame() {
        let frame = EthercatFrame::parse(&C1_FRAME).unwrap();
        assert_eq!(frame.ethernet.destination, BROADCAST);
        assert_eq!(frame.ethernet.source, [0x02, 0, 0, 0, 0, 0x01]);
        assert_eq!(frame.ethernet.vlan_tci, None);
        assert_eq!(
            frame.header,
            FrameHeader {
                length: 14,
                frame_type: FrameType::Datagrams
            }
        );
        assert_eq!(frame.payload_offset, 16);
        assert_eq!(frame.payload, &C1_FRAME[16..30]);
        let datagrams: Vec<_> = frame.datagrams().unwrap().collect();
        assert_eq!(datagrams.len(), 1);
        let brd = datagrams[0].as_ref().unwrap();
        assert_eq!(brd.command, Command::Brd);
        assert_eq!(brd.index, 1);
        assert_eq!(brd.address, 0);
        assert_eq!(brd.data, &[0, 0]);
        assert_eq!(brd.wkc, 0);
        assert!(!brd.more);
        assert_eq!(
            frame.to_string(),
            "ETH 02:00:00:00:00:01 > ff:ff:ff:ff:ff:ff type=0x88a4 ECAT EtherCAT command len=14\n  \
             BRD idx=1 adp=0x0000 ado=0x0000 len=2 wkc=0"
        );
        // The view: padding is visible but not part of the payload.
        let view = Frame::new_checked(&C1_FRAME[14..]).unwrap();
        assert_eq!(view.header(), 0x100E);
        assert_eq!(view.padding().len(), 30);
    }

    #[test]
    fn c1_frame_without_padding_or_with_vlan_tag() {
        // As captured on the sending host: no padding (ETG.1000.4, spec-notes §frame).
        let frame = EthercatFrame::parse(&C1_FRAME[..30]).unwrap();
        assert_eq!(frame.header.length, 14);
        assert_eq!(frame.datagrams().unwrap().count(), 1);
        // With an 802.1Q tag (TCI 0x0001) inserted after the source MAC.
        let mut tagged = C1_FRAME[..12].to_vec();
        tagged.extend_from_slice(&[0x81, 0x00, 0x00, 0x01]);
        tagged.extend_from_slice(&C1_FRAME[12..]);
        let frame = EthercatFrame::parse(&tagged).unwrap();
        assert_eq!(frame.ethernet.vlan_tci, Some(1));
        assert_eq!(frame.payload_offset, 20);
        assert_eq!(frame.payload, &C1_FRAME[16..30]);
        assert_eq!(frame.datagram_at(20).unwrap().command(), Command::Brd);
    }

    #[test]
    fn c1_returned_from_three_slaves() {
        // spec-notes §commands: returned ADP `03 00`, WKC `03 00`; data = OR of type/revision (here
        // 0x11, 0x00 as an example of returned data).
        let mut returned = C1_FRAME;
        returned[18] = 0x03;
        returned[26] = 0x11;
        returned[28] = 0x03;
        let frame = EthercatFrame::parse(&returned).unwrap();
        let brd = frame.datagrams().unwrap().next().unwrap().unwrap();
        assert_eq!(brd.address, 3);
        assert_eq!(brd.wkc, 3);
        assert_eq!(brd.data, &[0x11, 0x00]);
        assert_eq!(
            brd.to_string(),
            "BRD idx=1 adp=0x0003 ado=0x0000 len=2 wkc=3"
        );
    }

    #[test]
    fn header_c1_and_seed_emit() {
        let mut bytes = [0xa5u8; 2];
        FrameHeader {
            length: 14,
            frame_type: FrameType::Datagrams,
        }
        .emit(&mut Frame::new_unchecked(&mut bytes[..]))
        .unwrap();
        assert_eq!(bytes, [0x0e, 0x10]);
        // Reference capture: 0x100d is type 1, reserved 0, length 13 (= 10 + 1 data byte + 2).
        let mut seed = SEED_HEADER.to_vec();
        seed.extend_from_slice(&[0u8; 13]);
        let header = FrameHeader::parse(&Frame::new_checked(&seed[..]).unwrap()).unwrap();
        assert_eq!(header.length, 13);
        assert_eq!(header.frame_type, FrameType::Datagrams);
        assert_eq!(header.to_raw(), Ok(0x100d));
        // Worked values (spec-notes §frame): 0x2C → `2c 10`; ethercrab's 0x28 → `28 10`.
        for (length, bytes) in [(0x2C, [0x2c, 0x10]), (0x28, [0x28, 0x10])] {
            let mut out = [0xa5u8; 2];
            FrameHeader {
                length,
                frame_type: FrameType::Datagrams,
            }
            .emit(&mut Frame::new_unchecked(&mut out[..]))
            .unwrap();
            assert_eq!(out, bytes);
        }
    }

    #[test]
    fn frame_type_names() {
        assert_eq!(FrameType::from(1), FrameType::Datagrams);
        assert_eq!(FrameType::from(4), FrameType::NetworkVariables);
        assert_eq!(FrameType::from(5), FrameType::Mailbox);
        assert_eq!(FrameType::Datagrams.name(), "EtherCAT command");
        assert_eq!(FrameType::Mailbox.name(), "Mailbox");
        assert_eq!(FrameType::NetworkVariables.name(), "Network Variables");
        assert_eq!(FrameType::from(9), FrameType::Unknown(9));
        // Type 5 mailbox header as the ETG.8200 gateway sends it (spec-notes §gateway: `10 50`).
        let mut bytes = [0x10, 0x50, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
        let view = Frame::new_checked(&bytes[..]).unwrap();
        assert_eq!(view.frame_type(), FrameType::Mailbox);
        assert_eq!(view.length(), 16);
        bytes[1] = 0x90;
        let header = FrameHeader::parse(&Frame::new_checked(&bytes[..]).unwrap()).unwrap();
        assert_eq!(header.to_string(), "ECAT unknown len=16 (type 0x9)");
    }

    #[test]
    fn reserved_bit_is_refused() {
        // 0x180E: the count-slaves frame's header with bit 11 set (spec-notes §frame).
        let mut bytes = C1_FRAME;
        bytes[15] = 0x18;
        assert_eq!(
            EthercatFrame::parse(&bytes).unwrap_err(),
            WireError::ReservedBits {
                what: "EtherCAT header",
                value: 0x0800
            }
        );
    }

    #[test]
    fn length_beyond_buffer_is_bad_length() {
        // Declares 14 payload bytes, carries 13.
        assert_eq!(
            EthercatFrame::parse(&C1_FRAME[..29]).unwrap_err(),
            WireError::BadLength {
                what: "EtherCAT length",
                declared: 14,
                available: 13
            }
        );
        assert!(matches!(
            EthercatFrame::parse(&C1_FRAME[..15]),
            Err(WireError::Truncated {
                what: "EtherCAT header",
                ..
            })
        ));
    }

    #[test]
    fn other_ethertypes_are_refused() {
        let mut bytes = C1_FRAME;
        bytes[12] = 0x08;
        bytes[13] = 0x00;
        assert_eq!(
            EthercatFrame::parse(&bytes).unwrap_err(),
            WireError::UnknownType {
                what: "EtherType",
                value: 0x0800
            }
        );
    }

    #[test]
    fn non_datagram_types_have_no_datagrams() {
        let mut bytes = C1_FRAME;
        bytes[15] = 0x50;
        let frame = EthercatFrame::parse(&bytes).unwrap();
        assert!(frame.datagrams().is_err());
    }

    #[test]
    fn emit_out_of_range_writes_nothing() {
        let mut bytes = [0u8; 2];
        let long = FrameHeader {
            length: 0x800,
            frame_type: FrameType::Datagrams,
        };
        assert!(
            long.emit(&mut Frame::new_unchecked(&mut bytes[..]))
                .is_err()
        );
        let wide = FrameHeader {
            length: 1,
            frame_type: FrameType::Unknown(0x10),
        };
        assert!(
            wide.emit(&mut Frame::new_unchecked(&mut bytes[..]))
                .is_err()
        );
        assert_eq!(bytes, [0u8; 2]);
        assert!(matches!(
            long.emit(&mut Frame::new_unchecked(&mut bytes[..1])),
            Err(WireError::BufferTooSmall { .. })
        ));
    }

    #[test]
    fn datagram_at_rejects_offsets_outside_payload() {
        let frame = EthercatFrame::parse(&C1_FRAME).unwrap();
        assert!(frame.datagram_at(16).is_ok());
        assert!(frame.datagram_at(15).is_err());
        assert!(frame.datagram_at(30).is_err());
        assert!(frame.datagram_at(1000).is_err());
    }

    pub(crate) fn arb_header() -> impl Strategy<Value = FrameHeader> {
        (0u16..=MAX_LENGTH, 0u8..16).prop_map(|(length, ty)| FrameHeader {
            length,
            frame_type: FrameType::from(ty),
        })
    }

    proptest! {
        #[test]
        fn round_trip(header in arb_header(), padding in 0usize..4) {
            let mut bytes = vec![0u8; HEADER_LEN + usize::from(header.length) + padding];
            header.emit(&mut Frame::new_unchecked(&mut bytes[..])).unwrap();
            let view = Frame::new_checked(&bytes[..]).unwrap();
            prop_assert_eq!(FrameHeader::parse(&view).unwrap(), header);
            prop_assert_eq!(view.payload().len(), usize::from(header.length));
            prop_assert_eq!(view.padding().len(), padding);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..96)) {
            if let Ok(view) = Frame::new_checked(&bytes[..]) {
                let _ = FrameHeader::parse(&view);
                let _ = (view.payload(), view.padding());
            }
        }

        #[test]
        fn whole_frame_never_panics(
            tail in proptest::collection::vec(any::<u8>(), 0..96),
            tagged: bool,
            offset in 0usize..128,
        ) {
            // Most random bytes fail at the EtherType; start from a valid Ethernet header so
            // the EtherCAT header and datagram chain see random bytes.
            let mut bytes = C1_FRAME[..12].to_vec();
            if tagged {
                bytes.extend_from_slice(&[0x81, 0x00, 0x00, 0x00]);
            }
            bytes.extend_from_slice(&[0x88, 0xa4]);
            bytes.extend_from_slice(&tail);
            for input in [&bytes[..], &tail[..]] {
                if let Ok(frame) = EthercatFrame::parse(input) {
                    let _ = frame.to_string();
                    if let Ok(chain) = frame.datagrams() {
                        for item in chain {
                            let _ = item.map(|d| d.to_string());
                        }
                    }
                    let _ = frame.datagram_at(offset);
                }
            }
        }

        #[test]
        fn whole_frame_round_trip(
            ethernet in crate::ethernet::tests::arb_ethernet(),
            header in arb_header(),
            padding in 0usize..50,
        ) {
            let ethernet = EthernetRepr { ethertype: ETHERTYPE_ETHERCAT, ..ethernet };
            let total = ethernet.buffer_len() + HEADER_LEN + usize::from(header.length) + padding;
            let mut bytes = vec![0u8; total];
            ethernet.emit(&mut EthernetFrame::new_unchecked(&mut bytes[..])).unwrap();
            let start = ethernet.buffer_len();
            header.emit(&mut Frame::new_unchecked(&mut bytes[start..])).unwrap();
            let frame = EthercatFrame::parse(&bytes).unwrap();
            prop_assert_eq!(frame.ethernet, ethernet);
            prop_assert_eq!(frame.header, header);
            prop_assert_eq!(frame.payload.len(), usize::from(header.length));
            prop_assert_eq!(frame.payload_offset, start + HEADER_LEN);
        }
    }

    #[test]
    fn display_of_an_unparsable_chain() {
        // One datagram declaring M=1 and nothing after it.
        let mut bytes = C1_FRAME;
        bytes[23] = 0x80;
        let frame = EthercatFrame::parse(&bytes).unwrap();
        let text = frame.to_string();
        assert!(text.contains("\n  BRD idx=1"), "{text}");
        assert!(text.contains("\n  malformed: "), "{text}");
    }
}
