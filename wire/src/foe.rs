//! FoE — file access over EtherCAT (mailbox type 4, ETG.1000.6, spec-notes §foe).
//!
//! ```text
//! offset 0  u8   opcode     1 RRQ, 2 WRQ, 3 DATA, 4 ACK, 5 ERROR, 6 BUSY
//! offset 1  u8   reserved   0
//! offset 2  u32  password (RRQ/WRQ) | packet number (DATA/ACK) | error code (ERROR)
//!                | done u16 + entire u16 (BUSY)
//! offset 6  ...  file name (RRQ/WRQ) | file data (DATA) | error text (ERROR) | busy text (BUSY)
//! ```
//!
//! The view covers the mailbox *data* (after the 6-byte mailbox header). The packet number and
//! error code are u32 as in SOEM, SOES and IgH (Wireshark and KickCAT use u16 + 2 reserved
//! bytes; for packet numbers below 65536 the bytes are identical — ETG.1000.6, spec-notes §foe).

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field::{self, Field, Rest};
use crate::macros::enum_with_unknown;

mod fields {
    use super::{Field, Rest};
    pub const OPCODE: usize = 0;
    pub const RESERVED: usize = 1;
    pub const PARAM: Field = 2..6;
    pub const BUSY_DONE: Field = 2..4;
    pub const BUSY_ENTIRE: Field = 4..6;
    pub const PAYLOAD: Rest = 6..;
}

/// Size of the FoE header in bytes.
pub const HEADER_LEN: usize = fields::PAYLOAD.start;

/// Maximum file data per DATA packet for a receiver mailbox of `mailbox_size` bytes:
/// `M − 12` (6 mailbox header + 6 FoE header, spec-notes §foe). 0 if the mailbox is too small.
pub const fn max_data(mailbox_size: usize) -> usize {
    mailbox_size.saturating_sub(crate::mailbox::HEADER_LEN + HEADER_LEN)
}

enum_with_unknown! {
    /// FoE opcode (ETG.1000.6, spec-notes §foe).
    pub enum FoeOpcode(u8) {
        /// Read request (upload slave → master).
        ReadRequest = 1,
        /// Write request (download master → slave).
        WriteRequest = 2,
        /// A packet of file data.
        Data = 3,
        /// Acknowledge of a packet (0 = ready for packet 1).
        Ack = 4,
        /// Error; aborts the transfer.
        Error = 5,
        /// Busy: not ready, repeat the last packet later.
        Busy = 6,
    }
}

impl FoeOpcode {
    /// Short name as in TFTP / Wireshark.
    pub fn name(self) -> &'static str {
        match self {
            FoeOpcode::ReadRequest => "RRQ",
            FoeOpcode::WriteRequest => "WRQ",
            FoeOpcode::Data => "DATA",
            FoeOpcode::Ack => "ACK",
            FoeOpcode::Error => "ERROR",
            FoeOpcode::Busy => "BUSY",
            FoeOpcode::Unknown(_) => "unknown",
        }
    }
}

enum_with_unknown! {
    /// FoE error code (spec-notes §foe; the 0x8000-based numbering of SOEM/SOES/KickCAT).
    pub enum FoeError(u32) {
        /// Not defined (see the error text).
        NotDefined = 0x8000,
        /// File not found.
        NotFound = 0x8001,
        /// Access denied.
        AccessDenied = 0x8002,
        /// Disk full.
        DiskFull = 0x8003,
        /// Illegal operation (not allowed in this state / unexpected opcode).
        Illegal = 0x8004,
        /// Wrong packet number.
        PacketNumberWrong = 0x8005,
        /// File already exists.
        AlreadyExists = 0x8006,
        /// No user.
        NoUser = 0x8007,
        /// Only allowed in BOOT.
        BootstrapOnly = 0x8008,
        /// Not allowed in BOOT.
        NotBootstrap = 0x8009,
        /// No rights (wrong password).
        NoRights = 0x800A,
        /// Program error.
        ProgramError = 0x800B,
        /// Checksum error (SOES only).
        ChecksumError = 0x800C,
    }
}

impl FoeError {
    /// The text of the error code (ETG.1000.6, spec-notes §foe).
    pub fn description(self) -> &'static str {
        match self {
            FoeError::NotDefined => "Not defined",
            FoeError::NotFound => "Not found",
            FoeError::AccessDenied => "Access denied",
            FoeError::DiskFull => "Disk full",
            FoeError::Illegal => "Illegal",
            FoeError::PacketNumberWrong => "Packet number wrong",
            FoeError::AlreadyExists => "Already exists",
            FoeError::NoUser => "No user",
            FoeError::BootstrapOnly => "Bootstrap only",
            FoeError::NotBootstrap => "Not bootstrap",
            FoeError::NoRights => "No rights",
            FoeError::ProgramError => "Program error",
            FoeError::ChecksumError => "Checksum error",
            FoeError::Unknown(_) => "Unknown error",
        }
    }
}

/// A read/write view of an FoE message (mailbox data).
#[derive(Debug, Clone)]
pub struct FoePacket<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> FoePacket<T> {
    /// Wraps a buffer without checking it; accessors may panic until [`Self::check_len`] passed.
    pub const fn new_unchecked(buffer: T) -> Self {
        FoePacket { buffer }
    }

    /// Wraps a buffer and checks that the 6-byte header is present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let packet = Self::new_unchecked(buffer);
        packet.check_len()?;
        Ok(packet)
    }

    /// Checks that the header is present; the payload is the rest of the mailbox data.
    pub fn check_len(&self) -> Result<()> {
        need("FoE header", self.buffer.as_ref(), HEADER_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Opcode.
    pub fn opcode(&self) -> FoeOpcode {
        FoeOpcode::from(self.buffer.as_ref()[fields::OPCODE])
    }

    /// The reserved byte 1 (sent as 0).
    pub fn reserved(&self) -> u8 {
        self.buffer.as_ref()[fields::RESERVED]
    }

    /// The u32 at offset 2: password, packet number or error code, depending on the opcode.
    pub fn param(&self) -> u32 {
        field::u32_le(self.buffer.as_ref(), fields::PARAM.start)
    }

    /// BUSY: the progress done so far (u16 at offset 2).
    pub fn busy_done(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::BUSY_DONE.start)
    }

    /// BUSY: the total of the progress (u16 at offset 4).
    pub fn busy_entire(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::BUSY_ENTIRE.start)
    }

    /// Everything after the header: file name, data or text.
    pub fn payload(&self) -> &[u8] {
        &self.buffer.as_ref()[fields::PAYLOAD]
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> FoePacket<T> {
    /// Sets the opcode and clears the reserved byte.
    pub fn set_opcode(&mut self, value: FoeOpcode) {
        let buf = self.buffer.as_mut();
        buf[fields::OPCODE] = u8::from(value);
        buf[fields::RESERVED] = 0;
    }

    /// Sets the u32 at offset 2.
    pub fn set_param(&mut self, value: u32) {
        field::set_u32_le(self.buffer.as_mut(), fields::PARAM.start, value)
    }

    /// Sets the BUSY progress fields.
    pub fn set_busy(&mut self, done: u16, entire: u16) {
        let buf = self.buffer.as_mut();
        field::set_u16_le(buf, fields::BUSY_DONE.start, done);
        field::set_u16_le(buf, fields::BUSY_ENTIRE.start, entire);
    }

    /// Mutable payload (everything after the header).
    pub fn payload_mut(&mut self) -> &mut [u8] {
        &mut self.buffer.as_mut()[fields::PAYLOAD]
    }
}

/// A parsed FoE message.
///
/// File names and texts are ASCII without a terminating NUL (spec-notes §foe). On parse, trailing
/// NUL bytes are trimmed: some implementations (and a gateway's sample client) send a C string,
/// and a NUL can never be part of a file name. Because parse would lose them, emit refuses a
/// name or text that ends in NUL.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FoeRepr<'a> {
    /// RRQ: read the named file from the slave.
    ReadRequest {
        /// Password, 0 = none.
        password: u32,
        /// File name (ASCII).
        file_name: &'a [u8],
    },
    /// WRQ: write the named file to the slave.
    WriteRequest {
        /// Password, 0 = none.
        password: u32,
        /// File name (ASCII).
        file_name: &'a [u8],
    },
    /// DATA: one packet of the file; a packet shorter than `max_data` is the last.
    Data {
        /// Packet number, from 1.
        packet: u32,
        /// File data.
        data: &'a [u8],
    },
    /// ACK of a packet (0 = ready for packet 1 after a WRQ).
    Ack {
        /// The packet acknowledged.
        packet: u32,
    },
    /// ERROR: aborts the transfer.
    Error {
        /// Error code.
        code: FoeError,
        /// Optional error text (ASCII).
        text: &'a [u8],
    },
    /// BUSY: the receiver is not ready; progress `done` of `entire`.
    Busy {
        /// Progress done.
        done: u16,
        /// Progress total.
        entire: u16,
        /// Optional text (ASCII).
        text: &'a [u8],
    },
}

/// Trims trailing NUL bytes (see [`FoeRepr`]).
fn trim_nul(bytes: &[u8]) -> &[u8] {
    let end = bytes.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
    &bytes[..end]
}

impl<'a> FoeRepr<'a> {
    /// Parses a checked FoE view. An unknown opcode is [`WireError::UnknownType`] since its
    /// layout is unknown. The reserved byte is ignored, like the mailbox header's reserved bit.
    pub fn parse<T: AsRef<[u8]> + ?Sized>(packet: &FoePacket<&'a T>) -> Result<Self> {
        packet.check_len()?;
        // Copy the `&'a T` out of the view so the payload borrows the buffer, not the view.
        let buf: &'a [u8] = AsRef::<[u8]>::as_ref(packet.buffer);
        let payload = &buf[fields::PAYLOAD];
        let param = packet.param();
        Ok(match packet.opcode() {
            FoeOpcode::ReadRequest => FoeRepr::ReadRequest {
                password: param,
                file_name: trim_nul(payload),
            },
            FoeOpcode::WriteRequest => FoeRepr::WriteRequest {
                password: param,
                file_name: trim_nul(payload),
            },
            FoeOpcode::Data => FoeRepr::Data {
                packet: param,
                data: payload,
            },
            // An ACK has no payload; padding after it is ignored.
            FoeOpcode::Ack => FoeRepr::Ack { packet: param },
            FoeOpcode::Error => FoeRepr::Error {
                code: FoeError::from(param),
                text: trim_nul(payload),
            },
            FoeOpcode::Busy => FoeRepr::Busy {
                done: packet.busy_done(),
                entire: packet.busy_entire(),
                text: trim_nul(payload),
            },
            FoeOpcode::Unknown(raw) => {
                return Err(WireError::UnknownType {
                    what: "FoE opcode",
                    value: u32::from(raw),
                });
            }
        })
    }

    /// The opcode of this message.
    pub fn opcode(&self) -> FoeOpcode {
        match self {
            FoeRepr::ReadRequest { .. } => FoeOpcode::ReadRequest,
            FoeRepr::WriteRequest { .. } => FoeOpcode::WriteRequest,
            FoeRepr::Data { .. } => FoeOpcode::Data,
            FoeRepr::Ack { .. } => FoeOpcode::Ack,
            FoeRepr::Error { .. } => FoeOpcode::Error,
            FoeRepr::Busy { .. } => FoeOpcode::Busy,
        }
    }

    fn payload(&self) -> &'a [u8] {
        match *self {
            FoeRepr::ReadRequest { file_name, .. } | FoeRepr::WriteRequest { file_name, .. } => {
                file_name
            }
            FoeRepr::Data { data, .. } => data,
            FoeRepr::Ack { .. } => &[],
            FoeRepr::Error { text, .. } | FoeRepr::Busy { text, .. } => text,
        }
    }

    /// Bytes needed on the wire (header + payload).
    pub fn buffer_len(&self) -> usize {
        HEADER_LEN + self.payload().len()
    }

    /// Writes the message into the start of `packet`'s buffer.
    ///
    /// Refuses (writing nothing) a file name or text ending in NUL, which parse could not
    /// give back.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, packet: &mut FoePacket<T>) -> Result<()> {
        room("FoE message", packet.buffer.as_ref(), self.buffer_len())?;
        let payload = self.payload();
        if !matches!(self, FoeRepr::Data { .. }) && payload.last() == Some(&0) {
            return Err(WireError::Invalid {
                what: "FoE message",
                reason: "file name or text ends in NUL",
            });
        }
        packet.set_opcode(self.opcode());
        match *self {
            FoeRepr::ReadRequest { password, .. } | FoeRepr::WriteRequest { password, .. } => {
                packet.set_param(password)
            }
            FoeRepr::Data { packet: n, .. } | FoeRepr::Ack { packet: n } => packet.set_param(n),
            FoeRepr::Error { code, .. } => packet.set_param(u32::from(code)),
            FoeRepr::Busy { done, entire, .. } => packet.set_busy(done, entire),
        }
        packet.payload_mut()[..payload.len()].copy_from_slice(payload);
        Ok(())
    }
}

/// Writes bytes as a quoted ASCII string, escaping anything not printable.
pub(crate) fn fmt_ascii(f: &mut fmt::Formatter<'_>, bytes: &[u8]) -> fmt::Result {
    f.write_str("\"")?;
    for &b in bytes {
        write!(f, "{}", core::ascii::escape_default(b))?;
    }
    f.write_str("\"")
}

impl fmt::Display for FoeRepr<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "FoE {}", self.opcode().name())?;
        match *self {
            FoeRepr::ReadRequest {
                password,
                file_name,
            }
            | FoeRepr::WriteRequest {
                password,
                file_name,
            } => {
                f.write_str(" ")?;
                fmt_ascii(f, file_name)?;
                write!(f, " pw={password}")
            }
            FoeRepr::Data { packet, data } => write!(f, " #{packet} ({} bytes)", data.len()),
            FoeRepr::Ack { packet } => write!(f, " #{packet}"),
            FoeRepr::Error { code, text } => {
                write!(f, " {:#06x} {}", u32::from(code), code.description())?;
                if !text.is_empty() {
                    f.write_str(" ")?;
                    fmt_ascii(f, text)?;
                }
                Ok(())
            }
            FoeRepr::Busy { done, entire, text } => {
                write!(f, " {done}/{entire}")?;
                if !text.is_empty() {
                    f.write_str(" ")?;
                    fmt_ascii(f, text)?;
                }
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Emit;
    use crate::mailbox::{Mailbox, MailboxHeader, MailboxType};
    use proptest::prelude::*;

    // ETG.1000.6, spec-notes §foe.
    static WRQ: [u8; 18] = [
        0x0c, 0x00, 0x00, 0x00, 0x00, 0x24, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x66, 0x77, 0x2e,
        0x62, 0x69, 0x6e,
    ];
    static ACK0: [u8; 12] = [
        0x06, 0x00, 0x00, 0x00, 0x00, 0x14, 0x04, 0x00, 0x00, 0x00, 0x00, 0x00,
    ];
    // DATA 1 with n = 3 bytes (spec-notes §foe): mailbox length 6 + 3, Cnt 3.
    static DATA1: [u8; 15] = [
        0x09, 0x00, 0x00, 0x00, 0x00, 0x34, 0x03, 0x00, 0x01, 0x00, 0x00, 0x00, 0xd0, 0xd1, 0xd2,
    ];

    /// Parses a whole mailbox (header + FoE) and checks the header, then emits it back.
    fn mailbox_case(bytes: &[u8], counter: u8, expected: FoeRepr<'_>) {
        let mbx = Mailbox::new_checked(bytes).unwrap();
        let header = MailboxHeader::parse(&mbx).unwrap();
        assert_eq!(header.mailbox_type, MailboxType::Foe);
        assert_eq!(header.counter, counter);
        let packet = FoePacket::new_checked(mbx.data()).unwrap();
        let repr = FoeRepr::parse(&packet).unwrap();
        assert_eq!(repr, expected);

        let mut out = vec![0xa5u8; bytes.len()];
        let mut header_out = header;
        header_out.length = u16::try_from(repr.buffer_len()).unwrap();
        header_out
            .emit(&mut Mailbox::new_unchecked(&mut out[..]))
            .unwrap();
        repr.emit(&mut FoePacket::new_unchecked(&mut out[6..]))
            .unwrap();
        assert_eq!(out, bytes);
    }

    #[test]
    fn c12_write_request() {
        mailbox_case(
            &WRQ,
            2,
            FoeRepr::WriteRequest {
                password: 0,
                file_name: b"fw.bin",
            },
        );
        let repr = FoeRepr::WriteRequest {
            password: 0,
            file_name: b"fw.bin",
        };
        assert_eq!(repr.to_string(), "FoE WRQ \"fw.bin\" pw=0");
    }

    #[test]
    fn c12_ack_zero() {
        mailbox_case(&ACK0, 1, FoeRepr::Ack { packet: 0 });
        assert_eq!(FoeRepr::Ack { packet: 0 }.to_string(), "FoE ACK #0");
    }

    #[test]
    fn c12_data_one() {
        let repr = FoeRepr::Data {
            packet: 1,
            data: &[0xd0, 0xd1, 0xd2],
        };
        mailbox_case(&DATA1, 3, repr);
        assert_eq!(repr.to_string(), "FoE DATA #1 (3 bytes)");
    }

    #[test]
    fn max_data_is_m_minus_12() {
        assert_eq!(max_data(128), 116);
        assert_eq!(max_data(12), 0);
        assert_eq!(max_data(5), 0);
    }

    #[test]
    fn error_with_text() {
        // opcode 5, reserved, code 0x8001 LE, text "nope".
        let bytes = [0x05, 0x00, 0x01, 0x80, 0x00, 0x00, b'n', b'o', b'p', b'e'];
        let repr = FoeRepr::parse(&FoePacket::new_checked(&bytes[..]).unwrap()).unwrap();
        assert_eq!(
            repr,
            FoeRepr::Error {
                code: FoeError::NotFound,
                text: b"nope"
            }
        );
        assert_eq!(repr.to_string(), "FoE ERROR 0x8001 Not found \"nope\"");
        let mut out = [0xa5u8; 10];
        repr.emit(&mut FoePacket::new_unchecked(&mut out[..]))
            .unwrap();
        assert_eq!(out, bytes);
    }

    #[test]
    fn busy_with_text() {
        // opcode 6, reserved, done 3, entire 10, text "erase".
        let bytes = [
            0x06, 0x00, 0x03, 0x00, 0x0a, 0x00, b'e', b'r', b'a', b's', b'e',
        ];
        let repr = FoeRepr::parse(&FoePacket::new_checked(&bytes[..]).unwrap()).unwrap();
        assert_eq!(
            repr,
            FoeRepr::Busy {
                done: 3,
                entire: 10,
                text: b"erase"
            }
        );
        assert_eq!(repr.to_string(), "FoE BUSY 3/10 \"erase\"");
        let mut out = [0xa5u8; 11];
        repr.emit(&mut FoePacket::new_unchecked(&mut out[..]))
            .unwrap();
        assert_eq!(out, bytes);
    }

    #[test]
    fn trailing_nul_in_name_is_trimmed_and_refused_on_emit() {
        let bytes = [0x01, 0x00, 0x00, 0x00, 0x00, 0x00, b'a', b'b', 0x00];
        let repr = FoeRepr::parse(&FoePacket::new_checked(&bytes[..]).unwrap()).unwrap();
        assert_eq!(
            repr,
            FoeRepr::ReadRequest {
                password: 0,
                file_name: b"ab"
            }
        );
        let bad = FoeRepr::ReadRequest {
            password: 0,
            file_name: b"ab\0",
        };
        let mut out = [0u8; 9];
        assert!(matches!(
            bad.emit(&mut FoePacket::new_unchecked(&mut out[..])),
            Err(WireError::Invalid { .. })
        ));
        assert_eq!(out, [0u8; 9]);
    }

    #[test]
    fn errors() {
        assert!(matches!(
            FoePacket::new_checked(&[0x04u8, 0, 0, 0, 0][..]),
            Err(WireError::Truncated {
                need: 6,
                have: 5,
                ..
            })
        ));
        let unknown = [0x07u8, 0, 0, 0, 0, 0];
        assert_eq!(
            FoeRepr::parse(&FoePacket::new_checked(&unknown[..]).unwrap()),
            Err(WireError::UnknownType {
                what: "FoE opcode",
                value: 7
            })
        );
        let repr = FoeRepr::Data {
            packet: 2,
            data: &[1, 2, 3],
        };
        let mut out = [0u8; 8];
        assert!(matches!(
            repr.emit(&mut FoePacket::new_unchecked(&mut out[..])),
            Err(WireError::BufferTooSmall {
                need: 9,
                have: 8,
                ..
            })
        ));
        assert_eq!(out, [0u8; 8]);
    }

    fn arb_text() -> impl Strategy<Value = Vec<u8>> {
        proptest::collection::vec(any::<u8>(), 0..40).prop_map(|mut v| {
            if v.last() == Some(&0) {
                v.pop();
                v.push(b'x');
            }
            v
        })
    }

    proptest! {
        #[test]
        fn round_trip(kind in 0u8..6, param in any::<u32>(), done in any::<u16>(),
                      entire in any::<u16>(), payload in arb_text()) {
            let repr = match kind {
                0 => FoeRepr::ReadRequest { password: param, file_name: &payload },
                1 => FoeRepr::WriteRequest { password: param, file_name: &payload },
                2 => FoeRepr::Data { packet: param, data: &payload },
                3 => FoeRepr::Ack { packet: param },
                4 => FoeRepr::Error { code: FoeError::from(param), text: &payload },
                _ => FoeRepr::Busy { done, entire, text: &payload },
            };
            let buf = repr.to_vec().unwrap();
            let parsed = FoeRepr::parse(&FoePacket::new_checked(&buf[..]).unwrap()).unwrap();
            prop_assert_eq!(parsed, repr);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..32)) {
            if let Ok(packet) = FoePacket::new_checked(&bytes[..])
                && let Ok(repr) = FoeRepr::parse(&packet) {
                    let _ = repr.to_string();
                }
        }
    }
}
