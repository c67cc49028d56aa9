//! CoE emergency (service 1, spec-notes §coe.emcy; CiA 301 EMCY carried over the mailbox).
//!
//! ```text
//! mailbox data offset 0  u16  CoE header `00 10`
//!                     2  u16  error code (CiA 301, e.g. 0x8100 communication)
//!                     4  u8   error register (object 0x1001)
//!                     5  5    manufacturer-specific data
//! ```
//! Mailbox length 10. Emergencies are unsolicited and may arrive between SDO replies.

use core::fmt;

use super::display::Hex;
use super::header::{CoeFrame, CoeService, put_header};
use crate::error::{Result, WireError, need, room};
use crate::field::{self, Field};

mod fields {
    use super::Field;
    pub const ERROR_CODE: Field = 2..4;
    pub const ERROR_REGISTER: usize = 4;
    pub const DATA: Field = 5..10;
}

/// Mailbox length of an emergency.
pub const EMERGENCY_LEN: usize = fields::DATA.end;

/// A view of an emergency (mailbox data, CoE header included).
#[derive(Debug, Clone)]
pub struct EmergencyFrame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> EmergencyFrame<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        EmergencyFrame { buffer }
    }

    /// Wraps a buffer and checks its length.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let e = Self::new_unchecked(buffer);
        e.check_len()?;
        Ok(e)
    }

    /// Checks that all 10 bytes are present.
    pub fn check_len(&self) -> Result<()> {
        need("CoE emergency", self.buffer.as_ref(), EMERGENCY_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// The CoE service of the frame (1 for an emergency).
    pub fn service(&self) -> CoeService {
        CoeFrame::new_unchecked(self.buffer.as_ref()).service()
    }

    /// CiA 301 error code.
    pub fn error_code(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::ERROR_CODE.start)
    }

    /// Error register (value of object 0x1001).
    pub fn error_register(&self) -> u8 {
        self.buffer.as_ref()[fields::ERROR_REGISTER]
    }

    /// The 5 manufacturer-specific bytes.
    pub fn data(&self) -> [u8; 5] {
        let mut out = [0u8; 5];
        out.copy_from_slice(&self.buffer.as_ref()[fields::DATA]);
        out
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> EmergencyFrame<T> {
    /// Sets the error code.
    pub fn set_error_code(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::ERROR_CODE.start, value)
    }

    /// Sets the error register.
    pub fn set_error_register(&mut self, value: u8) {
        self.buffer.as_mut()[fields::ERROR_REGISTER] = value
    }

    /// Sets the manufacturer-specific bytes.
    pub fn set_data(&mut self, value: [u8; 5]) {
        self.buffer.as_mut()[fields::DATA].copy_from_slice(&value)
    }
}

/// A parsed emergency.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct EmergencyRepr {
    /// CiA 301 error code.
    pub error_code: u16,
    /// Error register.
    pub error_register: u8,
    /// Manufacturer-specific data (SOEM splits it as u8 + u16 + u16).
    pub data: [u8; 5],
}

impl EmergencyRepr {
    /// Parses an emergency; the CoE service must be 1.
    pub fn parse<T: AsRef<[u8]>>(e: &EmergencyFrame<T>) -> Result<Self> {
        e.check_len()?;
        let service = e.service();
        if service != CoeService::Emergency {
            return Err(WireError::UnknownType {
                what: "CoE service of an emergency",
                value: u32::from(u8::from(service)),
            });
        }
        Ok(EmergencyRepr {
            error_code: e.error_code(),
            error_register: e.error_register(),
            data: e.data(),
        })
    }

    /// Mailbox length (10).
    pub const fn buffer_len(&self) -> usize {
        EMERGENCY_LEN
    }

    /// Writes the CoE header and the emergency.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, e: &mut EmergencyFrame<T>) -> Result<()> {
        room("CoE emergency", e.buffer.as_ref(), EMERGENCY_LEN)?;
        put_header(e.buffer.as_mut(), CoeService::Emergency);
        e.set_error_code(self.error_code);
        e.set_error_register(self.error_register);
        e.set_data(self.data);
        Ok(())
    }
}

impl fmt::Display for EmergencyRepr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "CoE emergency error code {:#06x} register {:#04x} data {}",
            self.error_code,
            self.error_register,
            Hex(&self.data)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mailbox::{HEADER_LEN, Mailbox, MailboxHeader, MailboxType};
    use proptest::prelude::*;

    // By hand (spec-notes §coe.emcy): length 10, CoE, counter 1; error 0x8100, register 0x11,
    // data 01 02 03 04 05.
    static EMCY: [u8; 16] = [
        0x0a, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x10, 0x00, 0x81, 0x11, 0x01, 0x02, 0x03, 0x04,
        0x05,
    ];

    fn repr() -> EmergencyRepr {
        EmergencyRepr {
            error_code: 0x8100,
            error_register: 0x11,
            data: [1, 2, 3, 4, 5],
        }
    }

    #[test]
    fn parse_and_emit() {
        let mbx = Mailbox::new_checked(&EMCY[..]).unwrap();
        assert_eq!(
            MailboxHeader::parse(&mbx).unwrap().mailbox_type,
            MailboxType::Coe
        );
        let e = EmergencyRepr::parse(&EmergencyFrame::new_checked(mbx.data()).unwrap()).unwrap();
        assert_eq!(e, repr());
        let mut out = [0xa5u8; 10];
        repr()
            .emit(&mut EmergencyFrame::new_unchecked(&mut out[..]))
            .unwrap();
        assert_eq!(out, EMCY[HEADER_LEN..]);
        assert_eq!(
            e.to_string(),
            "CoE emergency error code 0x8100 register 0x11 data [01 02 03 04 05]"
        );
    }

    #[test]
    fn errors() {
        assert!(EmergencyFrame::new_checked(&EMCY[HEADER_LEN..15]).is_err());
        let mut sdo = EMCY;
        sdo[7] = 0x30;
        assert!(matches!(
            EmergencyRepr::parse(&EmergencyFrame::new_unchecked(&sdo[HEADER_LEN..])),
            Err(WireError::UnknownType { value: 3, .. })
        ));
        let mut short = [0u8; 9];
        assert!(
            repr()
                .emit(&mut EmergencyFrame::new_unchecked(&mut short[..]))
                .is_err()
        );
        assert_eq!(short, [0; 9]);
    }

    pub(crate) fn arb_emergency() -> impl Strategy<Value = EmergencyRepr> {
        (any::<u16>(), any::<u8>(), any::<[u8; 5]>()).prop_map(
            |(error_code, error_register, data)| EmergencyRepr {
                error_code,
                error_register,
                data,
            },
        )
    }

    proptest! {
        #[test]
        fn round_trip(e in arb_emergency()) {
            let mut out = [0u8; EMERGENCY_LEN];
            e.emit(&mut EmergencyFrame::new_unchecked(&mut out[..])).unwrap();
            prop_assert_eq!(EmergencyRepr::parse(&EmergencyFrame::new_checked(&out[..]).unwrap()).unwrap(), e);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..16)) {
            if let Ok(e) = EmergencyFrame::new_checked(&bytes[..]) {
                let _ = EmergencyRepr::parse(&e);
            }
        }
    }
}
