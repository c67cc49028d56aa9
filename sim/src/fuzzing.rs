//! The segment's frame processing driven by arbitrary bytes, for the fuzz target
//! `sim_segment` (fuzz/) and the corpus replay test: a sequence of EtherCAT payloads, each
//! sent in a well-formed frame through the built-in segment, with time moving on between
//! frames. The payloads are anything (datagram chains that lie about their lengths, writes
//! to any register, mailbox and EEPROM traffic, AL control), so every ESC function a master
//! can reach is exercised.

use ecat_wire::command::{AddressingMode, Command};
use ecat_wire::datagram::{DatagramRepr, Datagrams};
use ecat_wire::frame::EthercatFrame;

use crate::topology::{Topology, build_with_handles};

/// Ethernet header (broadcast destination, a locally administered source, EtherType
/// 0x88A4) and EtherCAT header length.
const HEADERS: usize = 14 + 2;
/// The longest EtherCAT payload in a standard frame (1500 bytes less the EtherCAT header).
const MAX_PAYLOAD: usize = 1498;
/// Time between two frames: a cycle of 1 ms.
const CYCLE_NS: u64 = 1_000_000;

/// The frame that carries `payload`, padded to the Ethernet minimum.
fn frame(payload: &[u8]) -> Vec<u8> {
    let mut frame = vec![0xFF; 6];
    frame.extend_from_slice(&[0x02, 0, 0, 0, 0, 0x01]);
    frame.extend_from_slice(&[0x88, 0xA4]);
    // Length (11 bits) and type 1, EtherCAT datagrams (ETG.1000.4, spec-notes §frame).
    let header = (payload.len() as u16) | 0x1000;
    frame.extend_from_slice(&header.to_le_bytes());
    frame.extend_from_slice(payload);
    frame.resize(frame.len().max(60), 0);
    frame
}

/// What a slave never changes in a datagram: command, index, length, the M flag, and the
/// address of node and logical commands (position and broadcast commands get ADP
/// incremented).
fn fixed(d: &DatagramRepr<'_>) -> (Command, u8, usize, bool, Option<u32>) {
    let address = match d.command.addressing() {
        AddressingMode::Position | AddressingMode::Broadcast => None,
        _ => Some(d.address),
    };
    (d.command, d.index, d.data.len(), d.more, address)
}

fn headers(frame: &[u8]) -> Vec<(Command, u8, usize, bool, Option<u32>)> {
    let Ok(parsed) = EthercatFrame::parse(frame) else {
        return Vec::new();
    };
    Datagrams::new(parsed.payload)
        .map_while(Result::ok)
        .map(|d| fixed(&d))
        .collect()
}

/// Runs the payloads in `data` (each a little-endian length and that many bytes) through a
/// fresh built-in segment. Panics if a frame is not processed, changes length, or comes
/// back with datagram headers a slave must not touch changed.
#[doc(hidden)]
pub fn frames(data: &[u8]) {
    let mut built = build_with_handles(&Topology::default_segment()).expect("default segment");
    let mut rest = data;
    while let Some((len, tail)) = rest.split_first_chunk::<2>() {
        let len = usize::from(u16::from_le_bytes(*len))
            .min(tail.len())
            .min(MAX_PAYLOAD);
        let (payload, next) = tail.split_at(len);
        rest = next;
        let mut bytes = frame(payload);
        let before = headers(&bytes);
        let length = bytes.len();
        assert!(
            built.segment.process(&mut bytes),
            "a datagram frame was refused"
        );
        assert_eq!(bytes.len(), length);
        assert_eq!(headers(&bytes), before, "datagram headers changed");
        assert_eq!(
            bytes[HEADERS - 2..HEADERS],
            frame(payload)[HEADERS - 2..HEADERS]
        );
        built.time.advance(CYCLE_NS);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_broadcast_read_counts_every_slave() {
        // BRD of 2 bytes at 0x0000, index 7, wkc 0.
        let payload = [0x07, 0x07, 0, 0, 0, 0, 0x02, 0, 0, 0, 0, 0, 0, 0];
        let mut bytes = frame(&payload);
        let mut segment = build_with_handles(&Topology::default_segment())
            .unwrap()
            .segment;
        assert!(segment.process(&mut bytes));
        let parsed = EthercatFrame::parse(&bytes).unwrap();
        let d = Datagrams::new(parsed.payload).next().unwrap().unwrap();
        assert_eq!(d.wkc, 5);
        let mut input = (payload.len() as u16).to_le_bytes().to_vec();
        input.extend_from_slice(&payload);
        frames(&input);
    }
}
