//! Frames as other masters really send them, with their quirks: a real ESC processes them,
//! so the simulator must too.

use crate::segment_support;

use ecat_link::MAX_FRAME_LEN;
use ecat_wire::command::{Command, DatagramAddress};
use ecat_wire::datagram::{DatagramRepr, FrameBuilder};
use ecat_wire::frame::EthercatFrame;
use segment_support::*;

/// KickCAT leaves the reserved bits 11-13 of the datagram length field uninitialised (seen
/// as 0x9002 on the wire: M, bit 12, length 2). The ESC ignores them: every datagram of the
/// frame is processed, and the bits are forwarded unchanged.
#[test]
fn reserved_length_bits_are_ignored_and_forwarded() {
    let mut bench = Bench::new(3);
    bench.assign_addresses();
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let mut builder = FrameBuilder::new(&mut buf).unwrap();
    let mut offsets = Vec::new();
    for (i, p) in [0usize, 1, 2].into_iter().enumerate() {
        let address = DatagramAddress::Node {
            station: station(p),
            ado: 0x0010,
        };
        offsets.push(
            builder
                .push(&DatagramRepr::request(
                    Command::Fprd,
                    i as u8,
                    address,
                    &[0, 0],
                ))
                .unwrap(),
        );
    }
    let len = builder.finish([0, 0, 0, 0, 0, 1]).unwrap();
    // Bit 12 on the first two datagrams (high byte of the length field, offset 7).
    for offset in &offsets[..2] {
        buf[offset + 7] |= 0x10;
    }
    let frame = &mut buf[..len];
    assert!(bench.segment.process(frame));
    for (p, offset) in offsets.iter().enumerate() {
        let datagram = &frame[*offset..];
        let wkc = u16::from_le_bytes([datagram[12], datagram[13]]);
        let value = u16::from_le_bytes([datagram[10], datagram[11]]);
        assert_eq!((wkc, value), (1, station(p)), "datagram {p}");
    }
    assert_eq!(
        frame[offsets[0] + 7] & 0x38,
        0x10,
        "bits forwarded unchanged"
    );
    // The frame is otherwise as a master expects it.
    assert!(EthercatFrame::parse(frame).is_ok());
}
