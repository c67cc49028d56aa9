//! VoE — vendor specific over EtherCAT (mailbox type 0xF, ETG.1000.4, spec-notes §voe).
//!
//! ```text
//! offset 0  u32  vendor id    EtherCAT vendor id of the protocol owner (as in 0x1018:01)
//! offset 4  u16  vendor type  vendor-defined message type
//! offset 6  ...  vendor data
//! ```
//!
//! The view covers the mailbox *data* (after the 6-byte mailbox header). The semantics are
//! the vendor's: the master and the gateway only move these bytes.

use core::fmt;

use crate::error::{Result, need, room};
use crate::field::{self, Field, Rest};

mod fields {
    use super::{Field, Rest};
    pub const VENDOR_ID: Field = 0..4;
    pub const VENDOR_TYPE: Field = 4..6;
    pub const DATA: Rest = 6..;
}

/// Size of the VoE header in bytes.
pub const HEADER_LEN: usize = fields::DATA.start;

/// A read/write view of a VoE message (mailbox data).
#[derive(Debug, Clone)]
pub struct VoePacket<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> VoePacket<T> {
    /// Wraps a buffer without checking it; accessors may panic until [`Self::check_len`] passed.
    pub const fn new_unchecked(buffer: T) -> Self {
        VoePacket { buffer }
    }

    /// Wraps a buffer and checks that the 6-byte header is present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let packet = Self::new_unchecked(buffer);
        packet.check_len()?;
        Ok(packet)
    }

    /// Checks that the header is present (the data have no declared length of their own:
    /// they are the rest of the mailbox data).
    pub fn check_len(&self) -> Result<()> {
        need("VoE header", self.buffer.as_ref(), HEADER_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Vendor id of the protocol owner.
    pub fn vendor_id(&self) -> u32 {
        field::u32_le(self.buffer.as_ref(), fields::VENDOR_ID.start)
    }

    /// Vendor-defined message type.
    pub fn vendor_type(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::VENDOR_TYPE.start)
    }

    /// The vendor data: everything after the header.
    pub fn data(&self) -> &[u8] {
        &self.buffer.as_ref()[fields::DATA]
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> VoePacket<T> {
    /// Sets the vendor id.
    pub fn set_vendor_id(&mut self, value: u32) {
        field::set_u32_le(self.buffer.as_mut(), fields::VENDOR_ID.start, value)
    }

    /// Sets the vendor type.
    pub fn set_vendor_type(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::VENDOR_TYPE.start, value)
    }

    /// Mutable vendor data (everything after the header).
    pub fn data_mut(&mut self) -> &mut [u8] {
        &mut self.buffer.as_mut()[fields::DATA]
    }
}

/// A parsed VoE message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct VoeRepr<'a> {
    /// Vendor id of the protocol owner.
    pub vendor_id: u32,
    /// Vendor-defined message type.
    pub vendor_type: u16,
    /// Vendor data.
    pub data: &'a [u8],
}

impl<'a> VoeRepr<'a> {
    /// Parses a checked VoE view.
    pub fn parse<T: AsRef<[u8]> + ?Sized>(packet: &VoePacket<&'a T>) -> Result<Self> {
        packet.check_len()?;
        // Copy the `&'a T` out of the view so the payload borrows the buffer, not the view.
        let buf: &'a [u8] = AsRef::<[u8]>::as_ref(packet.buffer);
        Ok(VoeRepr {
            vendor_id: packet.vendor_id(),
            vendor_type: packet.vendor_type(),
            data: &buf[fields::DATA],
        })
    }

    /// Bytes needed on the wire (header + data).
    pub fn buffer_len(&self) -> usize {
        HEADER_LEN + self.data.len()
    }

    /// Writes header and data into the start of `packet`'s buffer.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, packet: &mut VoePacket<T>) -> Result<()> {
        room("VoE message", packet.buffer.as_ref(), self.buffer_len())?;
        packet.set_vendor_id(self.vendor_id);
        packet.set_vendor_type(self.vendor_type);
        packet.data_mut()[..self.data.len()].copy_from_slice(self.data);
        Ok(())
    }
}

impl fmt::Display for VoeRepr<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "VoE vendor={:#010x} type={:#06x} ({} bytes)",
            self.vendor_id,
            self.vendor_type,
            self.data.len()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Emit;
    use crate::WireError;
    use proptest::prelude::*;

    // Worked out from spec-notes §voe: vendor 0x00001164 (LE), type 0x0001 (LE), 2 data bytes.
    static BYTES: [u8; 8] = [0x64, 0x11, 0x00, 0x00, 0x01, 0x00, 0x01, 0x02];

    #[test]
    fn parse_and_emit_by_hand() {
        let packet = VoePacket::new_checked(&BYTES[..]).unwrap();
        let repr = VoeRepr::parse(&packet).unwrap();
        assert_eq!(repr.vendor_id, 0x1164);
        assert_eq!(repr.vendor_type, 1);
        assert_eq!(repr.data, &[1, 2]);
        let mut out = [0xa5u8; 8];
        repr.emit(&mut VoePacket::new_unchecked(&mut out[..]))
            .unwrap();
        assert_eq!(out, BYTES);
        assert_eq!(
            repr.to_string(),
            "VoE vendor=0x00001164 type=0x0001 (2 bytes)"
        );
    }

    #[test]
    fn truncated_and_small_buffer() {
        assert!(matches!(
            VoePacket::new_checked(&BYTES[..5]),
            Err(WireError::Truncated {
                need: 6,
                have: 5,
                ..
            })
        ));
        let repr = VoeRepr {
            vendor_id: 1,
            vendor_type: 2,
            data: &[1, 2, 3],
        };
        let mut out = [0u8; 8];
        assert!(matches!(
            repr.emit(&mut VoePacket::new_unchecked(&mut out[..])),
            Err(WireError::BufferTooSmall { need: 9, .. })
        ));
        assert_eq!(out, [0u8; 8], "a refused emit writes nothing");
    }

    proptest! {
        #[test]
        fn round_trip(vendor_id in any::<u32>(), vendor_type in any::<u16>(),
                      data in proptest::collection::vec(any::<u8>(), 0..64)) {
            let repr = VoeRepr { vendor_id, vendor_type, data: &data };
            let buf = repr.to_vec().unwrap();
            let packet = VoePacket::new_checked(&buf[..]).unwrap();
            prop_assert_eq!(VoeRepr::parse(&packet).unwrap(), repr);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..32)) {
            if let Ok(packet) = VoePacket::new_checked(&bytes[..]) {
                let _ = VoeRepr::parse(&packet);
            }
        }
    }
}
