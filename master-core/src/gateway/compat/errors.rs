//! The gateway's own error answers to a request in the compatibility layout, with the code
//! table of the manual those clients were written against (docs/gateway.md):
//!
//! | fault | CoE | SoE | FoE | VoE, EoE |
//! |---|---|---|---|---|
//! | unknown address | abort 0x06020000 | error 0x1009 | error 0x8002 | 0x0001 |
//! | protocol not served, mailbox not running | abort 0x06010000 | error 0x8001 | error 0x8001 | 0x0001 |
//! | a `read` client's write | abort 0x06010002 | error 0x7002 | error 0x8002 | 0x0001 |
//! | timeout, an absent slave | abort 0x08000000 | error 0x8000 | error 0x8000 | 0x0003 |
//! | busy, larger than the mailbox, a transfer step sent to 0xFFFF, anything else | abort 0x08000000 | error 0x8000 | error 0x8000 | 0x0000 |
//!
//! In that table FoE 0x8001 is "invalid op code / not implemented" and 0x8002 "file not
//! found" (ETG.1000.6 numbers them "not found" and "access denied"); SoE 0x8001 "service not
//! available", 0x1009 "IDN does not exist", 0x7002 "write failed", 0x8000 "general error".
//! VoE and EoE have no error message of their own: their code goes in a mailbox error
//! message (type 0, ETG.1000.4 §5.6, Table 30: type 0x0001, then the code), whose type byte
//! 0x00 reads the same in both layouts.

use crate::wire::coe::AbortCode;
use crate::wire::foe::FoeError;
use crate::wire::mailbox::MailboxType;
use crate::wire::soe::SoeError;

use super::super::answer::{Fault, coe_answer, foe_answer, soe_answer};
use super::super::ask::Ask;

/// The answer (standard type and data, to be encoded in the compatibility layout) to a
/// request of `ty` with standard data `request` that failed with `fault`.
pub(crate) fn answer(request: &Ask, fault: Fault) -> Option<(MailboxType, Vec<u8>)> {
    match request.ty {
        MailboxType::Coe => coe_answer(request, AbortCode::from(coe(fault))),
        MailboxType::Soe => soe_answer(request, SoeError::from(soe(fault))),
        MailboxType::Foe => foe_answer((FoeError::from(foe(fault)), b"")),
        _ => Some(code_error(other(fault))),
    }
}

fn coe(fault: Fault) -> u32 {
    match fault {
        Fault::UnknownAddress => 0x0602_0000,
        Fault::Unsupported | Fault::NotRunning => 0x0601_0000,
        Fault::Denied => 0x0601_0002,
        Fault::Timeout
        | Fault::Absent
        | Fault::Busy
        | Fault::Oversized
        | Fault::NotBroadcast
        | Fault::Other => 0x0800_0000,
    }
}

fn soe(fault: Fault) -> u16 {
    match fault {
        Fault::UnknownAddress => 0x1009,
        Fault::Unsupported | Fault::NotRunning => 0x8001,
        Fault::Denied => 0x7002,
        Fault::Timeout
        | Fault::Absent
        | Fault::Busy
        | Fault::Oversized
        | Fault::NotBroadcast
        | Fault::Other => 0x8000,
    }
}

fn foe(fault: Fault) -> u32 {
    match fault {
        Fault::UnknownAddress | Fault::Denied => 0x8002,
        Fault::Unsupported | Fault::NotRunning => 0x8001,
        Fault::Timeout
        | Fault::Absent
        | Fault::Busy
        | Fault::Oversized
        | Fault::NotBroadcast
        | Fault::Other => 0x8000,
    }
}

fn other(fault: Fault) -> u16 {
    match fault {
        Fault::UnknownAddress | Fault::Unsupported | Fault::NotRunning | Fault::Denied => 0x0001,
        Fault::Timeout | Fault::Absent => 0x0003,
        Fault::Busy | Fault::Oversized | Fault::NotBroadcast | Fault::Other => 0x0000,
    }
}

/// A mailbox error message carrying `code` (type 0x0001, then the code, little endian).
fn code_error(code: u16) -> (MailboxType, Vec<u8>) {
    let mut data = vec![0x01, 0x00];
    data.extend_from_slice(&code.to_le_bytes());
    (MailboxType::Error, data)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn answer_to(ty: MailboxType, data: &[u8], fault: Fault) -> Option<(MailboxType, Vec<u8>)> {
        answer(&Ask::read(ty, data), fault)
    }

    #[test]
    fn the_manuals_codes_are_used() {
        let upload = [0x00, 0x20, 0x40, 0x40, 0x60, 0x00, 0, 0, 0, 0];
        let (_, data) = answer_to(MailboxType::Coe, &upload, Fault::Denied).unwrap();
        assert_eq!(data[2], 0x80);
        assert_eq!(data[6..10], 0x0601_0002u32.to_le_bytes());
        let write = [0x03, 0x40, 0x20, 0x00, 1, 0];
        let (_, data) = answer_to(MailboxType::Soe, &write, Fault::Denied).unwrap();
        assert_eq!(data[0], 0x14);
        assert_eq!(data[4..6], 0x7002u16.to_le_bytes());
        let (_, data) = answer_to(MailboxType::Foe, &[], Fault::UnknownAddress).unwrap();
        assert_eq!(data[2..6], 0x8002u32.to_le_bytes());
        let (ty, data) = answer_to(MailboxType::Voe, &[], Fault::Timeout).unwrap();
        assert_eq!((ty, data), (MailboxType::Error, vec![1, 0, 3, 0]));
    }
}
