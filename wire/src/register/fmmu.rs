//! FMMU register set, 16 bytes per FMMU at 0x0600 + 16·n (ETG.1000.4, spec-notes §esc.fmmu).
//!
//! ```text
//! 0x0 u32 logical start | 0x4 u16 length | 0x6 u8 logical start bit | 0x7 u8 logical stop bit
//! 0x8 u16 physical start | 0xA u8 physical start bit | 0xB u8 type (bit 0 read, bit 1 write)
//! 0xC u8 activate (bit 0) | 0xD 3 bytes reserved
//! ```

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field::{self, Field};

mod fields {
    use super::Field;
    pub const LOGICAL_START: Field = 0..4;
    pub const LENGTH: Field = 4..6;
    pub const LOGICAL_START_BIT: usize = 6;
    pub const LOGICAL_STOP_BIT: usize = 7;
    pub const PHYSICAL_START: Field = 8..10;
    pub const PHYSICAL_START_BIT: usize = 10;
    pub const TYPE: usize = 11;
    pub const ACTIVATE: usize = 12;
    pub const RESERVED: Field = 13..16;
}

/// Size of one FMMU register set.
pub const FMMU_LEN: usize = fields::RESERVED.end;

/// Bits 0-2: the only used bits of the bit-position bytes.
const BIT_MASK: u8 = 0x07;

/// View of one 16-byte FMMU register set.
#[derive(Debug, Clone)]
pub struct Fmmu<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Fmmu<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        Fmmu { buffer }
    }

    /// Wraps a buffer and checks that the 16 bytes are present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let view = Self::new_unchecked(buffer);
        view.check_len()?;
        Ok(view)
    }

    /// Checks that the 16 bytes are present.
    pub fn check_len(&self) -> Result<()> {
        need("FMMU", self.buffer.as_ref(), FMMU_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Logical start address.
    pub fn logical_start(&self) -> u32 {
        field::u32_le(self.buffer.as_ref(), fields::LOGICAL_START.start)
    }

    /// Length of the logical range in bytes.
    pub fn length(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::LENGTH.start)
    }

    /// Logical start bit (0-7).
    pub fn logical_start_bit(&self) -> u8 {
        self.buffer.as_ref()[fields::LOGICAL_START_BIT] & BIT_MASK
    }

    /// Logical stop bit (0-7).
    pub fn logical_stop_bit(&self) -> u8 {
        self.buffer.as_ref()[fields::LOGICAL_STOP_BIT] & BIT_MASK
    }

    /// Physical start address.
    pub fn physical_start(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::PHYSICAL_START.start)
    }

    /// Physical start bit (0-7).
    pub fn physical_start_bit(&self) -> u8 {
        self.buffer.as_ref()[fields::PHYSICAL_START_BIT] & BIT_MASK
    }

    /// Raw type byte.
    pub fn type_raw(&self) -> u8 {
        self.buffer.as_ref()[fields::TYPE]
    }

    /// Raw activate byte.
    pub fn activate_raw(&self) -> u8 {
        self.buffer.as_ref()[fields::ACTIVATE]
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Fmmu<T> {
    /// Sets the logical start address.
    pub fn set_logical_start(&mut self, value: u32) {
        field::set_u32_le(self.buffer.as_mut(), fields::LOGICAL_START.start, value)
    }

    /// Sets the length.
    pub fn set_length(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::LENGTH.start, value)
    }

    /// Sets the logical start and stop bits (raw bytes).
    pub fn set_logical_bits(&mut self, start: u8, stop: u8) {
        let buf = self.buffer.as_mut();
        buf[fields::LOGICAL_START_BIT] = start;
        buf[fields::LOGICAL_STOP_BIT] = stop;
    }

    /// Sets the physical start address.
    pub fn set_physical_start(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::PHYSICAL_START.start, value)
    }

    /// Sets the physical start bit (raw byte).
    pub fn set_physical_start_bit(&mut self, value: u8) {
        self.buffer.as_mut()[fields::PHYSICAL_START_BIT] = value
    }

    /// Sets the raw type byte.
    pub fn set_type_raw(&mut self, value: u8) {
        self.buffer.as_mut()[fields::TYPE] = value
    }

    /// Sets the raw activate byte.
    pub fn set_activate_raw(&mut self, value: u8) {
        self.buffer.as_mut()[fields::ACTIVATE] = value
    }

    /// Clears the three reserved bytes.
    pub fn clear_reserved(&mut self) {
        self.buffer.as_mut()[fields::RESERVED].fill(0)
    }
}

/// A parsed FMMU register set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FmmuRepr {
    /// Logical start address.
    pub logical_start: u32,
    /// Length of the logical range in bytes (counting partial first/last bytes).
    pub length: u16,
    /// Logical start bit, 0..=7.
    pub logical_start_bit: u8,
    /// Logical stop bit, 0..=7 (last bit of the last logical byte).
    pub logical_stop_bit: u8,
    /// Physical (ESC) start address.
    pub physical_start: u16,
    /// Physical start bit, 0..=7.
    pub physical_start_bit: u8,
    /// Type bit 0: read (LRD/LRW copy ESC → frame, i.e. inputs).
    pub read: bool,
    /// Type bit 1: write (LWR/LRW copy frame → ESC, i.e. outputs).
    pub write: bool,
    /// Activate bit 0.
    pub enable: bool,
}

impl FmmuRepr {
    /// An enabled byte-aligned mapping of `length` bytes of outputs (type write).
    pub const fn outputs(logical_start: u32, length: u16, physical_start: u16) -> Self {
        FmmuRepr {
            logical_start,
            length,
            logical_start_bit: 0,
            logical_stop_bit: 7,
            physical_start,
            physical_start_bit: 0,
            read: false,
            write: true,
            enable: true,
        }
    }

    /// An enabled byte-aligned mapping of `length` bytes of inputs (type read).
    pub const fn inputs(logical_start: u32, length: u16, physical_start: u16) -> Self {
        FmmuRepr {
            read: true,
            write: false,
            ..Self::outputs(logical_start, length, physical_start)
        }
    }

    /// Mapped bits: (length − 1) × 8 + (stop − start + 1) (spec-notes §esc.fmmu); 0 for an empty or
    /// contradictory mapping.
    pub fn bit_count(&self) -> u32 {
        (u32::from(self.length) * 8)
            .saturating_sub(u32::from(self.logical_start_bit))
            .saturating_sub(7u32.saturating_sub(u32::from(self.logical_stop_bit)))
    }

    /// Parses a checked view; unused bits of the bit positions, type and activate bytes
    /// and the reserved bytes are ignored.
    pub fn parse<T: AsRef<[u8]>>(view: &Fmmu<T>) -> Result<Self> {
        view.check_len()?;
        Ok(FmmuRepr {
            logical_start: view.logical_start(),
            length: view.length(),
            logical_start_bit: view.logical_start_bit(),
            logical_stop_bit: view.logical_stop_bit(),
            physical_start: view.physical_start(),
            physical_start_bit: view.physical_start_bit(),
            read: view.type_raw() & 0x01 != 0,
            write: view.type_raw() & 0x02 != 0,
            enable: view.activate_raw() & 0x01 != 0,
        })
    }

    /// Bytes written by [`Self::emit`].
    pub const fn buffer_len(&self) -> usize {
        FMMU_LEN
    }

    /// Writes the 16 bytes (reserved bytes 0); refuses bit positions above 7.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, view: &mut Fmmu<T>) -> Result<()> {
        room("FMMU", view.buffer.as_ref(), FMMU_LEN)?;
        if self.logical_start_bit > BIT_MASK
            || self.logical_stop_bit > BIT_MASK
            || self.physical_start_bit > BIT_MASK
        {
            return Err(WireError::Invalid {
                what: "FMMU",
                reason: "bit position above 7",
            });
        }
        view.set_logical_start(self.logical_start);
        view.set_length(self.length);
        view.set_logical_bits(self.logical_start_bit, self.logical_stop_bit);
        view.set_physical_start(self.physical_start);
        view.set_physical_start_bit(self.physical_start_bit);
        view.set_type_raw(u8::from(self.read) | (u8::from(self.write) << 1));
        view.set_activate_raw(u8::from(self.enable));
        view.clear_reserved();
        Ok(())
    }
}

impl fmt::Display for FmmuRepr {
    /// `FMMU log=0x00000000.0 len=2 bits=16 → phys=0x1100.0 write enabled`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = match (self.read, self.write) {
            (true, true) => "read/write",
            (true, false) => "read",
            (false, true) => "write",
            (false, false) => "unused",
        };
        write!(
            f,
            "FMMU log={:#010x}.{} len={} bits={} phys={:#06x}.{} {kind} {}",
            self.logical_start,
            self.logical_start_bit,
            self.length,
            self.bit_count(),
            self.physical_start,
            self.physical_start_bit,
            if self.enable { "enabled" } else { "disabled" }
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    // The worked example (ETG.1000.4, spec-notes §esc.fmmu).
    static C18_FMMU0: [u8; 16] = [
        0x00, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x07, 0x00, 0x11, 0x00, 0x02, 0x01, 0x00, 0x00,
        0x00,
    ];
    static C18_FMMU1: [u8; 16] = [
        0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x07, 0x80, 0x11, 0x00, 0x01, 0x01, 0x00, 0x00,
        0x00,
    ];
    static C18_FMMU2: [u8; 16] = [
        0x03, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x07, 0x0d, 0x08, 0x00, 0x01, 0x01, 0x00, 0x00,
        0x00,
    ];

    fn c18() -> [(FmmuRepr, &'static [u8; 16]); 3] {
        [
            (FmmuRepr::outputs(0, 2, 0x1100), &C18_FMMU0),
            (FmmuRepr::inputs(2, 1, 0x1180), &C18_FMMU1),
            (FmmuRepr::inputs(3, 1, 0x080D), &C18_FMMU2),
        ]
    }

    #[test]
    fn c18_parse_and_emit() {
        for (repr, bytes) in c18() {
            let parsed = FmmuRepr::parse(&Fmmu::new_checked(&bytes[..]).unwrap()).unwrap();
            assert_eq!(parsed, repr);
            let mut buf = [0xa5u8; 16];
            repr.emit(&mut Fmmu::new_unchecked(&mut buf[..])).unwrap();
            assert_eq!(&buf, bytes);
        }
        assert_eq!(c18()[0].0.bit_count(), 16);
        assert_eq!(c18()[1].0.bit_count(), 8);
    }

    #[test]
    fn bit_count_partial_bytes() {
        // One bit: bit 3 of one byte.
        let mut r = FmmuRepr::inputs(0, 1, 0x080D);
        r.logical_start_bit = 3;
        r.logical_stop_bit = 3;
        assert_eq!(r.bit_count(), 1);
        // Bits 6 of byte 0 to 1 of byte 1: 2 + 2 = 4.
        r.length = 2;
        r.logical_start_bit = 6;
        r.logical_stop_bit = 1;
        assert_eq!(r.bit_count(), 4);
        r.length = 0;
        assert_eq!(r.bit_count(), 0);
    }

    #[test]
    fn errors() {
        assert!(Fmmu::new_checked(&C18_FMMU0[..15]).is_err());
        let mut bad = FmmuRepr::outputs(0, 2, 0x1100);
        bad.logical_stop_bit = 8;
        let mut buf = [0xa5u8; 16];
        assert!(bad.emit(&mut Fmmu::new_unchecked(&mut buf[..])).is_err());
        assert_eq!(buf, [0xa5; 16]);
    }

    pub(crate) fn arb_fmmu() -> impl Strategy<Value = FmmuRepr> {
        (
            any::<u32>(),
            any::<u16>(),
            (0u8..8, 0u8..8, 0u8..8),
            any::<u16>(),
            (any::<bool>(), any::<bool>(), any::<bool>()),
        )
            .prop_map(
                |(logical_start, length, (sb, eb, pb), physical_start, (r, w, e))| FmmuRepr {
                    logical_start,
                    length,
                    logical_start_bit: sb,
                    logical_stop_bit: eb,
                    physical_start,
                    physical_start_bit: pb,
                    read: r,
                    write: w,
                    enable: e,
                },
            )
    }

    proptest! {
        #[test]
        fn round_trip(repr in arb_fmmu()) {
            let mut buf = [0u8; FMMU_LEN];
            repr.emit(&mut Fmmu::new_unchecked(&mut buf[..])).unwrap();
            let parsed = FmmuRepr::parse(&Fmmu::new_checked(&buf[..]).unwrap()).unwrap();
            prop_assert_eq!(parsed, repr);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..20)) {
            if let Ok(view) = Fmmu::new_checked(&bytes[..]) {
                let _ = FmmuRepr::parse(&view).map(|r| (r.to_string(), r.bit_count()));
            }
        }
    }
}
