//! `BusHandle::submit_chain`: the bus thread sends each step of a chain in the next frame
//! out once the step before came back with its first datagram counted, and skips the rest
//! after one that did not count (the mailbox layer's writes of several messages into SM0,
//! spec-notes §mbx.chain).

use crate::bus_support;

use std::sync::{Arc, Mutex, PoisonError};

use bus_support::bus::{config, finish, start};
use bus_support::responder::{Script, answer};
use bus_support::segment::FakeSegment;
use master_core::bus::{BusError, Chained, DatagramRequest};
use master_core::link::Link;
use master_core::wire::frame::EthercatFrame;
use std::sync::mpsc;
use std::time::Duration;

const AT: u16 = 0x0F00;

/// Each frame's datagrams as they arrived: command byte and data.
type Seen = Arc<Mutex<Vec<Vec<(u8, Vec<u8>)>>>>;

/// Records every frame; frame number `empty` (from 0) comes back as it went, counted by no
/// slave; frame number `lost` never comes back.
struct Steps {
    seen: Seen,
    empty: Option<usize>,
    lost: Option<usize>,
}

impl Steps {
    fn new(empty: Option<usize>, lost: Option<usize>) -> (Steps, Seen) {
        let seen = Seen::default();
        let steps = Steps {
            seen: Arc::clone(&seen),
            empty,
            lost,
        };
        (steps, seen)
    }
}

impl Script for Steps {
    fn on_frame(&mut self, frame: &mut [u8], segment: &mut FakeSegment, link: &mut dyn Link) {
        let datagrams: Vec<(u8, Vec<u8>)> = EthercatFrame::parse(frame)
            .ok()
            .and_then(|parsed| parsed.datagrams().ok())
            .map(|chain| {
                chain
                    .flatten()
                    .map(|d| (d.command.into(), d.data.to_vec()))
                    .collect()
            })
            .unwrap_or_default();
        let mut seen = self.seen.lock().unwrap_or_else(PoisonError::into_inner);
        let number = seen.len();
        seen.push(datagrams);
        drop(seen);
        if self.lost == Some(number) {
            return;
        }
        if self.empty == Some(number) {
            frame[6] |= 0x02;
            let _ = link.send(frame);
            return;
        }
        answer(frame, segment, link);
    }
}

fn write(value: u8) -> Chained {
    Chained::new(DatagramRequest::fpwr(
        FakeSegment::station(0),
        AT,
        vec![value],
    ))
}

fn read() -> Chained {
    Chained::once(DatagramRequest::fprd(FakeSegment::station(0), AT, 1))
}

fn writes(seen: &Seen) -> Vec<Vec<u8>> {
    let fpwr = 0x05;
    seen.lock()
        .unwrap()
        .iter()
        .map(|frame| {
            frame
                .iter()
                .filter(|(command, _)| *command == fpwr)
                .flat_map(|(_, data)| data.clone())
                .collect()
        })
        .collect()
}

#[test]
fn each_step_goes_in_a_frame_of_its_own_once_the_one_before_counted() {
    let (script, seen) = Steps::new(None, None);
    let bus = start(1, script, config());
    let steps = vec![vec![write(1)], vec![write(2)], vec![write(3), read()]];
    let pendings = bus.handle.submit_chain(steps);
    let results: Vec<Vec<_>> = pendings
        .into_iter()
        .map(|step| step.into_iter().map(|p| finish(p).unwrap()).collect())
        .collect();
    for step in &results {
        assert_eq!(step[0].wkc, 1, "every write counted");
    }
    assert_eq!(
        results[2][1].data.as_slice(),
        [3],
        "the read behind the last write"
    );
    assert_eq!(
        writes(&seen),
        [vec![1], vec![2], vec![3]],
        "one step per frame"
    );
    let (stats, _, report) = bus.stop();
    assert_eq!(report.frames, 3);
    assert_eq!(
        stats.datagrams_chained, 2,
        "the bus staged two steps itself"
    );
    assert_eq!(report.segment.slaves[0].mem[usize::from(AT)], 3);
}

#[test]
fn after_a_write_that_did_not_count_the_rest_is_skipped_unsent() {
    let (script, seen) = Steps::new(Some(1), None);
    let bus = start(1, script, config());
    let steps = vec![vec![write(1)], vec![write(2)], vec![write(3), read()]];
    let mut pendings = bus.handle.submit_chain(steps).into_iter();
    let first = finish(pendings.next().unwrap().remove(0)).unwrap();
    let second = finish(pendings.next().unwrap().remove(0)).unwrap();
    assert_eq!((first.wkc, second.wkc), (1, 0));
    for pending in pendings.next().unwrap() {
        assert_eq!(finish(pending).unwrap_err(), BusError::Skipped);
    }
    assert_eq!(
        writes(&seen),
        [vec![1], vec![2]],
        "the third step never left"
    );
    let (stats, _, report) = bus.stop();
    assert_eq!((report.frames, stats.datagrams_chained), (2, 1));
    assert_eq!(report.segment.slaves[0].mem[usize::from(AT)], 1);
}

#[test]
fn a_lost_step_is_sent_again_and_the_chain_goes_on() {
    let (script, seen) = Steps::new(None, Some(1));
    let mut cfg = config();
    cfg.response_timeout = std::time::Duration::from_millis(20);
    let bus = start(1, script, cfg);
    let steps = vec![vec![write(1)], vec![write(2)], vec![write(3)]];
    for step in bus.handle.submit_chain(steps) {
        for pending in step {
            assert_eq!(finish(pending).unwrap().wkc, 1);
        }
    }
    assert_eq!(writes(&seen), [vec![1], vec![2], vec![2], vec![3]]);
    let (stats, _, _) = bus.stop();
    assert_eq!((stats.retries, stats.datagrams_chained), (1, 2));
}

#[test]
fn a_step_that_cannot_be_sent_fails_the_whole_chain_and_nothing_leaves() {
    let (script, seen) = Steps::new(None, None);
    let bus = start(1, script, config());
    let too_long = Chained::new(DatagramRequest::fpwr(
        FakeSegment::station(0),
        AT,
        vec![0u8; 4000],
    ));
    let steps = vec![vec![write(1)], vec![too_long], vec![]];
    for step in bus.handle.submit_chain(steps) {
        for pending in step {
            assert!(matches!(finish(pending), Err(BusError::TooLarge { .. })));
        }
    }
    let empty = bus.handle.submit_chain(vec![vec![write(1)], vec![]]);
    assert!(matches!(
        finish(empty.into_iter().next().unwrap().remove(0)),
        Err(BusError::InvalidRequest(_))
    ));
    assert!(seen.lock().unwrap().is_empty());
    let (_, _, report) = bus.stop();
    assert_eq!(report.frames, 0);
}

/// Every frame's commands, in order.
fn commands(seen: &Seen) -> Vec<Vec<u8>> {
    seen.lock()
        .unwrap()
        .iter()
        .map(|frame| frame.iter().map(|(command, _)| *command).collect())
        .collect()
}

#[test]
fn a_poll_submitted_with_a_chain_rides_in_its_first_frame_behind_the_first_write() {
    let (fpwr, fprd) = (0x05, 0x04);
    let (script, seen) = Steps::new(None, None);
    let bus = start(1, script, config());
    let rounds = 10;
    for round in 0..rounds {
        let first = round * 3;
        let steps = vec![
            vec![write(first)],
            vec![write(first + 1)],
            vec![write(first + 2)],
        ];
        let poll = DatagramRequest::fprd(FakeSegment::station(0), AT, 1);
        let (pendings, poll) = bus.handle.submit_chain_then_poll(steps, poll, 0);
        let poll = finish(poll).unwrap();
        assert_eq!(
            (poll.wkc, poll.data.as_slice()),
            (1, &[first][..]),
            "the poll read what the first write had just written"
        );
        for pending in pendings.into_iter().flatten() {
            assert_eq!(finish(pending).unwrap().wkc, 1);
        }
    }
    let expected: Vec<Vec<u8>> = (0..rounds)
        .flat_map(|_| [vec![fpwr, fprd], vec![fpwr], vec![fpwr]])
        .collect();
    assert_eq!(commands(&seen), expected, "no frame of the poll's own");
    let (stats, _, report) = bus.stop();
    assert_eq!(report.frames, 3 * u64::from(rounds));
    // One submission per chain and its poll: the sleeping bus thread is woken once for both.
    assert!(
        stats.wakeups <= u64::from(rounds),
        "{} wake-ups",
        stats.wakeups
    );
}

#[test]
fn a_poll_with_a_refused_chain_fails_with_it_and_nothing_is_sent() {
    let (script, seen) = Steps::new(None, None);
    let bus = start(1, script, config());
    let steps = vec![vec![write(1)], vec![]];
    let poll = DatagramRequest::fprd(FakeSegment::station(0), AT, 1);
    let (pendings, poll) = bus.handle.submit_chain_then_poll(steps, poll, 0);
    assert!(matches!(finish(poll), Err(BusError::InvalidRequest(_))));
    for pending in pendings.into_iter().flatten() {
        assert!(finish(pending).is_err());
    }
    let (stats, _, _) = bus.stop();
    assert_eq!(stats.datagrams_sent, 0);
    assert!(seen.lock().unwrap().is_empty());
}

/// [`Steps`] that holds its answer to the first frame until the test opens the gate, so
/// steps can be fed to a chain while it is known to run.
struct Gated {
    steps: Steps,
    gate: Option<mpsc::Receiver<()>>,
}

impl Script for Gated {
    fn on_frame(&mut self, frame: &mut [u8], segment: &mut FakeSegment, link: &mut dyn Link) {
        if let Some(gate) = self.gate.take() {
            // Bounded: a test that never opens the gate fails on its own assertions.
            let _ = gate.recv_timeout(Duration::from_secs(30));
        }
        self.steps.on_frame(frame, segment, link);
    }
}

fn gated(empty: Option<usize>) -> (Gated, Seen, mpsc::Sender<()>) {
    let (steps, seen) = Steps::new(empty, None);
    let (open, gate) = mpsc::channel();
    let script = Gated {
        steps,
        gate: Some(gate),
    };
    (script, seen, open)
}

#[test]
fn steps_fed_while_a_chain_runs_follow_its_own_and_a_feed_after_its_end_is_refused() {
    let (fpwr, fprd) = (0x05, 0x04);
    let (script, seen, open) = gated(None);
    let bus = start(1, script, config());
    let poll = DatagramRequest::fprd(FakeSegment::station(0), AT, 1);
    let (own, poll, feed) = bus
        .handle
        .submit_chain_fed(vec![vec![write(1)], vec![write(2)]], poll);
    // The first frame is held: the chain is under way.
    let fed = bus
        .handle
        .feed_chain(&feed, vec![vec![write(3)], vec![write(4)]])
        .expect("the chain is still running");
    open.send(()).unwrap();
    assert_eq!(finish(poll).unwrap().data.as_slice(), [1]);
    for pending in own.into_iter().chain(fed).flatten() {
        assert_eq!(finish(pending).unwrap().wkc, 1);
    }
    assert!(
        feed.is_closed(),
        "the last write came back with nothing fed"
    );
    assert!(
        bus.handle.feed_chain(&feed, vec![vec![write(5)]]).is_none(),
        "a feed after the end is refused"
    );
    assert_eq!(
        commands(&seen),
        [vec![fpwr, fprd], vec![fpwr], vec![fpwr], vec![fpwr]],
        "one write per frame, in order, and nothing of the refused step"
    );
    assert_eq!(writes(&seen), [vec![1], vec![2], vec![3], vec![4]]);
    let (stats, _, report) = bus.stop();
    assert_eq!(report.frames, 4);
    assert_eq!(
        stats.datagrams_chained, 3,
        "the bus staged three steps itself"
    );
    assert_eq!(report.segment.slaves[0].mem[usize::from(AT)], 4);
}

#[test]
fn steps_fed_to_a_chain_that_stops_are_skipped_unsent() {
    // The second frame comes back counted by no slave: SM0 still full, say.
    let (script, seen, open) = gated(Some(1));
    let bus = start(1, script, config());
    let poll = DatagramRequest::fprd(FakeSegment::station(0), AT, 1);
    let (own, _poll, feed) = bus
        .handle
        .submit_chain_fed(vec![vec![write(1)], vec![write(2)]], poll);
    let fed = bus
        .handle
        .feed_chain(&feed, vec![vec![write(3)]])
        .expect("the chain is still running");
    open.send(()).unwrap();
    let own: Vec<_> = own
        .into_iter()
        .flatten()
        .map(|p| finish(p).unwrap().wkc)
        .collect();
    assert_eq!(own, [1, 0]);
    for pending in fed.into_iter().flatten() {
        assert_eq!(finish(pending).unwrap_err(), BusError::Skipped);
    }
    assert!(feed.is_closed());
    assert_eq!(writes(&seen), [vec![1], vec![2]], "the fed step never left");
    let (stats, _, _) = bus.stop();
    assert_eq!(stats.datagrams_chained, 1);
}
