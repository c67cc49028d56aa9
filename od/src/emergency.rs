//! Building CoE emergency messages (spec-notes §coe.emcy) for the owner of a dictionary to post in
//! SM1 — unsolicited, outside any SDO exchange, so the server does not send them itself.

use ecat_wire::coe::emergency::EMERGENCY_LEN;
use ecat_wire::coe::{EmergencyFrame, EmergencyRepr};

/// CiA 301 error codes a simulated device commonly reports.
pub mod codes {
    /// 0x0000: error reset / no error (sent when a diagnosed error disappears).
    pub const NO_ERROR: u16 = 0x0000;
    /// 0x8100: communication error.
    pub const COMMUNICATION: u16 = 0x8100;
    /// 0xA000: transition from PREOP to SAFEOP failed (ETG.1000.6 sync errors).
    pub const SAFEOP_TRANSITION: u16 = 0xA000;
    /// 0xFF00: device specific.
    pub const DEVICE_SPECIFIC: u16 = 0xFF00;
}

/// The 10 bytes of CoE mailbox data of an emergency (the caller adds the mailbox header).
pub fn emergency(error_code: u16, error_register: u8, data: [u8; 5]) -> [u8; EMERGENCY_LEN] {
    let mut out = [0u8; EMERGENCY_LEN];
    let repr = EmergencyRepr {
        error_code,
        error_register,
        data,
    };
    // The buffer has exactly the emergency's length, which is all emit needs.
    let _ = repr.emit(&mut EmergencyFrame::new_unchecked(&mut out[..]));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_back() {
        let bytes = emergency(codes::COMMUNICATION, 0x11, [1, 2, 3, 4, 5]);
        assert_eq!(bytes[..2], [0x00, 0x10]);
        let parsed =
            EmergencyRepr::parse(&EmergencyFrame::new_checked(&bytes[..]).unwrap()).unwrap();
        assert_eq!(parsed.error_code, 0x8100);
        assert_eq!(parsed.error_register, 0x11);
        assert_eq!(parsed.data, [1, 2, 3, 4, 5]);
    }
}
