//! The 2-byte CoE header (ETG.1000.6 CoE header, spec-notes §coe.header).
//!
//! ```text
//! u16 LE: bits 0-8 number (PDO number; 0 for SDO, SDO Info, emergency)
//!         bits 9-11 reserved (0)
//!         bits 12-15 service
//! ```
//!
//! Views in this module and its siblings all wrap the *mailbox data* (what
//! [`crate::mailbox::Mailbox::data`] returns: exactly `length` bytes, starting with
//! this header), so that the length of the view's buffer is the mailbox length.

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field::{self, Field, Rest};
use crate::macros::enum_with_unknown;

mod fields {
    use super::{Field, Rest};
    pub const HEADER: Field = 0..2;
    pub const PAYLOAD: Rest = 2..;
}

/// Size of the CoE header in bytes.
pub const COE_HEADER_LEN: usize = fields::PAYLOAD.start;

const NUMBER_MASK: u16 = 0x01FF;
const RESERVED_MASK: u16 = 0x0E00;
const SERVICE_SHIFT: u16 = 12;

enum_with_unknown! {
    /// CoE service (bits 12-15 of the CoE header, ETG.1000.6, spec-notes §coe.header).
    pub enum CoeService(u8) {
        /// Emergency (slave → master, unsolicited).
        Emergency = 1,
        /// SDO request (client → server).
        SdoRequest = 2,
        /// SDO response (server → client).
        SdoResponse = 3,
        /// TxPDO via mailbox (slave → master).
        TxPdo = 4,
        /// RxPDO via mailbox (master → slave).
        RxPdo = 5,
        /// TxPDO remote request.
        TxPdoRemote = 6,
        /// RxPDO remote request.
        RxPdoRemote = 7,
        /// SDO Information.
        SdoInfo = 8,
    }
}

impl CoeService {
    /// Wireshark-style service name.
    pub fn name(self) -> &'static str {
        match self {
            CoeService::Emergency => "Emergency",
            CoeService::SdoRequest => "SDO Request",
            CoeService::SdoResponse => "SDO Response",
            CoeService::TxPdo => "TxPDO",
            CoeService::RxPdo => "RxPDO",
            CoeService::TxPdoRemote => "TxPDO remote request",
            CoeService::RxPdoRemote => "RxPDO remote request",
            CoeService::SdoInfo => "SDO Information",
            CoeService::Unknown(_) => "unknown",
        }
    }
}

/// A view of CoE mailbox data: the CoE header and the bytes after it.
#[derive(Debug, Clone)]
pub struct CoeFrame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> CoeFrame<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        CoeFrame { buffer }
    }

    /// Wraps a buffer and checks that the CoE header is present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let frame = Self::new_unchecked(buffer);
        frame.check_len()?;
        Ok(frame)
    }

    /// Checks that the 2-byte header is present.
    pub fn check_len(&self) -> Result<()> {
        need("CoE header", self.buffer.as_ref(), COE_HEADER_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    fn raw(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::HEADER.start)
    }

    /// PDO number (bits 0-8).
    pub fn number(&self) -> u16 {
        self.raw() & NUMBER_MASK
    }

    /// Reserved bits 9-11, shifted down (0..=7).
    pub fn reserved(&self) -> u8 {
        ((self.raw() & RESERVED_MASK) >> 9) as u8
    }

    /// The service (bits 12-15).
    pub fn service(&self) -> CoeService {
        CoeService::from((self.raw() >> SERVICE_SHIFT) as u8)
    }

    /// The bytes after the CoE header.
    pub fn payload(&self) -> &[u8] {
        &self.buffer.as_ref()[fields::PAYLOAD]
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> CoeFrame<T> {
    /// Writes number and service; reserved bits are cleared. Wider values are masked, so
    /// callers go through [`CoeHeaderRepr::emit`], which refuses them.
    pub fn set_header(&mut self, number: u16, service: CoeService) {
        let raw = (number & NUMBER_MASK) | (u16::from(u8::from(service) & 0x0F) << SERVICE_SHIFT);
        field::set_u16_le(self.buffer.as_mut(), fields::HEADER.start, raw)
    }

    /// Mutable bytes after the header.
    pub fn payload_mut(&mut self) -> &mut [u8] {
        &mut self.buffer.as_mut()[fields::PAYLOAD]
    }

    /// The whole mutable buffer (service emitters write the CoE header through it).
    pub fn buffer_mut(&mut self) -> &mut [u8] {
        self.buffer.as_mut()
    }
}

impl<'a> CoeFrame<&'a [u8]> {
    /// The whole frame with the lifetime of the underlying buffer (for borrowing parses).
    pub fn bytes(&self) -> &'a [u8] {
        self.buffer
    }
}

/// The parsed CoE header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CoeHeaderRepr {
    /// PDO number, 0..=511 (0 for SDO, SDO Info and emergency).
    pub number: u16,
    /// The service.
    pub service: CoeService,
}

impl CoeHeaderRepr {
    /// Parses the header. Reserved bits 9-11 are ignored on receive (they are sent as 0),
    /// following the tolerant-receiver rule the mailbox header uses.
    pub fn parse<T: AsRef<[u8]>>(frame: &CoeFrame<T>) -> Result<Self> {
        frame.check_len()?;
        Ok(CoeHeaderRepr {
            number: frame.number(),
            service: frame.service(),
        })
    }

    /// Size on the wire.
    pub const fn buffer_len(&self) -> usize {
        COE_HEADER_LEN
    }

    /// Checks that every field fits its bits.
    pub(crate) fn validate(&self) -> Result<()> {
        if self.number > NUMBER_MASK || u8::from(self.service) > 0x0F {
            return Err(WireError::Invalid {
                what: "CoE header",
                reason: "number above 511 or service above 15",
            });
        }
        Ok(())
    }

    /// Writes the header; refuses a number above 511 or a service above 15.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, frame: &mut CoeFrame<T>) -> Result<()> {
        self.validate()?;
        room("CoE header", frame.buffer.as_ref(), COE_HEADER_LEN)?;
        frame.set_header(self.number, self.service);
        Ok(())
    }
}

impl fmt::Display for CoeHeaderRepr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "CoE {}", self.service.name())?;
        if let CoeService::Unknown(raw) = self.service {
            write!(f, " ({raw})")?;
        }
        if self.number != 0 {
            write!(f, " number {}", self.number)?;
        }
        Ok(())
    }
}

/// Writes the CoE header of an SDO/SDO-Info/emergency frame (number 0) into `buf`.
/// The caller has checked the room.
pub(crate) fn put_header(buf: &mut [u8], service: CoeService) {
    CoeFrame::new_unchecked(buf).set_header(0, service);
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn digest_header_bytes() {
        // spec-notes §coe.header: SDO request `00 20`, response `00 30`, SDO info `00 80`, emergency `00 10`.
        for (bytes, service) in [
            ([0x00, 0x20], CoeService::SdoRequest),
            ([0x00, 0x30], CoeService::SdoResponse),
            ([0x00, 0x80], CoeService::SdoInfo),
            ([0x00, 0x10], CoeService::Emergency),
        ] {
            let frame = CoeFrame::new_checked(&bytes[..]).unwrap();
            let repr = CoeHeaderRepr::parse(&frame).unwrap();
            assert_eq!(repr, CoeHeaderRepr { number: 0, service });
            let mut out = [0xa5u8; 2];
            repr.emit(&mut CoeFrame::new_unchecked(&mut out[..]))
                .unwrap();
            assert_eq!(out, bytes);
        }
    }

    #[test]
    fn pdo_number_and_reserved_bits() {
        // 0x51FF: number 0x1FF, reserved 0, service 5 (RxPDO).
        let frame = CoeFrame::new_checked(&[0xFF, 0x51][..]).unwrap();
        assert_eq!(frame.number(), 0x1FF);
        assert_eq!(frame.service(), CoeService::RxPdo);
        // 0x2E00: reserved bits 9-11 all set, ignored by parse.
        let frame = CoeFrame::new_checked(&[0x00, 0x2E][..]).unwrap();
        assert_eq!(frame.reserved(), 7);
        assert_eq!(CoeHeaderRepr::parse(&frame).unwrap().number, 0);
    }

    #[test]
    fn errors() {
        assert!(matches!(
            CoeFrame::new_checked(&[0x00][..]),
            Err(WireError::Truncated { .. })
        ));
        let mut out = [0u8; 2];
        let bad = CoeHeaderRepr {
            number: 512,
            service: CoeService::SdoRequest,
        };
        assert!(
            bad.emit(&mut CoeFrame::new_unchecked(&mut out[..]))
                .is_err()
        );
        let bad = CoeHeaderRepr {
            number: 0,
            service: CoeService::Unknown(16),
        };
        assert!(
            bad.emit(&mut CoeFrame::new_unchecked(&mut out[..]))
                .is_err()
        );
        assert_eq!(out, [0, 0]);
        let mut short = [0u8; 1];
        let ok = CoeHeaderRepr {
            number: 0,
            service: CoeService::SdoInfo,
        };
        assert!(matches!(
            ok.emit(&mut CoeFrame::new_unchecked(&mut short[..])),
            Err(WireError::BufferTooSmall { .. })
        ));
    }

    #[test]
    fn display() {
        let r = CoeHeaderRepr {
            number: 3,
            service: CoeService::TxPdo,
        };
        assert_eq!(r.to_string(), "CoE TxPDO number 3");
    }

    pub(crate) fn arb_coe_header() -> impl Strategy<Value = CoeHeaderRepr> {
        (0u16..512, 0u8..16).prop_map(|(number, s)| CoeHeaderRepr {
            number,
            service: CoeService::from(s),
        })
    }

    proptest! {
        #[test]
        fn round_trip(repr in arb_coe_header()) {
            let mut out = [0u8; 2];
            repr.emit(&mut CoeFrame::new_unchecked(&mut out[..])).unwrap();
            let parsed = CoeHeaderRepr::parse(&CoeFrame::new_checked(&out[..]).unwrap()).unwrap();
            prop_assert_eq!(parsed, repr);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..8)) {
            if let Ok(frame) = CoeFrame::new_checked(&bytes[..]) {
                let _ = CoeHeaderRepr::parse(&frame);
                let _ = (frame.payload(), frame.reserved());
            }
        }
    }
}
