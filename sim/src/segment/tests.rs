//! Lines and rings: which slaves process a frame, in which order, and on which master port
//! it comes back (cable redundancy, ETG.1000.3 §4.2, ETG.1000.4 §6).

use ecat_link::MAX_FRAME_LEN;
use ecat_wire::command::{Command, DatagramAddress};
use ecat_wire::datagram::{DatagramRepr, FrameBuilder};
use ecat_wire::frame::EthercatFrame;
use ecat_wire::register::dl::DlStatus;

use super::{Port, Segment};
use crate::esc::test_support::slave;
use crate::esc::{DcConfig, ManualTime};

const N: usize = 5;
const MASTER_MAC: [u8; 6] = [0x02, 0x01, 0x01, 0x01, 0x01, 0x01];

/// `n` test slaves, wired as a ring or a line.
fn segment(n: usize, ring: bool) -> Segment {
    let mut segment = Segment::default();
    for _ in 0..n {
        let (esc, device) = slave();
        segment.push(esc, Box::new(device));
    }
    segment.set_ring(ring);
    segment
}

/// One datagram as sent: command, raw address, data.
struct Dg(Command, DatagramAddress, Vec<u8>);

fn brd(ado: u16, len: usize) -> Dg {
    Dg(Command::Brd, DatagramAddress::broadcast(ado), vec![0; len])
}

fn aprd(position: u16, ado: u16, len: usize) -> Dg {
    Dg(
        Command::Aprd,
        DatagramAddress::position(position, ado),
        vec![0; len],
    )
}

fn apwr(position: u16, ado: u16, data: &[u8]) -> Dg {
    Dg(
        Command::Apwr,
        DatagramAddress::position(position, ado),
        data.to_vec(),
    )
}

fn frame(datagrams: &[Dg]) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let mut builder = FrameBuilder::new(&mut buf).unwrap();
    for (i, Dg(command, address, data)) in datagrams.iter().enumerate() {
        builder
            .push(&DatagramRepr::request(*command, i as u8, *address, data))
            .unwrap();
    }
    let len = builder.finish(MASTER_MAC).unwrap();
    buf.truncate(len);
    buf
}

/// (wkc, data) of every datagram of a frame.
type Replies = Vec<(u16, Vec<u8>)>;

/// The replies in a returned frame.
fn replies(frame: &[u8]) -> Replies {
    EthercatFrame::parse(frame)
        .unwrap()
        .datagrams()
        .unwrap()
        .map(|d| {
            let d = d.unwrap();
            (d.wkc, d.data.to_vec())
        })
        .collect()
}

/// Sends `datagrams` on `port`; the return port and the replies.
fn send(segment: &mut Segment, port: Port, datagrams: &[Dg]) -> Option<(Port, Replies)> {
    let mut buf = frame(datagrams);
    let exit = segment.process_from(port, &mut buf)?;
    assert_eq!(
        buf[6] & 0x02,
        0x02,
        "returned frames carry the returned-MAC bit"
    );
    Some((exit, replies(&buf)))
}

/// The working counter of a BRD sent on `port`, and where it came back.
fn count(segment: &mut Segment, port: Port) -> Option<(Port, u16)> {
    send(segment, port, &[brd(0x0000, 2)]).map(|(exit, r)| (exit, r[0].0))
}

/// Gives slave `p` station address 0x1000 + p, position by position on the primary port
/// of the whole (unbroken) segment.
fn assign_stations(segment: &mut Segment) {
    for p in 0..segment.len() {
        let station = 0x1000 + p as u16;
        let (_, r) = send(
            segment,
            Port::Primary,
            &[apwr(p as u16, 0x0010, &station.to_le_bytes())],
        )
        .unwrap();
        assert_eq!(r[0].0, 1, "slave {p} addressed");
    }
}

/// The station address an APRD of 0x0010 at `position` reads when sent on `port`.
fn station_at(segment: &mut Segment, port: Port, position: u16) -> (Port, u16, u16) {
    let (exit, r) = send(segment, port, &[aprd(position, 0x0010, 2)]).unwrap();
    (exit, r[0].0, u16::from_le_bytes([r[0].1[0], r[0].1[1]]))
}

#[test]
fn a_closed_ring_processes_primary_frames_and_returns_them_on_the_backup_port() {
    let mut ring = segment(N, true);
    assert!(ring.is_ring());
    assert_eq!(
        count(&mut ring, Port::Primary),
        Some((Port::Backup, N as u16))
    );
    // The backup frame runs backwards through every slave untouched.
    let sent = frame(&[brd(0x0130, 2), aprd(0, 0x0010, 2)]);
    let mut buf = sent.clone();
    assert_eq!(
        ring.process_from(Port::Backup, &mut buf),
        Some(Port::Primary)
    );
    assert_eq!(&buf[12..], &sent[12..], "unprocessed: data and wkc as sent");
    assert_eq!(replies(&buf)[0].0, 0);
    // `process` only reports frames back on the primary port, which no longer happens.
    let mut buf = frame(&[brd(0x0000, 2)]);
    assert!(!ring.process(&mut buf));
    assert_eq!(replies(&buf)[0].0, N as u16, "processed all the same");
    assert_eq!(ring.reachable(), N);
}

#[test]
fn a_break_after_k_slaves_splits_the_ring_in_two_lines() {
    for k in 1..N {
        let mut ring = segment(N, true);
        assign_stations(&mut ring);
        ring.break_cable(k).unwrap();
        assert_eq!(
            count(&mut ring, Port::Primary),
            Some((Port::Primary, k as u16)),
            "break after {k}: primary"
        );
        assert_eq!(
            count(&mut ring, Port::Backup),
            Some((Port::Backup, (N - k) as u16)),
            "break after {k}: backup"
        );
        assert_eq!(ring.reachable(), k);
        // Position addressing on the backup frame counts from the first slave behind the
        // break, in the primary direction.
        assert_eq!(
            station_at(&mut ring, Port::Backup, 0),
            (Port::Backup, 1, 0x1000 + k as u16)
        );
        if k + 1 < N {
            assert_eq!(
                station_at(&mut ring, Port::Backup, 1),
                (Port::Backup, 1, 0x1001 + k as u16)
            );
        }
        assert_eq!(
            station_at(&mut ring, Port::Primary, 0),
            (Port::Primary, 1, 0x1000)
        );
    }
}

#[test]
fn the_frame_passes_the_slaves_behind_a_break_in_primary_order() {
    // An APWR then an APRD of the same register at position 1 in one frame: the slave the
    // write reaches is the one the read then reads, the second behind the break.
    let mut ring = segment(N, true);
    assign_stations(&mut ring);
    ring.break_cable(2).unwrap();
    let (exit, r) = send(
        &mut ring,
        Port::Backup,
        &[apwr(1, 0x0010, &[0x34, 0x12]), aprd(1, 0x0010, 2)],
    )
    .unwrap();
    assert_eq!(exit, Port::Backup);
    assert_eq!(
        (r[0].0, r[1].0, r[1].1.as_slice()),
        (1, 1, &[0x34, 0x12][..])
    );
    assert_eq!(ring.esc(3).unwrap().station_address(), 0x1234);
    assert_eq!(ring.esc(2).unwrap().station_address(), 0x1002);
}

#[test]
fn cutting_either_master_cable_loses_that_ports_frames() {
    let mut ring = segment(N, true);
    ring.break_cable(0).unwrap();
    let mut buf = frame(&[brd(0x0000, 2)]);
    let sent = buf.clone();
    assert_eq!(ring.process_from(Port::Primary, &mut buf), None);
    assert_eq!(buf, sent, "a lost frame is left untouched");
    assert_eq!(
        count(&mut ring, Port::Backup),
        Some((Port::Backup, N as u16))
    );

    let mut ring = segment(N, true);
    ring.break_cable(N).unwrap();
    assert_eq!(count(&mut ring, Port::Backup), None);
    assert_eq!(
        count(&mut ring, Port::Primary),
        Some((Port::Primary, N as u16))
    );
}

#[test]
fn a_dead_slave_neither_processes_nor_forwards() {
    for p in 0..N {
        let mut ring = segment(N, true);
        ring.kill(p).unwrap();
        assert!(!ring.slave(p).unwrap().is_powered());
        let primary = (p > 0).then_some((Port::Primary, p as u16));
        assert_eq!(count(&mut ring, Port::Primary), primary, "kill {p}");
        let backup = (p + 1 < N).then_some((Port::Backup, (N - p - 1) as u16));
        assert_eq!(count(&mut ring, Port::Backup), backup, "kill {p}");
    }
    let mut ring = segment(N, true);
    assert!(ring.kill(N).is_err());
    assert_eq!(
        count(&mut ring, Port::Primary),
        Some((Port::Backup, N as u16))
    );
}

#[test]
fn heal_reconnects_every_cable_and_powers_every_slave_up_in_init() {
    let mut ring = segment(N, true);
    assign_stations(&mut ring);
    ring.break_cable(1).unwrap();
    ring.break_cable(N).unwrap();
    ring.kill(3).unwrap();
    assert_eq!(count(&mut ring, Port::Primary), Some((Port::Primary, 1)));
    assert_eq!(count(&mut ring, Port::Backup), None);
    ring.heal();
    assert_eq!(
        count(&mut ring, Port::Primary),
        Some((Port::Backup, N as u16))
    );
    assert!(ring.slave(3).unwrap().is_powered());
    assert_eq!(ring.esc(3).unwrap().station_address(), 0, "power-on values");
    assert_eq!(ring.esc(3).unwrap().read_u16(0x0130), 0x0001, "INIT");
    assert_eq!(
        ring.esc(2).unwrap().station_address(),
        0x1002,
        "others kept theirs"
    );
    for p in 0..N {
        let dl = DlStatus::decode(ring.esc(p).unwrap().read_u16(0x0110));
        assert!(dl.ports[0].link && dl.ports[1].link, "slave {p} links up");
    }
}

#[test]
fn dl_status_shows_the_ports_a_break_took_the_link_from() {
    let mut ring = segment(N, true);
    let dl = |ring: &Segment, p: usize| DlStatus::decode(ring.esc(p).unwrap().read_u16(0x0110));
    let last = dl(&ring, N - 1);
    assert!(
        last.ports[1].link && !last.ports[1].loop_closed,
        "the ring's last port 1"
    );
    assert_eq!(last.active_ports(), 2);
    ring.break_cable(2).unwrap();
    let before = dl(&ring, 1);
    assert!(!before.ports[1].link && before.ports[1].loop_closed);
    assert!(before.ports[0].link);
    let behind = dl(&ring, 2);
    assert!(!behind.ports[0].link && behind.ports[0].loop_closed);
    assert!(behind.ports[1].link);
    assert_eq!(
        ring.esc(1).unwrap().read_u8(0x0311),
        1,
        "lost link on port 1"
    );
    assert_eq!(
        ring.esc(2).unwrap().read_u8(0x0310),
        1,
        "lost link on port 0"
    );
    // Read over the wire from the backup side, as a master would.
    let (exit, r) = send(&mut ring, Port::Backup, &[aprd(0, 0x0110, 2)]).unwrap();
    assert_eq!(exit, Port::Backup);
    let seen = DlStatus::decode(u16::from_le_bytes([r[0].1[0], r[0].1[1]]));
    assert!(!seen.ports[0].link && seen.ports[1].link);
    // A kill takes the links of both neighbours.
    ring.heal();
    ring.kill(3).unwrap();
    assert!(!dl(&ring, 2).ports[1].link);
    assert!(!dl(&ring, 4).ports[0].link);
    assert!(ring.break_cable(N + 1).is_err());
}

#[test]
fn a_line_behaves_as_before_rings() {
    let mut line = segment(N, false);
    assert!(!line.is_ring());
    assert_eq!(
        count(&mut line, Port::Primary),
        Some((Port::Primary, N as u16))
    );
    assert_eq!(count(&mut line, Port::Backup), None, "no backup cable");
    let last = DlStatus::decode(line.esc(N - 1).unwrap().read_u16(0x0110));
    assert!(!last.ports[1].link && last.ports[1].loop_closed);
    let err = line.break_cable(N).unwrap_err();
    assert!(err.contains("line"), "{err}");
    line.break_cable(3).unwrap();
    assert_eq!(count(&mut line, Port::Primary), Some((Port::Primary, 3)));
    line.set_plugged(3, true);
    assert_eq!(
        count(&mut line, Port::Primary),
        Some((Port::Primary, N as u16))
    );
    line.set_ring(true);
    assert_eq!(
        count(&mut line, Port::Primary),
        Some((Port::Backup, N as u16))
    );
}

#[test]
fn timing_accumulates_hop_delays_along_the_reversed_path() {
    // Slave p's cable costs 100 * (p + 1) ns. Break after 2 of 4 slaves: the backup frame
    // crosses the backup cable (slave 3's delay), cable 3 and reaches slave 2's port 1 at
    // 400 + 400; slave 2's port 0 is closed, so its processing unit sees the frame then;
    // slave 3 gets it back at 800 + 400 = 1200 after seeing it at port 1 at 400.
    let time = ManualTime::new(0);
    let mut ring = Segment::new(Box::new(time.clone()));
    for p in 0..4u32 {
        let (mut esc, device) = slave();
        esc.set_dc_config(DcConfig {
            hop_delay_ns: 100 * (p + 1),
            ..DcConfig::default()
        });
        ring.push(esc, Box::new(device));
    }
    ring.set_ring(true);
    ring.break_cable(2).unwrap();
    let mut route = super::route::Route::default();
    route.plan(&ring, Port::Backup, 0);
    let timing: Vec<_> = route
        .processed()
        .iter()
        .map(|(p, t)| (*p, t.port0_ns, t.port1_ns))
        .collect();
    assert_eq!(timing, vec![(2, 800, Some(800)), (3, 1200, Some(400))]);
    assert_eq!(route.exit(), Some(Port::Backup));
    // The primary frame in the same ring: a line of two, mirrored as in a line.
    route.plan(&ring, Port::Primary, 0);
    let timing: Vec<_> = route
        .processed()
        .iter()
        .map(|(p, t)| (*p, t.port0_ns, t.port1_ns))
        .collect();
    assert_eq!(timing, vec![(0, 100, Some(500)), (1, 300, None)]);
}
