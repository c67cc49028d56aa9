//! The `mailbox.start` knob: the SII announces the mailbox where the description says, and
//! a start the ESC's RAM does not cover makes a slave that refuses INIT → PREOP with AL
//! status code 0x0016 although the master configures exactly what the SII announces.

use ecat_wire::command::{Command, DatagramAddress};
use ecat_wire::datagram::{DatagramRepr, FrameBuilder};
use ecat_wire::frame::EthercatFrame;
use ecat_wire::register::{AlState, AlStatusCode, SyncManager, SyncManagerRepr};
use ecat_wire::sii::SiiImage;
use sim::segment::Segment;
use sim::topology::{Topology, build};

const STATION: u16 = 0x1001;

/// Runs one datagram through the segment; returns (data, wkc).
fn exchange(
    segment: &mut Segment,
    command: Command,
    address: DatagramAddress,
    data: &[u8],
) -> (Vec<u8>, u16) {
    let mut buf = vec![0u8; 1514];
    let mut builder = FrameBuilder::new(&mut buf).unwrap();
    builder
        .push(&DatagramRepr::request(command, 0, address, data))
        .unwrap();
    let len = builder.finish([2, 0, 0, 0, 0, 1]).unwrap();
    buf.truncate(len);
    assert!(segment.process(&mut buf));
    let frame = EthercatFrame::parse(&buf).unwrap();
    let d = frame.datagrams().unwrap().next().unwrap().unwrap();
    (d.data.to_vec(), d.wkc)
}

/// The CoE store of the default segment with its mailbox moved to `start`.
fn store_with_mailbox_at(start: u16) -> (Topology, Segment) {
    let mut slave = Topology::default_segment().slaves[3].clone();
    slave.mailbox.as_mut().unwrap().start = Some(start);
    let topology = Topology {
        ring: false,
        slaves: vec![slave],
    };
    let segment = build(&topology).unwrap();
    (topology, segment)
}

/// Configures SM0/SM1 exactly as the SII says and requests PREOP; returns the AL status.
fn preop_as_the_sii_says(segment: &mut Segment) -> (AlState, bool, AlStatusCode) {
    let sii = SiiImage::parse(segment.esc(0).unwrap().sii()).unwrap();
    let (rx, tx) = (sii.fixed.std_rx_mailbox, sii.fixed.std_tx_mailbox);
    let mut sms = [0u8; 16];
    SyncManagerRepr::mailbox_out(rx.offset, rx.size)
        .emit(&mut SyncManager::new_unchecked(&mut sms[..8]))
        .unwrap();
    SyncManagerRepr::mailbox_in(tx.offset, tx.size)
        .emit(&mut SyncManager::new_unchecked(&mut sms[8..]))
        .unwrap();
    let node = |ado| DatagramAddress::Node {
        station: STATION,
        ado,
    };
    exchange(
        segment,
        Command::Apwr,
        DatagramAddress::position(0, 0x0010),
        &STATION.to_le_bytes(),
    );
    assert_eq!(exchange(segment, Command::Fpwr, node(0x0800), &sms).1, 1);
    assert_eq!(
        exchange(segment, Command::Fpwr, node(0x0120), &[0x02, 0x00]).1,
        1
    );
    let esc = segment.esc(0).unwrap();
    (esc.al_state(), esc.al_status().error, esc.al_status_code())
}

#[test]
fn the_sii_announces_the_configured_mailbox_start() {
    let (topology, segment) = store_with_mailbox_at(0x1400);
    let sii = SiiImage::parse(segment.esc(0).unwrap().sii()).unwrap();
    let m = topology.slaves[0].mailbox.unwrap();
    assert_eq!(sii.fixed.std_rx_mailbox.offset, 0x1400);
    assert_eq!(sii.fixed.std_tx_mailbox.offset, 0x1400 + m.rx_size);
    assert_eq!(sii.syncm[0].start, 0x1400);
    assert_eq!(sii.syncm[1].start, 0x1400 + m.rx_size);
    // Inside the RAM, it works.
    let mut segment = segment;
    assert_eq!(
        preop_as_the_sii_says(&mut segment),
        (AlState::PreOp, false, AlStatusCode::NoError)
    );
}

#[test]
fn a_mailbox_outside_the_ram_is_refused_with_0x0016() {
    let ram_end = 0x1000 + Topology::default_segment().slaves[3].esc.ram_kib * 1024;
    let (_, mut segment) = store_with_mailbox_at(ram_end);
    assert_eq!(
        preop_as_the_sii_says(&mut segment),
        (AlState::Init, true, AlStatusCode::InvalidMailboxConfigPreop)
    );
}
