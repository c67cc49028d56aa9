//! The Ethernet II header that carries EtherCAT (ETG.1000.4, spec-notes §frame).
//!
//! ```text
//! offset 0   [u8; 6]  destination MAC (masters send broadcast ff:ff:ff:ff:ff:ff)
//! offset 6   [u8; 6]  source MAC
//! offset 12  u16 BE   EtherType (0x88A4), or 0x8100 followed by a 2-byte TCI and the
//!                     real EtherType at offset 16 (one optional IEEE 802.1Q tag)
//! ```
//!
//! This is the only big-endian structure of the wire layer. The FCS is not part of the
//! buffers handled here: NICs add and strip it.

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field::{Field, Rest};

mod fields {
    use super::{Field, Rest};
    pub const DESTINATION: Field = 0..6;
    pub const SOURCE: Field = 6..12;
    pub const ETHERTYPE: Field = 12..14;
    pub const PAYLOAD: Rest = 14..;
    /// With an 802.1Q tag, ETHERTYPE holds the TPID 0x8100 and these follow it.
    pub const VLAN_TCI: Field = 14..16;
    pub const VLAN_ETHERTYPE: Field = 16..18;
    pub const VLAN_PAYLOAD: Rest = 18..;
}

/// Size of an untagged Ethernet II header.
pub const HEADER_LEN: usize = fields::PAYLOAD.start;
/// Size of an Ethernet II header with one 802.1Q tag.
pub const VLAN_HEADER_LEN: usize = fields::VLAN_PAYLOAD.start;
/// EtherType of EtherCAT (ETG.1000.4, spec-notes §frame).
pub const ETHERTYPE_ETHERCAT: u16 = 0x88A4;
/// Tag protocol identifier of an IEEE 802.1Q VLAN tag.
pub const ETHERTYPE_VLAN: u16 = 0x8100;
/// Minimum Ethernet frame length without the FCS (ETG.1000.4, spec-notes §frame: 64 with FCS).
pub const MIN_FRAME_LEN: usize = 60;
/// Maximum untagged Ethernet frame length without the FCS (1500-byte MTU + header).
pub const MAX_FRAME_LEN: usize = HEADER_LEN + 1500;
/// The broadcast MAC address masters send to.
pub const BROADCAST: [u8; 6] = [0xFF; 6];

/// Number of zero bytes to append to a frame of `frame_len` bytes (header included, FCS
/// excluded) so that it reaches the Ethernet minimum of [`MIN_FRAME_LEN`] (spec-notes §frame).
pub const fn padding_len(frame_len: usize) -> usize {
    MIN_FRAME_LEN.saturating_sub(frame_len)
}

/// Display wrapper for a MAC address: `aa:bb:cc:dd:ee:ff`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Mac(pub [u8; 6]);

impl fmt::Display for Mac {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [a, b, c, d, e, g] = self.0;
        write!(f, "{a:02x}:{b:02x}:{c:02x}:{d:02x}:{e:02x}:{g:02x}")
    }
}

/// A read/write view of an Ethernet II frame (header, optional 802.1Q tag, payload).
#[derive(Debug, Clone)]
pub struct EthernetFrame<T: AsRef<[u8]>> {
    buffer: T,
}

fn mac_at(buf: &[u8], range: Field) -> [u8; 6] {
    let mut mac = [0u8; 6];
    mac.copy_from_slice(&buf[range]);
    mac
}

fn u16_be(buf: &[u8], range: Field) -> u16 {
    u16::from_be_bytes([buf[range.start], buf[range.start + 1]])
}

impl<T: AsRef<[u8]>> EthernetFrame<T> {
    /// Wraps a buffer without checking it; accessors may panic until [`Self::check_len`] passed.
    pub const fn new_unchecked(buffer: T) -> Self {
        EthernetFrame { buffer }
    }

    /// Wraps a buffer and checks that the header (and the VLAN tag, if announced) is present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let frame = Self::new_unchecked(buffer);
        frame.check_len()?;
        Ok(frame)
    }

    /// Checks that the 14-byte header is present, and the 4 more bytes of an 802.1Q tag when
    /// the first EtherType is 0x8100.
    pub fn check_len(&self) -> Result<()> {
        let buf = self.buffer.as_ref();
        need("Ethernet header", buf, HEADER_LEN)?;
        if u16_be(buf, fields::ETHERTYPE) == ETHERTYPE_VLAN {
            need("Ethernet 802.1Q tag", buf, VLAN_HEADER_LEN)?;
        }
        Ok(())
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Destination MAC address.
    pub fn destination(&self) -> [u8; 6] {
        mac_at(self.buffer.as_ref(), fields::DESTINATION)
    }

    /// Source MAC address.
    pub fn source(&self) -> [u8; 6] {
        mac_at(self.buffer.as_ref(), fields::SOURCE)
    }

    /// The EtherType at offset 12 (0x8100 for a tagged frame).
    pub fn outer_ethertype(&self) -> u16 {
        u16_be(self.buffer.as_ref(), fields::ETHERTYPE)
    }

    /// The 802.1Q tag control information (priority, DEI, VLAN id), if the frame is tagged.
    pub fn vlan_tci(&self) -> Option<u16> {
        (self.outer_ethertype() == ETHERTYPE_VLAN)
            .then(|| u16_be(self.buffer.as_ref(), fields::VLAN_TCI))
    }

    /// The EtherType of the payload, behind the VLAN tag if there is one.
    pub fn ethertype(&self) -> u16 {
        if self.outer_ethertype() == ETHERTYPE_VLAN {
            u16_be(self.buffer.as_ref(), fields::VLAN_ETHERTYPE)
        } else {
            self.outer_ethertype()
        }
    }

    /// Header length: 14, or 18 with a VLAN tag.
    pub fn header_len(&self) -> usize {
        if self.outer_ethertype() == ETHERTYPE_VLAN {
            VLAN_HEADER_LEN
        } else {
            HEADER_LEN
        }
    }

    /// Everything after the header, padding included (Ethernet has no length field).
    pub fn payload(&self) -> &[u8] {
        &self.buffer.as_ref()[self.header_len()..]
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> EthernetFrame<T> {
    /// Sets the destination MAC address.
    pub fn set_destination(&mut self, mac: [u8; 6]) {
        self.buffer.as_mut()[fields::DESTINATION].copy_from_slice(&mac);
    }

    /// Sets the source MAC address.
    pub fn set_source(&mut self, mac: [u8; 6]) {
        self.buffer.as_mut()[fields::SOURCE].copy_from_slice(&mac);
    }

    /// Sets the EtherType at offset 12 (making the frame untagged unless it is 0x8100).
    pub fn set_outer_ethertype(&mut self, value: u16) {
        self.buffer.as_mut()[fields::ETHERTYPE].copy_from_slice(&value.to_be_bytes());
    }

    /// Writes an 802.1Q tag (TPID, TCI) and the inner EtherType; needs 18 bytes.
    pub fn set_vlan(&mut self, tci: u16, ethertype: u16) {
        let buf = self.buffer.as_mut();
        buf[fields::ETHERTYPE].copy_from_slice(&ETHERTYPE_VLAN.to_be_bytes());
        buf[fields::VLAN_TCI].copy_from_slice(&tci.to_be_bytes());
        buf[fields::VLAN_ETHERTYPE].copy_from_slice(&ethertype.to_be_bytes());
    }

    /// Mutable payload (everything after the header).
    pub fn payload_mut(&mut self) -> &mut [u8] {
        let start = self.header_len();
        &mut self.buffer.as_mut()[start..]
    }
}

/// The parsed Ethernet II header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct EthernetRepr {
    /// Destination MAC address.
    pub destination: [u8; 6],
    /// Source MAC address.
    pub source: [u8; 6],
    /// Tag control information of one 802.1Q tag, if present.
    pub vlan_tci: Option<u16>,
    /// EtherType of the payload (behind the tag, if any).
    pub ethertype: u16,
}

impl EthernetRepr {
    /// Parses the header of a checked view.
    pub fn parse<T: AsRef<[u8]>>(frame: &EthernetFrame<T>) -> Result<Self> {
        frame.check_len()?;
        Ok(EthernetRepr {
            destination: frame.destination(),
            source: frame.source(),
            vlan_tci: frame.vlan_tci(),
            ethertype: frame.ethertype(),
        })
    }

    /// Header size on the wire: 14, or 18 with a VLAN tag.
    pub const fn buffer_len(&self) -> usize {
        match self.vlan_tci {
            Some(_) => VLAN_HEADER_LEN,
            None => HEADER_LEN,
        }
    }

    /// Writes the header at the start of `frame`'s buffer.
    ///
    /// An untagged header with EtherType 0x8100 is refused: it would read back as tagged.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, frame: &mut EthernetFrame<T>) -> Result<()> {
        room("Ethernet header", frame.buffer.as_ref(), self.buffer_len())?;
        if self.ethertype == ETHERTYPE_VLAN {
            return Err(WireError::Invalid {
                what: "Ethernet header",
                reason: "EtherType 0x8100 is the VLAN tag identifier, not a payload type",
            });
        }
        frame.set_destination(self.destination);
        frame.set_source(self.source);
        match self.vlan_tci {
            Some(tci) => frame.set_vlan(tci, self.ethertype),
            None => frame.set_outer_ethertype(self.ethertype),
        }
        Ok(())
    }
}

impl fmt::Display for EthernetRepr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ETH {} > {} type={:#06x}",
            Mac(self.source),
            Mac(self.destination),
            self.ethertype
        )?;
        if let Some(tci) = self.vlan_tci {
            write!(f, " vlan={} prio={}", tci & 0x0FFF, tci >> 13)?;
        }
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    // ETG.1000.4, spec-notes §commands: the first 14 bytes of the 60-byte count-slaves frame.
    static HEADER_BYTES: [u8; 14] = [
        0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02, 0x00, 0x00, 0x00, 0x00, 0x01, 0x88, 0xa4,
    ];

    // The same header with an 802.1Q tag, VLAN 5 priority 3 (TCI 0x6005), worked out by hand.
    static TAGGED_BYTES: [u8; 18] = [
        0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02, 0x00, 0x00, 0x00, 0x00, 0x01, 0x81, 0x00, 0x60,
        0x05, 0x88, 0xa4,
    ];

    fn repr() -> EthernetRepr {
        EthernetRepr {
            destination: BROADCAST,
            source: [0x02, 0, 0, 0, 0, 0x01],
            vlan_tci: None,
            ethertype: ETHERTYPE_ETHERCAT,
        }
    }

    #[test]
    fn parse_c1_header() {
        let frame = EthernetFrame::new_checked(&HEADER_BYTES[..]).unwrap();
        assert_eq!(EthernetRepr::parse(&frame).unwrap(), repr());
        assert_eq!(frame.header_len(), 14);
        assert!(frame.payload().is_empty());
    }

    #[test]
    fn emit_c1_header() {
        let mut bytes = [0xa5u8; 14];
        repr()
            .emit(&mut EthernetFrame::new_unchecked(&mut bytes[..]))
            .unwrap();
        assert_eq!(bytes, HEADER_BYTES);
    }

    #[test]
    fn vlan_tag_is_skipped() {
        let tagged = EthernetRepr {
            vlan_tci: Some(0x6005),
            ..repr()
        };
        let frame = EthernetFrame::new_checked(&TAGGED_BYTES[..]).unwrap();
        assert_eq!(EthernetRepr::parse(&frame).unwrap(), tagged);
        assert_eq!(frame.outer_ethertype(), ETHERTYPE_VLAN);
        assert_eq!(frame.header_len(), 18);
        let mut bytes = [0xa5u8; 18];
        tagged
            .emit(&mut EthernetFrame::new_unchecked(&mut bytes[..]))
            .unwrap();
        assert_eq!(bytes, TAGGED_BYTES);
        assert_eq!(
            tagged.to_string(),
            "ETH 02:00:00:00:00:01 > ff:ff:ff:ff:ff:ff type=0x88a4 vlan=5 prio=3"
        );
    }

    #[test]
    fn truncated_headers() {
        assert_eq!(
            EthernetFrame::new_checked(&HEADER_BYTES[..13]).unwrap_err(),
            WireError::Truncated {
                what: "Ethernet header",
                need: 14,
                have: 13
            }
        );
        assert!(matches!(
            EthernetFrame::new_checked(&TAGGED_BYTES[..17]),
            Err(WireError::Truncated { need: 18, .. })
        ));
    }

    #[test]
    fn emit_refusals_write_nothing() {
        let mut bytes = [0u8; 14];
        let bad = EthernetRepr {
            ethertype: ETHERTYPE_VLAN,
            ..repr()
        };
        assert!(
            bad.emit(&mut EthernetFrame::new_unchecked(&mut bytes[..]))
                .is_err()
        );
        assert_eq!(bytes, [0u8; 14]);
        let tagged = EthernetRepr {
            vlan_tci: Some(1),
            ..repr()
        };
        assert!(matches!(
            tagged.emit(&mut EthernetFrame::new_unchecked(&mut bytes[..])),
            Err(WireError::BufferTooSmall {
                need: 18,
                have: 14,
                ..
            })
        ));
        assert_eq!(bytes, [0u8; 14]);
    }

    #[test]
    fn mac_display_and_padding() {
        assert_eq!(
            Mac([0xaa, 0xbb, 0xcc, 0x0d, 0xee, 0xff]).to_string(),
            "aa:bb:cc:0d:ee:ff"
        );
        // spec-notes §commands: 14 (Ethernet) + 2 (EtherCAT header) + 14 (BRD, 2 data bytes) = 30 → 30 zeros.
        assert_eq!(padding_len(30), 30);
        assert_eq!(padding_len(60), 0);
        assert_eq!(padding_len(1514), 0);
        assert_eq!(padding_len(0), 60);
    }

    pub(crate) fn arb_ethernet() -> impl Strategy<Value = EthernetRepr> {
        (
            any::<[u8; 6]>(),
            any::<[u8; 6]>(),
            proptest::option::of(any::<u16>()),
            any::<u16>().prop_filter("not the VLAN TPID", |t| *t != ETHERTYPE_VLAN),
        )
            .prop_map(|(destination, source, vlan_tci, ethertype)| EthernetRepr {
                destination,
                source,
                vlan_tci,
                ethertype,
            })
    }

    proptest! {
        #[test]
        fn round_trip(header in arb_ethernet(), tail in 0usize..8) {
            let mut bytes = vec![0u8; header.buffer_len() + tail];
            header.emit(&mut EthernetFrame::new_unchecked(&mut bytes[..])).unwrap();
            let frame = EthernetFrame::new_checked(&bytes[..]).unwrap();
            prop_assert_eq!(EthernetRepr::parse(&frame).unwrap(), header);
            prop_assert_eq!(frame.payload().len(), tail);
        }

        #[test]
        fn never_panics(mut bytes in proptest::collection::vec(any::<u8>(), 0..32), tag: bool) {
            // Half the cases announce a VLAN tag so that the tagged path is exercised too.
            if tag && bytes.len() >= HEADER_LEN {
                bytes[fields::ETHERTYPE].copy_from_slice(&ETHERTYPE_VLAN.to_be_bytes());
            }
            if let Ok(frame) = EthernetFrame::new_checked(&bytes[..]) {
                let _ = EthernetRepr::parse(&frame);
                let _ = frame.payload();
            }
        }
    }
}
