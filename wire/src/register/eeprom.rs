//! SII (EEPROM) interface 0x0500–0x050F (ETG.1000.4, spec-notes §esc.sii-if).
//!
//! ```text
//! 0x0502 u16 control/status: bit 0 write enable, 5 emulation, 6 8-byte reads, 7 2 address
//!            bytes, 8-10 command, 11 checksum error, 12 load error, 13 ack error,
//!            14 write-enable error, 15 busy
//! 0x0504 u32 word address
//! 0x0508 ..  data
//! ```
//! A master starts a command by writing control and address together: 6 bytes at 0x0502.

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field::{self, Field};
use crate::macros::enum_with_unknown;

mod fields {
    use super::Field;
    pub const CONTROL: Field = 0..2;
    pub const ADDRESS: Field = 2..6;
}

mod bits {
    pub const WRITE_ENABLE: u16 = 1 << 0;
    pub const EMULATION: u16 = 1 << 5;
    pub const READ_8_BYTES: u16 = 1 << 6;
    pub const TWO_ADDRESS_BYTES: u16 = 1 << 7;
    pub const COMMAND_SHIFT: u16 = 8;
    pub const COMMAND_MASK: u16 = 0x7;
    pub const CHECKSUM_ERROR: u16 = 1 << 11;
    pub const LOAD_ERROR: u16 = 1 << 12;
    pub const ACK_ERROR: u16 = 1 << 13;
    pub const WRITE_ENABLE_ERROR: u16 = 1 << 14;
    pub const BUSY: u16 = 1 << 15;
}

/// Bits 11-14: any error (SOEM's mask 0x7800).
pub const ERROR_MASK: u16 = 0x7800;

/// EEPROM configuration 0x0500 value that gives the EEPROM to the master (ECAT).
pub const CONFIG_ECAT_ACCESS: u8 = 0x00;
/// EEPROM configuration 0x0500 value that forces ECAT access (take it away from the PDI).
pub const CONFIG_FORCE_ECAT: u8 = 0x02;

enum_with_unknown! {
    /// EEPROM command, bits 8-10 of 0x0502.
    pub enum EepromCommand(u8) {
        /// 000: no operation / clear error bits.
        Nop = 0,
        /// 001: read.
        Read = 1,
        /// 010: write.
        Write = 2,
        /// 100: reload the ESC configuration from the EEPROM.
        Reload = 4,
    }
}

impl EepromCommand {
    /// Upper-case name.
    pub fn name(self) -> &'static str {
        match self {
            EepromCommand::Nop => "NOP",
            EepromCommand::Read => "READ",
            EepromCommand::Write => "WRITE",
            EepromCommand::Reload => "RELOAD",
            EepromCommand::Unknown(_) => "unknown",
        }
    }
}

/// EEPROM control/status register 0x0502 (u16). Reserved bits 1-4 are dropped on decode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct EepromControl {
    /// Bit 0: ECAT write enable (must accompany a write command).
    pub write_enable: bool,
    /// Bit 5: the PDI emulates the EEPROM.
    pub emulation: bool,
    /// Bit 6: reads return 8 bytes (else 4).
    pub read_8_bytes: bool,
    /// Bit 7: 2 address bytes (else 1).
    pub two_address_bytes: bool,
    /// Bits 8-10: command.
    pub command: EepromCommand,
    /// Bit 11: checksum error in the ESC configuration area.
    pub checksum_error: bool,
    /// Bit 12: EEPROM not loaded / device info error.
    pub load_error: bool,
    /// Bit 13: missing acknowledge or invalid command (retry).
    pub ack_error: bool,
    /// Bit 14: write command without write enable.
    pub write_enable_error: bool,
    /// Bit 15: operation in progress.
    pub busy: bool,
}

impl EepromControl {
    /// Size of the register.
    pub const LEN: usize = 2;

    /// A control word carrying only `command` (write enable set for a write, spec-notes §esc.sii-if).
    pub const fn command(command: EepromCommand) -> Self {
        EepromControl {
            write_enable: matches!(command, EepromCommand::Write),
            emulation: false,
            read_8_bytes: false,
            two_address_bytes: false,
            command,
            checksum_error: false,
            load_error: false,
            ack_error: false,
            write_enable_error: false,
            busy: false,
        }
    }

    /// Decodes a register value.
    pub fn decode(raw: u16) -> Self {
        EepromControl {
            write_enable: raw & bits::WRITE_ENABLE != 0,
            emulation: raw & bits::EMULATION != 0,
            read_8_bytes: raw & bits::READ_8_BYTES != 0,
            two_address_bytes: raw & bits::TWO_ADDRESS_BYTES != 0,
            command: EepromCommand::from(((raw >> bits::COMMAND_SHIFT) & bits::COMMAND_MASK) as u8),
            checksum_error: raw & bits::CHECKSUM_ERROR != 0,
            load_error: raw & bits::LOAD_ERROR != 0,
            ack_error: raw & bits::ACK_ERROR != 0,
            write_enable_error: raw & bits::WRITE_ENABLE_ERROR != 0,
            busy: raw & bits::BUSY != 0,
        }
    }

    /// Encodes the register value; refuses a command wider than 3 bits.
    pub fn encode(&self) -> Result<u16> {
        let command = u16::from(u8::from(self.command));
        if command > bits::COMMAND_MASK {
            return Err(WireError::Invalid {
                what: "EEPROM control",
                reason: "command does not fit in 3 bits",
            });
        }
        let mut raw = command << bits::COMMAND_SHIFT;
        for (set, bit) in [
            (self.write_enable, bits::WRITE_ENABLE),
            (self.emulation, bits::EMULATION),
            (self.read_8_bytes, bits::READ_8_BYTES),
            (self.two_address_bytes, bits::TWO_ADDRESS_BYTES),
            (self.checksum_error, bits::CHECKSUM_ERROR),
            (self.load_error, bits::LOAD_ERROR),
            (self.ack_error, bits::ACK_ERROR),
            (self.write_enable_error, bits::WRITE_ENABLE_ERROR),
            (self.busy, bits::BUSY),
        ] {
            if set {
                raw |= bit;
            }
        }
        Ok(raw)
    }

    /// Whether any of the error bits 11-14 is set.
    pub fn has_error(&self) -> bool {
        self.checksum_error || self.load_error || self.ack_error || self.write_enable_error
    }

    /// Bytes one read command returns at 0x0508: 8 if bit 6 is set, else 4.
    pub fn read_size(&self) -> usize {
        if self.read_8_bytes { 8 } else { 4 }
    }

    /// Parses the register from the first 2 bytes of `buf`.
    pub fn parse(buf: &[u8]) -> Result<Self> {
        need("EEPROM control", buf, Self::LEN)?;
        Ok(Self::decode(field::u16_le(buf, 0)))
    }

    /// Writes the register into the first 2 bytes of `buf`.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        room("EEPROM control", buf, Self::LEN)?;
        let raw = self.encode()?;
        field::set_u16_le(buf, 0, raw);
        Ok(())
    }
}

impl fmt::Display for EepromControl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "EEPROM {}", self.command.name())?;
        for (set, name) in [
            (self.busy, "busy"),
            (self.write_enable, "write enable"),
            (self.checksum_error, "checksum error"),
            (self.load_error, "load error"),
            (self.ack_error, "ack error"),
            (self.write_enable_error, "write enable error"),
        ] {
            if set {
                write!(f, ", {name}")?;
            }
        }
        Ok(())
    }
}

/// Size of the command request written at 0x0502.
pub const REQUEST_LEN: usize = fields::ADDRESS.end;

/// View of the 6-byte EEPROM request at 0x0502: control (u16) + word address (u32).
#[derive(Debug, Clone)]
pub struct EepromRequest<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> EepromRequest<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        EepromRequest { buffer }
    }

    /// Wraps a buffer and checks that all 6 bytes are present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let view = Self::new_unchecked(buffer);
        view.check_len()?;
        Ok(view)
    }

    /// Checks that the 6 bytes are present.
    pub fn check_len(&self) -> Result<()> {
        need("EEPROM request", self.buffer.as_ref(), REQUEST_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Raw control/status word.
    pub fn control_raw(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::CONTROL.start)
    }

    /// Decoded control/status word.
    pub fn control(&self) -> EepromControl {
        EepromControl::decode(self.control_raw())
    }

    /// Word address.
    pub fn address(&self) -> u32 {
        field::u32_le(self.buffer.as_ref(), fields::ADDRESS.start)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> EepromRequest<T> {
    /// Sets the raw control word.
    pub fn set_control_raw(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::CONTROL.start, value)
    }

    /// Sets the word address.
    pub fn set_address(&mut self, value: u32) {
        field::set_u32_le(self.buffer.as_mut(), fields::ADDRESS.start, value)
    }
}

/// A parsed EEPROM request (or the control/address registers read back).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct EepromRequestRepr {
    /// Control/status word.
    pub control: EepromControl,
    /// Word address.
    pub address: u32,
}

impl EepromRequestRepr {
    /// Read command for `word` (bytes `00 01 ww ww 00 00`).
    pub const fn read(word: u16) -> Self {
        EepromRequestRepr {
            control: EepromControl::command(EepromCommand::Read),
            address: word as u32,
        }
    }

    /// Write command (with write enable) for `word` (bytes `01 02 ww ww 00 00`).
    pub const fn write(word: u16) -> Self {
        EepromRequestRepr {
            control: EepromControl::command(EepromCommand::Write),
            address: word as u32,
        }
    }

    /// Parses a checked view.
    pub fn parse<T: AsRef<[u8]>>(view: &EepromRequest<T>) -> Result<Self> {
        view.check_len()?;
        Ok(EepromRequestRepr {
            control: view.control(),
            address: view.address(),
        })
    }

    /// Bytes written by [`Self::emit`].
    pub const fn buffer_len(&self) -> usize {
        REQUEST_LEN
    }

    /// Writes the 6 bytes.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, view: &mut EepromRequest<T>) -> Result<()> {
        room("EEPROM request", view.buffer.as_ref(), REQUEST_LEN)?;
        let control = self.control.encode()?;
        view.set_control_raw(control);
        view.set_address(self.address);
        Ok(())
    }
}

impl fmt::Display for EepromRequestRepr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} word {:#06x}", self.control, self.address)
    }
}

/// The little-endian words of an EEPROM data read at 0x0508 (4 or 8 bytes → 2 or 4 words,
/// starting at the requested word address); a trailing odd byte is ignored.
pub fn data_words(data: &[u8]) -> impl Iterator<Item = u16> + '_ {
    data.chunks_exact(2)
        .map(|w| u16::from_le_bytes([w[0], w[1]]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    // ETG.1000.4, spec-notes §esc.sii-if: SII read of word 0x0008.
    static C3_READ: [u8; 6] = [0x00, 0x01, 0x08, 0x00, 0x00, 0x00];

    #[test]
    fn c3_read_request() {
        let mut buf = [0xa5u8; 6];
        EepromRequestRepr::read(0x0008)
            .emit(&mut EepromRequest::new_unchecked(&mut buf[..]))
            .unwrap();
        assert_eq!(buf, C3_READ);
        let parsed =
            EepromRequestRepr::parse(&EepromRequest::new_checked(&C3_READ[..]).unwrap()).unwrap();
        assert_eq!(parsed, EepromRequestRepr::read(8));
        assert_eq!(parsed.control.command, EepromCommand::Read);
    }

    #[test]
    fn c3_data_read() {
        // spec-notes §esc.sii-if: 8 bytes from word 8 of an EL2004 = vendor 2, product 0x07D43052.
        let data = [0x02, 0x00, 0x00, 0x00, 0x52, 0x30, 0xd4, 0x07];
        let words: Vec<u16> = data_words(&data).collect();
        assert_eq!(words, [0x0002, 0x0000, 0x3052, 0x07D4]);
    }

    #[test]
    fn write_request_is_0x0201() {
        // ETG.1000.4, spec-notes §esc.sii-if: control = 0x0201 (write enable + write command).
        let mut buf = [0xa5u8; 6];
        EepromRequestRepr::write(0x0004)
            .emit(&mut EepromRequest::new_unchecked(&mut buf[..]))
            .unwrap();
        assert_eq!(buf, [0x01, 0x02, 0x04, 0x00, 0x00, 0x00]);
    }

    #[test]
    fn status_bits() {
        // Busy + 8-byte reads + NACK: 0x8000 | 0x0040 | 0x2000.
        let s = EepromControl::decode(0xA040);
        assert!(s.busy && s.read_8_bytes && s.ack_error && s.has_error());
        assert_eq!(s.read_size(), 8);
        assert!(!EepromControl::decode(0x8000).has_error());
        for bit in 11..15 {
            assert!(EepromControl::decode(1 << bit).has_error());
            assert_eq!((1u16 << bit) & ERROR_MASK, 1 << bit);
        }
        assert_eq!(EepromControl::decode(0x0400).command, EepromCommand::Reload);
    }

    #[test]
    fn errors() {
        assert!(EepromRequest::new_checked(&C3_READ[..5]).is_err());
        assert!(EepromControl::parse(&[0]).is_err());
        let bad = EepromRequestRepr {
            control: EepromControl::command(EepromCommand::Unknown(8)),
            address: 0,
        };
        let mut buf = [0xa5u8; 6];
        assert!(
            bad.emit(&mut EepromRequest::new_unchecked(&mut buf[..]))
                .is_err()
        );
        assert_eq!(buf, [0xa5; 6]);
    }

    proptest! {
        #[test]
        fn round_trip(raw in any::<u16>(), address in any::<u32>()) {
            // Bits 1-4 are reserved and dropped.
            let raw = raw & !0x001E;
            let repr = EepromRequestRepr { control: EepromControl::decode(raw), address };
            let mut buf = [0u8; REQUEST_LEN];
            repr.emit(&mut EepromRequest::new_unchecked(&mut buf[..])).unwrap();
            prop_assert_eq!(field::u16_le(&buf, 0), raw);
            let parsed = EepromRequestRepr::parse(&EepromRequest::new_checked(&buf[..]).unwrap()).unwrap();
            prop_assert_eq!(parsed, repr);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..8)) {
            let _ = EepromControl::parse(&bytes).map(|c| c.to_string());
            if let Ok(view) = EepromRequest::new_checked(&bytes[..]) {
                let _ = EepromRequestRepr::parse(&view).map(|r| r.to_string());
            }
        }
    }
}
