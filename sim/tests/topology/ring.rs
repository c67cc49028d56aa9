//! `ring = true`: the topology's last slave wired back to the master's backup port.

use ecat_wire::command::{Command, DatagramAddress};
use ecat_wire::datagram::{DatagramRepr, FrameBuilder};
use ecat_wire::frame::EthercatFrame;
use sim::segment::Port;
use sim::topology::{Topology, build};

const DEFAULT_TOML: &str = "topologies/default.toml";

fn default_text() -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_TOML);
    std::fs::read_to_string(path).unwrap()
}

#[test]
fn ring_is_a_top_level_key_that_wires_the_segment_as_a_ring() {
    let line = Topology::from_toml(&default_text()).unwrap();
    assert!(!line.ring, "a line unless the file says otherwise");
    assert!(!build(&line).unwrap().is_ring());

    let text = format!("ring = true\n{}", default_text());
    let ring = Topology::from_toml(&text).unwrap();
    assert!(ring.ring);
    assert_eq!(ring.slaves, line.slaves);
    let mut segment = build(&ring).unwrap();
    assert!(segment.is_ring());
    // A BRD sent on the primary port passes every slave and comes back on the backup port.
    let mut buf = [0u8; 64];
    let mut builder = FrameBuilder::new(&mut buf).unwrap();
    let brd = DatagramRepr::request(Command::Brd, 0, DatagramAddress::broadcast(0), &[0, 0]);
    builder.push(&brd).unwrap();
    let len = builder.finish([2, 1, 1, 1, 1, 1]).unwrap();
    let frame = &mut buf[..len];
    assert_eq!(
        segment.process_from(Port::Primary, frame),
        Some(Port::Backup)
    );
    let parsed = EthercatFrame::parse(frame).unwrap();
    let datagram = parsed.datagrams().unwrap().next().unwrap().unwrap();
    assert_eq!(usize::from(datagram.wkc), ring.slaves.len());
    // Round trip: the key is written only when set.
    assert!(ring.to_toml().unwrap().starts_with("ring = true"));
    assert!(!line.to_toml().unwrap().contains("ring ="));
}

#[test]
fn a_bad_ring_value_or_a_misspelt_key_is_refused() {
    let bad = format!("ring = \"yes\"\n{}", default_text());
    assert!(Topology::from_toml(&bad).is_err());
    let misspelt = format!("rings = true\n{}", default_text());
    let err = Topology::from_toml(&misspelt).unwrap_err().to_string();
    assert!(err.contains("rings"), "{err}");
}
