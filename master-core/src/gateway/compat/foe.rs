//! FoE in the compatibility layout: the manual's clients leave out the reserved byte that
//! follows the op code in the standard header (ETG.1000.6 §5.9.1, Table 86: op code, one
//! reserved byte, a 4-byte password / packet number / error code, then data), so the file
//! name of a read or write request starts at offset 5, and they end it with a NUL:
//!
//! ```text
//! byte 0    op code (1 read, 2 write, 3 data, 4 ack, 5 error, 6 busy: the standard's)
//! byte 1-4  password (requests; those clients send 0), packet number, error code
//! byte 5-   file name and a NUL (requests), data (data), error text (error)
//! ```
//!
//! Every FoE message is translated by putting the reserved byte back (or taking it out, for
//! replies); in a read or write request the name ends at its first NUL.

use crate::wire::foe::FoeOpcode;

/// Op code and the 4-byte field.
const COMPAT_HEADER: usize = 5;

/// The standard FoE message for the client's `data`; `None` if it is shorter than its
/// 5-byte header.
pub(super) fn to_standard(data: &[u8]) -> Option<Vec<u8>> {
    let header = data.get(..COMPAT_HEADER)?;
    let mut rest = &data[COMPAT_HEADER..];
    let opcode = FoeOpcode::from(header[0]);
    if matches!(opcode, FoeOpcode::ReadRequest | FoeOpcode::WriteRequest) {
        let end = rest.iter().position(|&b| b == 0).unwrap_or(rest.len());
        rest = &rest[..end];
    }
    let mut out = Vec::with_capacity(data.len() + 1);
    out.push(header[0]);
    out.push(0);
    out.extend_from_slice(&header[1..]);
    out.extend_from_slice(rest);
    Some(out)
}

/// The client's form of a standard FoE reply; `None` if it is shorter than the standard
/// 6-byte header.
pub(super) fn to_compat(data: &[u8]) -> Option<Vec<u8>> {
    let (&opcode, rest) = data.split_first()?;
    let rest = rest.get(1..)?;
    rest.get(..4)?;
    let mut out = Vec::with_capacity(data.len() - 1);
    out.push(opcode);
    out.extend_from_slice(rest);
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_manuals_read_of_firmware_bin_becomes_a_standard_read_request() {
        let mut request = vec![0x01, 0, 0, 0, 0];
        request.extend_from_slice(b"firmware.bin\0");
        let mut standard = vec![0x01, 0, 0, 0, 0, 0];
        standard.extend_from_slice(b"firmware.bin");
        assert_eq!(to_standard(&request).unwrap(), standard);
        assert_eq!(to_standard(&[0x01, 0, 0, 0]), None);
    }

    #[test]
    fn data_and_errors_come_back_without_the_reserved_byte() {
        // DATA packet 1 with 3 bytes.
        let reply = to_compat(&[0x03, 0x00, 1, 0, 0, 0, 7, 8, 9]).unwrap();
        assert_eq!(reply, [0x03, 1, 0, 0, 0, 7, 8, 9]);
        // An ACK from the client goes the other way, data untouched.
        assert_eq!(
            to_standard(&[0x04, 1, 0, 0, 0]).unwrap(),
            [0x04, 0, 1, 0, 0, 0]
        );
        assert_eq!(to_compat(&[0x05, 0, 2, 0, 0]), None);
    }
}
