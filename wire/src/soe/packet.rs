//! The SoE message: a view over the mailbox data and its parsed representation.

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field::{self};

use super::{ERROR_CODE_LEN, ElementFlags, HEADER_LEN, Idn, SoeError, SoeOpcode, fields};

/// A read/write view of an SoE message (mailbox data).
#[derive(Debug, Clone)]
pub struct SoePacket<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> SoePacket<T> {
    /// Wraps a buffer without checking it; accessors may panic until [`Self::check_len`] passed.
    pub const fn new_unchecked(buffer: T) -> Self {
        SoePacket { buffer }
    }

    /// Wraps a buffer and checks that the 4-byte header is present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let packet = Self::new_unchecked(buffer);
        packet.check_len()?;
        Ok(packet)
    }

    /// Checks that the header is present, and the error code when the error bit is set.
    pub fn check_len(&self) -> Result<()> {
        let buf = self.buffer.as_ref();
        need("SoE header", buf, HEADER_LEN)?;
        if self.error() {
            need("SoE error code", buf, HEADER_LEN + ERROR_CODE_LEN)?;
        }
        Ok(())
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Opcode (3 bits).
    pub fn opcode(&self) -> SoeOpcode {
        SoeOpcode::from(self.buffer.as_ref()[fields::FLAGS] & fields::OPCODE_MASK)
    }

    /// Incomplete: more fragments follow; bytes 2-3 are fragments-left.
    pub fn incomplete(&self) -> bool {
        self.buffer.as_ref()[fields::FLAGS] & fields::INCOMPLETE != 0
    }

    /// Error: a u16 error code is present.
    pub fn error(&self) -> bool {
        self.buffer.as_ref()[fields::FLAGS] & fields::ERROR != 0
    }

    /// Drive number 0..=7.
    pub fn drive(&self) -> u8 {
        self.buffer.as_ref()[fields::FLAGS] >> fields::DRIVE_SHIFT
    }

    /// Element flags.
    pub fn elements(&self) -> ElementFlags {
        ElementFlags(self.buffer.as_ref()[fields::ELEMENTS])
    }

    /// The raw u16 at bytes 2-3: IDN or fragments-left, depending on [`Self::incomplete`].
    pub fn idn_or_fragments(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::IDN_OR_FRAGMENTS.start)
    }

    /// Everything after the header (element data and, with the error bit, the error code).
    pub fn payload(&self) -> &[u8] {
        &self.buffer.as_ref()[fields::PAYLOAD]
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> SoePacket<T> {
    /// Sets byte 0; values wider than their field are masked (callers check, see emit).
    pub fn set_flags(&mut self, opcode: SoeOpcode, incomplete: bool, error: bool, drive: u8) {
        let mut b = (u8::from(opcode) & fields::OPCODE_MASK) | (drive << fields::DRIVE_SHIFT);
        if incomplete {
            b |= fields::INCOMPLETE;
        }
        if error {
            b |= fields::ERROR;
        }
        self.buffer.as_mut()[fields::FLAGS] = b;
    }

    /// Sets the element flags.
    pub fn set_elements(&mut self, value: ElementFlags) {
        self.buffer.as_mut()[fields::ELEMENTS] = value.0;
    }

    /// Sets bytes 2-3.
    pub fn set_idn_or_fragments(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::IDN_OR_FRAGMENTS.start, value)
    }

    /// Mutable payload.
    pub fn payload_mut(&mut self) -> &mut [u8] {
        &mut self.buffer.as_mut()[fields::PAYLOAD]
    }
}

/// Bytes 2-3 of the SoE header: the IDN, or the fragments still to follow.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum IdnOrFragments {
    /// Incomplete = 0: the IDN.
    Idn(Idn),
    /// Incomplete = 1: number of fragments still to follow.
    FragmentsLeft(u16),
}

/// A parsed SoE message.
///
/// Where the error code sits (spec-notes §soe, IgH): for a read response it is the *last* two
/// bytes (element data, if any, come first); for every other opcode it is right after the
/// header at offset 4 (further bytes, if any, are kept in `data`). Both coincide when no
/// data are present, which is the usual case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SoeRepr<'a> {
    /// Opcode.
    pub opcode: SoeOpcode,
    /// Drive number 0..=7.
    pub drive: u8,
    /// Element flags.
    pub elements: ElementFlags,
    /// IDN (complete message or last fragment) or fragments-left (Incomplete = 1).
    pub idn_or_fragments: IdnOrFragments,
    /// The error code when the error bit is set.
    pub error: Option<SoeError>,
    /// Element data (without the error code).
    pub data: &'a [u8],
}

impl<'a> SoeRepr<'a> {
    /// Parses a checked SoE view. Unknown opcodes (0, 7) are kept as data: the header
    /// layout does not depend on the opcode.
    pub fn parse<T: AsRef<[u8]> + ?Sized>(packet: &SoePacket<&'a T>) -> Result<Self> {
        packet.check_len()?;
        // Copy the `&'a T` out of the view so the payload borrows the buffer, not the view.
        let buf: &'a [u8] = AsRef::<[u8]>::as_ref(packet.buffer);
        let payload = &buf[fields::PAYLOAD];
        let opcode = packet.opcode();
        let (error, data) = if packet.error() {
            // check_len guaranteed at least ERROR_CODE_LEN payload bytes.
            if opcode == SoeOpcode::ReadResponse {
                let (data, code) = payload.split_at(payload.len() - ERROR_CODE_LEN);
                (Some(SoeError::from(field::u16_le(code, 0))), data)
            } else {
                let (code, data) = payload.split_at(ERROR_CODE_LEN);
                (Some(SoeError::from(field::u16_le(code, 0))), data)
            }
        } else {
            (None, payload)
        };
        let raw = packet.idn_or_fragments();
        Ok(SoeRepr {
            opcode,
            drive: packet.drive(),
            elements: packet.elements(),
            idn_or_fragments: if packet.incomplete() {
                IdnOrFragments::FragmentsLeft(raw)
            } else {
                IdnOrFragments::Idn(Idn::from(raw))
            },
            error,
            data,
        })
    }

    /// Bytes needed on the wire.
    pub fn buffer_len(&self) -> usize {
        HEADER_LEN
            + self.data.len()
            + if self.error.is_some() {
                ERROR_CODE_LEN
            } else {
                0
            }
    }

    /// Writes the message into the start of `packet`'s buffer; refuses a drive above 7 or an
    /// opcode above 7.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, packet: &mut SoePacket<T>) -> Result<()> {
        room("SoE message", packet.buffer.as_ref(), self.buffer_len())?;
        if self.drive > 7 || u8::from(self.opcode) > fields::OPCODE_MASK {
            return Err(WireError::Invalid {
                what: "SoE header",
                reason: "drive number or opcode above 7",
            });
        }
        let (incomplete, raw) = match self.idn_or_fragments {
            IdnOrFragments::Idn(idn) => (false, u16::from(idn)),
            IdnOrFragments::FragmentsLeft(n) => (true, n),
        };
        packet.set_flags(self.opcode, incomplete, self.error.is_some(), self.drive);
        packet.set_elements(self.elements);
        packet.set_idn_or_fragments(raw);
        let n = self.data.len();
        let payload = packet.payload_mut();
        match self.error {
            None => payload[..n].copy_from_slice(self.data),
            Some(code) if self.opcode == SoeOpcode::ReadResponse => {
                payload[..n].copy_from_slice(self.data);
                field::set_u16_le(payload, n, u16::from(code));
            }
            Some(code) => {
                field::set_u16_le(payload, 0, u16::from(code));
                payload[ERROR_CODE_LEN..ERROR_CODE_LEN + n].copy_from_slice(self.data);
            }
        }
        Ok(())
    }
}

impl fmt::Display for SoeRepr<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("SoE ")?;
        f.write_str(self.opcode.name())?;
        if let SoeOpcode::Unknown(raw) = self.opcode {
            write!(f, " {raw}")?;
        }
        match self.idn_or_fragments {
            IdnOrFragments::Idn(idn) => write!(f, " {idn}")?,
            IdnOrFragments::FragmentsLeft(n) => write!(f, " fragments-left={n}")?,
        }
        write!(f, " drive {} elements={}", self.drive, self.elements)?;
        if let Some(code) = self.error {
            write!(f, " error {:#06x} {}", u16::from(code), code.description())?;
        }
        if !self.data.is_empty() {
            write!(f, " ({} bytes)", self.data.len())?;
        }
        Ok(())
    }
}
