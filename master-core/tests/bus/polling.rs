//! `BusHandle::submit_once_polling`: the bus thread sends a datagram that came back with
//! working counter 0 again by itself, at most `again` more times, and completes it once
//! (the mailbox layer's eager reads of SM1 while an answer is awaited).

use std::sync::{Arc, Mutex};
use std::time::Instant;

use crate::bus_support;

use bus_support::bus::{config, finish, start};
use bus_support::responder::{Answer, Script, answer};
use bus_support::segment::FakeSegment;
use master_core::bus::{BusError, DatagramRequest};
use master_core::link::{FaultConfig, FaultInjector, Link, MemoryLink};

/// Returns the first `empty` frames as they came, as if no slave had counted them (an empty
/// send mailbox), then answers from the segment.
struct EmptyFor {
    empty: usize,
}

impl Script for EmptyFor {
    fn on_frame(&mut self, frame: &mut [u8], segment: &mut FakeSegment, link: &mut dyn Link) {
        if self.empty > 0 {
            self.empty -= 1;
            // Unchanged: every working counter stays 0, the data as sent.
            frame[6] |= 0x02;
            let _ = link.send(frame);
        } else {
            answer(frame, segment, link);
        }
    }
}

fn poll() -> DatagramRequest {
    DatagramRequest::fprd(FakeSegment::station(0), 0x0180, 4)
}

fn pattern() -> Vec<u8> {
    (0..4)
        .map(|i| FakeSegment::pattern(0, 0x0180 + i))
        .collect()
}

#[test]
fn an_empty_poll_is_sent_again_by_the_bus_until_it_counts() {
    let bus = start(1, EmptyFor { empty: 2 }, config());
    let reply = finish(bus.handle.submit_once_polling(poll(), 5)).unwrap();
    assert_eq!(
        (reply.wkc, reply.data.as_slice()),
        (1, pattern().as_slice())
    );
    let (stats, _, report) = bus.stop();
    assert_eq!(report.frames, 3, "two empty tries and the one that counted");
    assert_eq!(stats.datagrams_sent, 3);
    assert_eq!(stats.datagrams_polled_again, 2);
    assert_eq!(stats.datagrams_completed, 1, "the caller hears once");
}

/// [`EmptyFor`], noting when each frame reached the segment.
struct Timed {
    inner: EmptyFor,
    arrived: Arc<Mutex<Vec<Instant>>>,
}

impl Script for Timed {
    fn on_frame(&mut self, frame: &mut [u8], segment: &mut FakeSegment, link: &mut dyn Link) {
        self.arrived.lock().unwrap().push(Instant::now());
        self.inner.on_frame(frame, segment, link);
    }
}

#[test]
fn a_poll_sent_again_tells_when_its_first_try_and_the_one_that_counted_left() {
    // The mailbox learns a slave's answer time from when the read that found the answer
    // left, not from when it came back (mailbox/engine/answer_time.rs).
    let arrived = Arc::new(Mutex::new(Vec::new()));
    let script = Timed {
        inner: EmptyFor { empty: 2 },
        arrived: Arc::clone(&arrived),
    };
    let bus = start(1, script, config());
    let asked = Instant::now();
    let reply = finish(bus.handle.submit_once_polling(poll(), 5)).unwrap();
    let back = Instant::now();
    bus.stop();
    let arrived = arrived.lock().unwrap().clone();
    assert_eq!((reply.wkc, arrived.len()), (1, 3));
    // In whole µs: the first try left within a µs of the time given.
    let first = reply.first_sent_at();
    let slack = std::time::Duration::from_micros(1);
    assert!(
        asked <= first + slack && first <= arrived[0],
        "{reply:?} {arrived:?}"
    );
    assert!(reply.polled_us > 0);
    // The third try left after the second came back empty, and before it reached the
    // segment; the reply came back after.
    let sent = reply.sent_at.instant();
    assert!(arrived[1] <= sent, "{reply:?} {arrived:?}");
    assert!(sent <= arrived[2] && arrived[2] <= back);
    // Sent once: both are the one frame's.
    let bus = start(1, EmptyFor { empty: 0 }, config());
    let once = finish(bus.handle.submit_once_polling(poll(), 5)).unwrap();
    bus.stop();
    assert_eq!(
        (once.polled_us, once.first_sent_at()),
        (0, once.sent_at.instant())
    );
}

#[test]
fn a_poll_that_stays_empty_ends_after_its_tries_with_the_empty_reply() {
    let bus = start(1, EmptyFor { empty: usize::MAX }, config());
    let reply = finish(bus.handle.submit_once_polling(poll(), 3)).unwrap();
    assert_eq!((reply.wkc, reply.data.as_slice()), (0, &[0u8; 4][..]));
    // A plain submission that comes back empty is not sent again.
    let plain = finish(bus.handle.submit_once(poll())).unwrap();
    assert_eq!(plain.wkc, 0);
    let (stats, _, report) = bus.stop();
    assert_eq!(report.frames, 5, "one try and three more, then one");
    assert_eq!(stats.datagrams_sent, 5);
    assert_eq!(stats.datagrams_polled_again, 3);
}

#[test]
fn a_poll_that_counts_at_once_is_sent_once() {
    let bus = start(1, EmptyFor { empty: 0 }, config());
    let reply = finish(bus.handle.submit_once_polling(poll(), 3)).unwrap();
    assert_eq!(reply.wkc, 1);
    let (stats, _, report) = bus.stop();
    assert_eq!((report.frames, stats.datagrams_polled_again), (1, 0));
}

#[test]
fn a_lost_frame_ends_the_poll_with_a_timeout_and_is_not_sent_again() {
    let (near, far) = MemoryLink::pair(bus_support::bus::LINK_CAPACITY);
    let lossy = FaultConfig {
        drop_tx: 1.0,
        ..FaultConfig::default()
    };
    let near = FaultInjector::new(near, lossy, 1);
    let fast = master_core::bus::BusConfig {
        response_timeout: std::time::Duration::from_millis(2),
        ..config()
    };
    let bus = bus_support::bus::start_on(near, far, 1, EmptyFor { empty: 0 }, fast);
    let result = finish(bus.handle.submit_once_polling(poll(), 3));
    assert_eq!(result.unwrap_err(), BusError::Timeout { attempts: 1 });
    let (stats, link, _) = bus.stop();
    assert_eq!((stats.retries, stats.datagrams_polled_again), (0, 0));
    assert_eq!(link.counts().tx_dropped, 1, "one try only");
}

/// The mailbox layer's write of SM0 and first read of SM1: one submission, so the bus thread
/// never sends the write alone because it woke between two submissions.
#[test]
fn a_write_and_its_poll_travel_in_one_frame_write_first_and_complete_on_their_own() {
    let bus = start(1, Answer, config());
    let rounds: u64 = 50;
    for round in 0..rounds {
        let data: Vec<u8> = (0..4u8).map(|i| round as u8 ^ i).collect();
        let write = DatagramRequest::fpwr(FakeSegment::station(0), 0x0180, data.clone());
        let (written, read) = bus.handle.submit_then_poll(write, poll(), 3);
        assert_eq!(finish(written).unwrap().wkc, 1);
        let read = finish(read).unwrap();
        // The read saw the write of its own pass: it went behind it in the same frame.
        assert_eq!((read.wkc, read.data.as_slice()), (1, data.as_slice()));
    }
    let (stats, _, report) = bus.stop();
    assert_eq!(report.frames, rounds, "one frame per write and its read");
    // Each submission finds the bus thread asleep at most once; two submissions per round
    // wake it twice whenever it has not run yet between them.
    assert!(
        stats.wakeups <= rounds,
        "{} wake-ups of the bus thread for {rounds} writes and their reads",
        stats.wakeups
    );
    assert_eq!(stats.datagrams_sent, 2 * rounds);
}

#[test]
fn a_write_the_bus_cannot_send_fails_alone_and_its_poll_still_goes() {
    let bus = start(1, Answer, config());
    let too_long = DatagramRequest::fpwr(FakeSegment::station(0), 0x0180, vec![0u8; 4000]);
    let (written, read) = bus.handle.submit_then_poll(too_long, poll(), 0);
    assert!(finish(written).is_err());
    assert_eq!(
        finish(read).unwrap().data.as_slice(),
        pattern().as_slice(),
        "the poll read the segment's own bytes: no write went before it"
    );
    let (stats, _, report) = bus.stop();
    assert_eq!((report.frames, stats.datagrams_sent), (1, 1));
}
