//! AL control 0x0120, AL status 0x0130 and the 6-byte status read 0x0130–0x0135
//! (ETG.1000.6, spec-notes §al).
//!
//! ```text
//! AL control / AL status (u16): bits 0-3 state, bit 4 error ack / error indication,
//!                               bit 5 ID request / ID loaded, bits 6-15 reserved
//! 0x0130 u16 AL status | 0x0132 u16 reserved | 0x0134 u16 AL status code
//! ```

use core::fmt;

use super::al_status_code::AlStatusCode;
use crate::error::{Result, WireError, need, room};
use crate::field::{self, Field};
use crate::macros::enum_with_unknown;

mod fields {
    use super::Field;
    pub const STATUS: Field = 0..2;
    pub const RESERVED: Field = 2..4;
    pub const CODE: Field = 4..6;
}

/// Bits 0-3: the state.
const STATE_MASK: u16 = 0x000F;
/// Bit 4: error acknowledge (control) / error indication (status).
const ERROR_BIT: u16 = 0x0010;
/// Bit 5: device identification request (control) / ID loaded (status).
const ID_BIT: u16 = 0x0020;

enum_with_unknown! {
    /// EtherCAT state machine state (spec-notes §al), the low nibble of AL control/status.
    ///
    /// A BRD of 0x0130 returns the OR of several slaves' states, which is why values like
    /// 0x6 (PREOP | SAFEOP) or 0xC appear as `Unknown`, and why INIT | PREOP (0x3) reads as
    /// BOOT: the OR is a hint that not every slave is in one state, never a state itself;
    /// only a slave's own AL status says which state it is in.
    pub enum AlState(u8) {
        /// INIT.
        Init = 0x1,
        /// PRE-OPERATIONAL.
        PreOp = 0x2,
        /// BOOTSTRAP.
        Boot = 0x3,
        /// SAFE-OPERATIONAL.
        SafeOp = 0x4,
        /// OPERATIONAL.
        Op = 0x8,
    }
}

impl AlState {
    /// The five states of the state machine (ETG.1000.6 §6.4.1), from INIT up.
    pub const ALL: [AlState; 5] = [
        AlState::Init,
        AlState::PreOp,
        AlState::Boot,
        AlState::SafeOp,
        AlState::Op,
    ];

    /// The name the standard and Wireshark use ("INIT", "PREOP", "BOOT", "SAFEOP", "OP").
    pub fn name(self) -> &'static str {
        match self {
            AlState::Init => "INIT",
            AlState::PreOp => "PREOP",
            AlState::Boot => "BOOT",
            AlState::SafeOp => "SAFEOP",
            AlState::Op => "OP",
            AlState::Unknown(_) => "unknown",
        }
    }

    /// Refuses a state value that does not fit the 4-bit field.
    fn checked_bits(self, what: &'static str) -> Result<u16> {
        let raw = u8::from(self);
        if u16::from(raw) > STATE_MASK {
            return Err(WireError::Invalid {
                what,
                reason: "state does not fit in 4 bits",
            });
        }
        Ok(u16::from(raw))
    }
}

impl fmt::Display for AlState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AlState::Unknown(raw) => write!(f, "state {raw:#x}"),
            known => f.write_str(known.name()),
        }
    }
}

/// Reads a u16 register value from the first two bytes of `buf`.
fn read_u16(what: &'static str, buf: &[u8]) -> Result<u16> {
    need(what, buf, 2)?;
    Ok(field::u16_le(buf, 0))
}

/// Writes a u16 register value into the first two bytes of `buf`.
fn write_u16(what: &'static str, buf: &mut [u8], value: u16) -> Result<()> {
    room(what, buf, 2)?;
    field::set_u16_le(buf, 0, value);
    Ok(())
}

/// AL control register 0x0120 (u16), written by the master (ETG.1000.6, spec-notes §al).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AlControl {
    /// Requested state.
    pub state: AlState,
    /// Bit 4: acknowledge a pending error indication.
    pub ack: bool,
    /// Bit 5: request the device identification value in 0x0134.
    pub id_request: bool,
}

impl AlControl {
    /// Size of the register.
    pub const LEN: usize = 2;

    /// A plain state request without acknowledge.
    pub const fn request(state: AlState) -> Self {
        AlControl {
            state,
            ack: false,
            id_request: false,
        }
    }

    /// A state request that also acknowledges an error (`state | 0x10`, as SOEM/IgH do).
    pub const fn acknowledge(state: AlState) -> Self {
        AlControl {
            state,
            ack: true,
            id_request: false,
        }
    }

    /// Decodes a register value; reserved bits 6-15 are ignored.
    pub fn decode(raw: u16) -> Self {
        AlControl {
            state: AlState::from((raw & STATE_MASK) as u8),
            ack: raw & ERROR_BIT != 0,
            id_request: raw & ID_BIT != 0,
        }
    }

    /// Encodes the register value; refuses a state wider than 4 bits.
    pub fn encode(&self) -> Result<u16> {
        let mut raw = self.state.checked_bits("AL control")?;
        if self.ack {
            raw |= ERROR_BIT;
        }
        if self.id_request {
            raw |= ID_BIT;
        }
        Ok(raw)
    }

    /// Parses the register from the first two bytes of `buf`.
    pub fn parse(buf: &[u8]) -> Result<Self> {
        read_u16("AL control", buf).map(Self::decode)
    }

    /// Writes the register into the first two bytes of `buf`.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        let raw = self.encode()?;
        write_u16("AL control", buf, raw)
    }
}

impl fmt::Display for AlControl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "AL control {}", self.state)?;
        if self.ack {
            f.write_str(" +ACK")?;
        }
        if self.id_request {
            f.write_str(" +ID")?;
        }
        Ok(())
    }
}

/// AL status register 0x0130 (u16), written by the slave (ETG.1000.6, spec-notes §al).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AlStatus {
    /// Current state.
    pub state: AlState,
    /// Bit 4: error indication (0x0134 says why).
    pub error: bool,
    /// Bit 5: device identification value loaded into 0x0134.
    pub id_loaded: bool,
}

impl AlStatus {
    /// Size of the register.
    pub const LEN: usize = 2;

    /// A status without error or ID flags.
    pub const fn new(state: AlState) -> Self {
        AlStatus {
            state,
            error: false,
            id_loaded: false,
        }
    }

    /// Decodes a register value; reserved bits 6-15 are ignored.
    pub fn decode(raw: u16) -> Self {
        AlStatus {
            state: AlState::from((raw & STATE_MASK) as u8),
            error: raw & ERROR_BIT != 0,
            id_loaded: raw & ID_BIT != 0,
        }
    }

    /// Encodes the register value; refuses a state wider than 4 bits.
    pub fn encode(&self) -> Result<u16> {
        let mut raw = self.state.checked_bits("AL status")?;
        if self.error {
            raw |= ERROR_BIT;
        }
        if self.id_loaded {
            raw |= ID_BIT;
        }
        Ok(raw)
    }

    /// Parses the register from the first two bytes of `buf`.
    pub fn parse(buf: &[u8]) -> Result<Self> {
        read_u16("AL status", buf).map(Self::decode)
    }

    /// Writes the register into the first two bytes of `buf`.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        let raw = self.encode()?;
        write_u16("AL status", buf, raw)
    }
}

impl fmt::Display for AlStatus {
    /// `INIT`, `PREOP + ERROR`, as IgH and SOEM print it.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.state)?;
        if self.error {
            f.write_str(" + ERROR")?;
        }
        if self.id_loaded {
            f.write_str(" + ID")?;
        }
        Ok(())
    }
}

/// Size of the AL status block read 0x0130–0x0135.
pub const AL_STATUS_BLOCK_LEN: usize = fields::CODE.end;

/// View of the 6 bytes 0x0130–0x0135: AL status, a reserved word, AL status code
/// (ETG.1000.6, spec-notes §al, master procedure).
#[derive(Debug, Clone)]
pub struct AlStatusBlock<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> AlStatusBlock<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        AlStatusBlock { buffer }
    }

    /// Wraps a buffer and checks that all 6 bytes are present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let view = Self::new_unchecked(buffer);
        view.check_len()?;
        Ok(view)
    }

    /// Checks that the 6 bytes are present.
    pub fn check_len(&self) -> Result<()> {
        need("AL status block", self.buffer.as_ref(), AL_STATUS_BLOCK_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Raw AL status (0x0130).
    pub fn status_raw(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::STATUS.start)
    }

    /// Decoded AL status.
    pub fn status(&self) -> AlStatus {
        AlStatus::decode(self.status_raw())
    }

    /// The reserved word 0x0132.
    pub fn reserved(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::RESERVED.start)
    }

    /// AL status code (0x0134); holds the ID value instead when `id_loaded` is set.
    pub fn code(&self) -> AlStatusCode {
        AlStatusCode::from(field::u16_le(self.buffer.as_ref(), fields::CODE.start))
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> AlStatusBlock<T> {
    /// Sets the raw AL status.
    pub fn set_status_raw(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::STATUS.start, value)
    }

    /// Sets the reserved word.
    pub fn set_reserved(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::RESERVED.start, value)
    }

    /// Sets the AL status code.
    pub fn set_code(&mut self, code: AlStatusCode) {
        field::set_u16_le(self.buffer.as_mut(), fields::CODE.start, u16::from(code))
    }
}

/// Parsed AL status block: what a master learns from one 6-byte FPRD of 0x0130.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AlStatusBlockRepr {
    /// AL status.
    pub status: AlStatus,
    /// AL status code.
    pub code: AlStatusCode,
}

impl AlStatusBlockRepr {
    /// Parses a checked view (the reserved word is ignored).
    pub fn parse<T: AsRef<[u8]>>(view: &AlStatusBlock<T>) -> Result<Self> {
        view.check_len()?;
        Ok(AlStatusBlockRepr {
            status: view.status(),
            code: view.code(),
        })
    }

    /// Bytes written by [`Self::emit`].
    pub const fn buffer_len(&self) -> usize {
        AL_STATUS_BLOCK_LEN
    }

    /// Writes the 6 bytes (reserved word 0).
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, view: &mut AlStatusBlock<T>) -> Result<()> {
        room("AL status block", view.buffer.as_ref(), AL_STATUS_BLOCK_LEN)?;
        let status = self.status.encode()?;
        view.set_status_raw(status);
        view.set_reserved(0);
        view.set_code(self.code);
        Ok(())
    }
}

impl fmt::Display for AlStatusBlockRepr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "AL status {}", self.status)?;
        if self.status.error {
            write!(f, ", code {}", self.code)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn state_names() {
        let names: Vec<_> = [1u8, 2, 3, 4, 8]
            .iter()
            .map(|&s| AlState::from(s).name())
            .collect();
        assert_eq!(names, ["INIT", "PREOP", "BOOT", "SAFEOP", "OP"]);
        assert_eq!(AlState::from(6).to_string(), "state 0x6");
    }

    #[test]
    fn c5_control_bytes() {
        // ETG.1000.6, spec-notes §al: request PREOP = `02 00`; acknowledge + PREOP = `12 00`.
        let mut buf = [0xa5u8; 2];
        AlControl::request(AlState::PreOp).emit(&mut buf).unwrap();
        assert_eq!(buf, [0x02, 0x00]);
        AlControl::acknowledge(AlState::PreOp)
            .emit(&mut buf)
            .unwrap();
        assert_eq!(buf, [0x12, 0x00]);
        assert_eq!(
            AlControl::parse(&[0x12, 0x00]).unwrap(),
            AlControl::acknowledge(AlState::PreOp)
        );
        // SOEM's broadcast "INIT + ack" (ETG.1000.4, spec-notes §esc.reset) is 0x0011.
        assert_eq!(AlControl::acknowledge(AlState::Init).encode(), Ok(0x0011));
    }

    static C5_STATUS: [u8; 6] = [0x11, 0x00, 0x00, 0x00, 0x16, 0x00];

    #[test]
    fn c5_status_block_parse() {
        let view = AlStatusBlock::new_checked(&C5_STATUS[..]).unwrap();
        let repr = AlStatusBlockRepr::parse(&view).unwrap();
        assert_eq!(repr.status.state, AlState::Init);
        assert!(repr.status.error);
        assert!(!repr.status.id_loaded);
        assert_eq!(repr.code, AlStatusCode::InvalidMailboxConfigPreop);
        assert_eq!(
            repr.to_string(),
            "AL status INIT + ERROR, code 0x0016 Invalid mailbox configuration (PREOP)"
        );
    }

    #[test]
    fn c5_status_block_emit() {
        let repr = AlStatusBlockRepr {
            status: AlStatus {
                state: AlState::Init,
                error: true,
                id_loaded: false,
            },
            code: AlStatusCode::InvalidMailboxConfigPreop,
        };
        let mut buf = [0xa5u8; 6];
        repr.emit(&mut AlStatusBlock::new_unchecked(&mut buf[..]))
            .unwrap();
        assert_eq!(buf, C5_STATUS);
    }

    #[test]
    fn truncated_and_refused() {
        assert!(matches!(
            AlStatusBlock::new_checked(&C5_STATUS[..5]),
            Err(WireError::Truncated {
                need: 6,
                have: 5,
                ..
            })
        ));
        assert!(AlControl::parse(&[0x02]).is_err());
        let mut buf = [0xa5u8; 2];
        let bad = AlControl::request(AlState::Unknown(0x10));
        assert!(bad.emit(&mut buf).is_err());
        assert_eq!(buf, [0xa5, 0xa5], "a refused emit writes nothing");
        assert!(AlControl::request(AlState::Op).emit(&mut [0u8; 1]).is_err());
    }

    pub(crate) fn arb_state() -> impl Strategy<Value = AlState> {
        (0u8..16).prop_map(AlState::from)
    }

    pub(crate) fn arb_status() -> impl Strategy<Value = AlStatus> {
        (arb_state(), any::<bool>(), any::<bool>()).prop_map(|(state, error, id_loaded)| AlStatus {
            state,
            error,
            id_loaded,
        })
    }

    proptest! {
        #[test]
        fn control_round_trip(state in arb_state(), ack in any::<bool>(), id in any::<bool>()) {
            let c = AlControl { state, ack, id_request: id };
            let mut buf = [0u8; 2];
            c.emit(&mut buf).unwrap();
            prop_assert_eq!(AlControl::parse(&buf).unwrap(), c);
        }

        #[test]
        fn status_block_round_trip(status in arb_status(), code in any::<u16>()) {
            let repr = AlStatusBlockRepr { status, code: AlStatusCode::from(code) };
            let mut buf = [0u8; AL_STATUS_BLOCK_LEN];
            repr.emit(&mut AlStatusBlock::new_unchecked(&mut buf[..])).unwrap();
            let parsed = AlStatusBlockRepr::parse(&AlStatusBlock::new_checked(&buf[..]).unwrap()).unwrap();
            prop_assert_eq!(parsed, repr);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..10)) {
            let _ = AlControl::parse(&bytes);
            let _ = AlStatus::parse(&bytes);
            if let Ok(view) = AlStatusBlock::new_checked(&bytes[..]) {
                let _ = AlStatusBlockRepr::parse(&view).map(|r| r.to_string());
                let _ = view.reserved();
            }
        }
    }
}
