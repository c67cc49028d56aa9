//! The ring link against a stand-in ring: two queues and a few slaves that count
//! themselves in every datagram (the simulator's real ring is exercised by the master's
//! integration tests).

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use super::*;
use crate::wire::command::{Command, DatagramAddress};
use crate::wire::datagram::{DatagramRepr, DatagramsMut};
use crate::wire::ethernet;
use crate::wire::frame::FrameBuilder;

/// The wiring of the stand-in: `slaves` in a ring, cut after `cut` of them (or whole), and
/// whether each master port's own cable is plugged.
#[derive(Debug)]
struct Wiring {
    slaves: usize,
    cut: Option<usize>,
    queues: [VecDeque<Vec<u8>>; 2],
    /// While set, what would come back on the backup port is held here instead (a copy
    /// late, or a way with no link).
    hold_backup: Option<VecDeque<Vec<u8>>>,
}

#[derive(Debug, Clone)]
struct Port {
    side: Side,
    wiring: Arc<Mutex<Wiring>>,
}

/// Each slave that processes a datagram adds 1 to its working counter and, for a
/// broadcast read, ORs the bit of its position into the first byte.
fn process(frame: &mut [u8], positions: std::ops::Range<usize>) {
    let parsed = EthercatFrame::parse(frame).unwrap();
    let (start, end) = (
        parsed.payload_offset,
        parsed.payload_offset + parsed.payload.len(),
    );
    for d in DatagramsMut::new(&mut frame[start..end]) {
        let mut d = d.unwrap();
        if d.command() == Command::Nop {
            continue;
        }
        for position in positions.clone() {
            let w = d.wkc();
            d.set_wkc(w + 1);
            if d.command() == Command::Brd && !d.data().is_empty() {
                d.data_mut()[0] |= 1 << position;
            }
        }
    }
}

impl Link for Port {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        let mut w = self.wiring.lock().unwrap();
        let mut frame = frame.to_vec();
        let n = w.slaves;
        let back = match (self.side, w.cut) {
            (Side::Primary, None) => {
                process(&mut frame, 0..n);
                Side::Backup
            }
            (Side::Backup, None) => Side::Primary,
            (Side::Primary, Some(0)) => return Ok(()),
            (Side::Primary, Some(k)) => {
                process(&mut frame, 0..k);
                Side::Primary
            }
            (Side::Backup, Some(k)) => {
                process(&mut frame, k..n);
                Side::Backup
            }
        };
        match (&mut w.hold_backup, back) {
            (Some(held), Side::Backup) => held.push_back(frame),
            _ => w.queues[back as usize].push_back(frame),
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], _wait: Wait) -> io::Result<Option<usize>> {
        let mut w = self.wiring.lock().unwrap();
        Ok(w.queues[self.side as usize].pop_front().map(|f| {
            buf[..f.len()].copy_from_slice(&f);
            f.len()
        }))
    }
}

fn ring(slaves: usize) -> (RingLink<Port, Port>, Arc<Mutex<Wiring>>) {
    let wiring = Arc::new(Mutex::new(Wiring {
        slaves,
        cut: None,
        queues: [VecDeque::new(), VecDeque::new()],
        hold_backup: None,
    }));
    let port = |side| Port {
        side,
        wiring: Arc::clone(&wiring),
    };
    (
        RingLink::new(port(Side::Primary), port(Side::Backup), Duration::ZERO),
        wiring,
    )
}

fn brd(index: u8) -> Vec<u8> {
    let mut buf = vec![0u8; ethernet::MAX_FRAME_LEN];
    let mut builder = FrameBuilder::new(&mut buf).unwrap();
    builder
        .push(&DatagramRepr::request(
            Command::Brd,
            index,
            DatagramAddress::broadcast(0x0130),
            &[0, 0],
        ))
        .unwrap();
    let len = builder.finish([2, 0, 0, 0, 0, 1]).unwrap();
    buf.truncate(len);
    buf
}

/// Sends a BRD and returns what came back: (first data byte, working counter).
fn round_trip(link: &mut RingLink<Port, Port>, index: u8) -> Option<(u8, u16)> {
    link.send(&brd(index)).unwrap();
    let mut buf = [0u8; MAX_FRAME_LEN];
    let len = link.recv(&mut buf, Wait::NoWait).unwrap()?;
    let parsed = EthercatFrame::parse(&buf[..len]).unwrap();
    let mut all = parsed.datagrams().unwrap();
    let d = all.next().unwrap().unwrap();
    assert!(all.next().is_none(), "no probe handed up");
    assert_eq!(len, brd(index).len());
    Some((d.data[0], d.wkc))
}

#[test]
fn a_closed_ring_answers_through_the_backup_port_and_is_seen_closed() {
    let (mut link, _) = ring(5);
    assert_eq!(round_trip(&mut link, 1), Some((0b1_1111, 5)));
    let status = link.watch().status();
    assert_eq!(status.state, RingState::Closed);
    assert_eq!((status.primary_side, status.ring_slaves), (5, 5));
}

/// A ring of `slaves` seen closed by one frame, then cut after `cut` of them, and a second
/// frame (index 2) that meets the cut: it already reaches everyone, from both sides.
fn cut_ring(slaves: usize, cut: usize) -> (RingLink<Port, Port>, Arc<Mutex<Wiring>>) {
    let (mut link, wiring) = ring(slaves);
    round_trip(&mut link, 1).unwrap();
    wiring.lock().unwrap().cut = Some(cut);
    let everyone = (1u8 << slaves) - 1;
    assert_eq!(
        round_trip(&mut link, 2),
        Some((everyone, slaves as u16)),
        "cut {cut}"
    );
    (link, wiring)
}

#[test]
fn every_break_is_located_served_from_both_sides_and_healed() {
    for cut in 0..=5 {
        let (mut link, wiring) = cut_ring(5, cut);
        let status = link.watch().status();
        assert_eq!(status.state, RingState::Broken, "cut {cut}");
        assert_eq!(status.break_after, Some(cut as u16));
        assert_eq!(status.backup_side, 5 - cut as u16);
        assert_eq!((status.breaks, status.unreachable), (1, 0));
        assert_eq!(round_trip(&mut link, 3), Some((0b1_1111, 5)));
        wiring.lock().unwrap().cut = None;
        assert_eq!(round_trip(&mut link, 4), Some((0b1_1111, 5)));
        let status = link.watch().status();
        assert_eq!(status.state, RingState::Closed, "healed after cut {cut}");
        assert_eq!(status.heals, 1);
    }
}

#[test]
fn a_lost_copy_is_waited_for_once_then_not_expected() {
    let (mut link, _) = cut_ring(3, 0);
    assert_eq!(link.watch().status().single_returns, 1);
    assert!(!link.expect[0], "the primary copy is not expected any more");
    assert_eq!(round_trip(&mut link, 3), Some((0b111, 3)));
}

#[test]
fn a_copy_late_past_the_grace_makes_its_frame_lost_not_short() {
    let (mut link, wiring) = cut_ring(5, 2);
    // The backup copy, processed by slaves 2 to 4, comes back after the grace (none here).
    wiring.lock().unwrap().hold_backup = Some(VecDeque::new());
    assert_eq!(
        round_trip(&mut link, 3),
        None,
        "a frame without what slaves 2 to 4 did (0b00011, 2) looks lost to the bus"
    );
    let status = link.watch().status();
    assert_eq!((status.single_returns, status.incomplete), (1, 1));
    assert_eq!(
        status.break_after,
        Some(2),
        "nothing learned from a short frame"
    );
    // The late copy comes: too late for its frame, but its way is expected again.
    let late = {
        let mut w = wiring.lock().unwrap();
        let late = w.hold_backup.take().unwrap();
        w.queues[Side::Backup as usize].extend(late);
        w.queues[Side::Backup as usize].len()
    };
    assert_eq!(late, 1);
    assert_eq!(round_trip(&mut link, 4), Some((0b1_1111, 5)));
    assert_eq!(link.watch().status().incomplete, 1);
}

#[test]
fn a_way_with_nothing_back_for_gone_after_is_given_up() {
    let (mut link, wiring) = ring(5);
    link.gone_after = Duration::from_millis(5);
    // Before the last backup copy comes back.
    let start = Instant::now();
    round_trip(&mut link, 1).unwrap();
    // The last slave loses power: its neighbour loops back, the backup port gets nothing.
    {
        let mut w = wiring.lock().unwrap();
        w.cut = Some(4);
        w.hold_backup = Some(VecDeque::new());
    }
    let mut lost = 0u32;
    let mut index = 2u8;
    let back = loop {
        assert!(start.elapsed() < Duration::from_secs(5), "never given up");
        index = index.wrapping_add(1).max(2);
        match round_trip(&mut link, index) {
            Some(back) => break back,
            None => lost += 1,
        }
    };
    assert!(start.elapsed() >= link.gone_after);
    assert!(lost >= 1, "the first frame without the backup copy is lost");
    assert_eq!(back, (0b0_1111, 4));
    let status = link.watch().status();
    assert_eq!((status.break_after, status.unreachable), (Some(4), 1));
    assert_eq!(status.incomplete, u64::from(lost));
    // From then on the short copy is the frame, at once.
    assert_eq!(round_trip(&mut link, 1), Some((0b0_1111, 4)));
}

/// A port that hands out the frames it was given, whatever they hold.
struct Replay(VecDeque<Vec<u8>>);

impl Link for Replay {
    fn send(&mut self, _frame: &[u8]) -> io::Result<()> {
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], _wait: Wait) -> io::Result<Option<usize>> {
        Ok(self.0.pop_front().map(|f| {
            let n = f.len().min(buf.len());
            buf[..n].copy_from_slice(&f[..n]);
            n
        }))
    }
}

mod damaged {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Whatever comes back on either port (a damaged copy of a frame in flight, or any
        /// bytes at all), the ring link hands up at most one frame per frame received and
        /// never panics.
        #[test]
        fn damaged_or_foreign_returns_never_panic(
            flips in proptest::collection::vec((0usize..200, any::<u8>()), 0..12),
            junk in proptest::collection::vec(any::<u8>(), 0..300),
            cut in 0usize..120,
        ) {
            let sent = brd(5);
            // A closed ring's copies as they would come back, then damaged.
            let (mut good, _) = ring(3);
            good.send(&sent).unwrap();
            let (p, b) = {
                let (primary, backup) = good.into_inner();
                let mut w = primary.wiring.lock().unwrap();
                let _ = backup;
                (w.queues[1].pop_front().unwrap(), w.queues[0].pop_front().unwrap())
            };
            let mut damaged_p = p.clone();
            for (at, value) in &flips {
                if let Some(byte) = damaged_p.get_mut(*at) {
                    *byte ^= value;
                }
            }
            let mut short_b = b.clone();
            short_b.truncate(cut.min(short_b.len()));
            let mut link = RingLink::new(
                Replay(VecDeque::from(vec![short_b, junk.clone()])),
                Replay(VecDeque::from(vec![damaged_p, junk])),
                Duration::ZERO,
            );
            link.send(&sent).unwrap();
            let mut buf = [0u8; MAX_FRAME_LEN];
            for _ in 0..6 {
                if let Some(len) = link.recv(&mut buf, Wait::NoWait).unwrap() {
                    prop_assert!(len <= MAX_FRAME_LEN);
                }
            }
        }
    }
}
