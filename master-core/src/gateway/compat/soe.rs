//! SoE in the compatibility layout, as the manual's clients write it:
//!
//! ```text
//! byte 0    op code: 1 read, 2 write (reply: bit 3 incomplete, bit 4 error, as the standard)
//! byte 1    drive number << 3 | element number
//! byte 2-3  IDN (or, in a reply fragment, the fragments left)
//! byte 4-   value (write), element data (reply), or the error code (reply with bit 4)
//! ```
//!
//! The standard header (ETG.1000.6 §5.7.1, Table 54: op code in bits 2:0, incomplete bit 3,
//! error bit 4, drive number in bits 7:5 of byte 0; element flags in byte 1) names elements
//! by flags, where these clients use numbers. The mapping:
//!
//! | number | the manual's name | standard element flag |
//! |---|---|---|
//! | 0 | name | 0x02 name |
//! | 1 | attribute | 0x04 attribute |
//! | 2 | unit | 0x08 unit |
//! | 3 | minimum | 0x10 minimum input value |
//! | 4 | maximum | 0x20 maximum input value |
//! | 5 | value | 0x40 operation data |
//! | 6 | default | 0x80 default value |
//! | 7 | data type | 0x04 attribute: the standard has no element of its own for the data type, which is bits 22:20 (data type and display format) of the attribute; the reply carries the whole 4-byte attribute |
//!
//! The data state (0x01) has no number in that layout. Drive numbers above 7 do not fit the
//! standard header: such a request is malformed.

use crate::wire::soe::{ElementFlags, SoeOpcode};

/// The standard element flags of the manual's element numbers 0-7.
const ELEMENTS: [ElementFlags; 8] = [
    ElementFlags::NAME,
    ElementFlags::ATTRIBUTE,
    ElementFlags::UNIT,
    ElementFlags::MINIMUM,
    ElementFlags::MAXIMUM,
    ElementFlags::VALUE,
    ElementFlags::DEFAULT,
    ElementFlags::ATTRIBUTE,
];

/// The manual's op codes.
const READ: u8 = 1;
const WRITE: u8 = 2;

/// Bits of byte 0 the standard and this layout share.
const INCOMPLETE: u8 = 0x08;
const ERROR: u8 = 0x10;

/// The standard SoE request for the client's `data` and the client's byte 1; `None` if it
/// is malformed (shorter than 4 bytes, another op code, a drive number above 7, a value in a
/// read).
pub(super) fn to_standard(data: &[u8]) -> Option<(Vec<u8>, u8)> {
    let (&op, rest) = data.split_first()?;
    let (&element_byte, rest) = rest.split_first()?;
    let idn = rest.get(..2)?;
    let value = &rest[2..];
    let drive = element_byte >> 3;
    if drive > 7 {
        return None;
    }
    let opcode = match op {
        READ if value.is_empty() => SoeOpcode::ReadRequest,
        WRITE => SoeOpcode::WriteRequest,
        _ => return None,
    };
    let flags = ELEMENTS[usize::from(element_byte & 0x07)];
    let mut out = Vec::with_capacity(data.len());
    out.push(u8::from(opcode) | drive << 5);
    out.push(flags.bits());
    out.extend_from_slice(idn);
    out.extend_from_slice(value);
    Some((out, element_byte))
}

/// The client's form of a standard SoE reply; `element_byte` is the request's byte 1.
/// `None` if the reply is shorter than an SoE header.
pub(super) fn to_compat(data: &[u8], element_byte: u8) -> Option<Vec<u8>> {
    let (&byte0, rest) = data.split_first()?;
    let rest = rest.get(1..)?;
    let op = match SoeOpcode::from(byte0 & 0x07) {
        SoeOpcode::ReadResponse | SoeOpcode::ReadRequest => READ,
        SoeOpcode::WriteResponse | SoeOpcode::WriteRequest => WRITE,
        // Notifications and the like keep their standard op code.
        other => u8::from(other),
    };
    let mut out = Vec::with_capacity(data.len());
    out.push(op | (byte0 & (INCOMPLETE | ERROR)));
    out.push(element_byte);
    out.extend_from_slice(rest);
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_manuals_read_and_write_of_s_0_0032_become_standard_requests() {
        // soe_read(0x03E9, 32, drive 0, element 5).
        let (read, byte1) = to_standard(&[0x01, 0x05, 0x20, 0x00]).unwrap();
        assert_eq!(read, [0x01, 0x40, 0x20, 0x00]);
        assert_eq!(byte1, 0x05);
        // soe_write(0x03E9, 32, 1000u32, drive 0, element 5).
        let (write, _) = to_standard(&[0x02, 0x05, 0x20, 0x00, 0xE8, 0x03, 0, 0]).unwrap();
        assert_eq!(write, [0x03, 0x40, 0x20, 0x00, 0xE8, 0x03, 0, 0]);
        // Drive 2, element 0 (name) → drive bits 7:5, flag 0x02.
        let (name, _) = to_standard(&[0x01, 2 << 3, 0x01, 0x00]).unwrap();
        assert_eq!(name, [0x41, 0x02, 0x01, 0x00]);
        // Data type → the attribute.
        assert_eq!(to_standard(&[0x01, 0x07, 0x20, 0]).unwrap().0[1], 0x04);
    }

    #[test]
    fn malformed_requests_are_refused() {
        assert_eq!(to_standard(&[0x01, 0x05, 0x20]), None);
        assert_eq!(to_standard(&[0x03, 0x05, 0x20, 0x00]), None);
        assert_eq!(to_standard(&[0x01, 8 << 3, 0x20, 0x00]), None);
        assert_eq!(to_standard(&[0x01, 0x05, 0x20, 0x00, 1]), None);
    }

    #[test]
    fn replies_come_back_with_the_clients_op_code_and_element() {
        // Read response, drive 0, value, IDN 32, value 2.
        let reply = to_compat(&[0x02, 0x40, 0x20, 0x00, 0x02, 0x00], 0x05).unwrap();
        assert_eq!(reply, [0x01, 0x05, 0x20, 0x00, 0x02, 0x00]);
        // Write response with error 0x7004.
        let error = to_compat(&[0x14, 0x40, 0x20, 0x00, 0x04, 0x70], 0x05).unwrap();
        assert_eq!(error, [0x12, 0x05, 0x20, 0x00, 0x04, 0x70]);
        assert_eq!(to_compat(&[0x02], 0), None);
    }
}
