//! The bus on a bad wire: foreign, duplicated and late frames are ignored and counted, lost
//! frames are sent again until every request completes, and a dead link ends in a timeout.

use crate::bus_support;

use std::time::{Duration, Instant};

use bus_support::bus::{config, finish, start, start_on};
use bus_support::responder::{Answer, Script, answer};
use bus_support::segment::FakeSegment;
use master_core::bus::{BusConfig, BusError, DatagramRequest};
use master_core::link::{FaultConfig, FaultInjector, Link, MemoryLink};

const SLAVES: usize = 3;

fn pattern(slave: usize, offset: u16, len: usize) -> Vec<u8> {
    (0..len)
        .map(|i| FakeSegment::pattern(slave, usize::from(offset) + i))
        .collect()
}

/// Before each reply, sends two frames that are not EtherCAT datagram frames and the
/// previous reply once more (stale by now).
#[derive(Default)]
struct Noisy {
    previous: Option<Vec<u8>>,
}

impl Script for Noisy {
    fn on_frame(&mut self, frame: &mut [u8], segment: &mut FakeSegment, link: &mut dyn Link) {
        // An IPv4 frame on the same wire.
        let mut ipv4 = frame.to_vec();
        ipv4[12..14].copy_from_slice(&[0x08, 0x00]);
        link.send(&ipv4).unwrap();
        // An EtherCAT frame whose header promises more than it carries.
        let mut cut = frame.to_vec();
        cut.truncate(20);
        link.send(&cut).unwrap();
        if let Some(previous) = &self.previous {
            link.send(previous).unwrap();
        }
        answer(frame, segment, link);
        self.previous = Some(frame.to_vec());
    }
}

#[test]
fn bus_ignores_foreign_frames_and_duplicate_replies() {
    let bus = start(SLAVES, Noisy::default(), config());
    for n in 0..50usize {
        let slave = n % SLAVES;
        let ado = 0x0300 + n as u16 * 2;
        let reply = finish(bus.handle.fprd(FakeSegment::station(slave), ado, 2)).unwrap();
        assert_eq!(reply.data.as_slice(), pattern(slave, ado, 2), "request {n}");
    }
    // The noise before each reply has been read by the time the reply completes.
    let stats = bus.handle.stats();
    assert_eq!(stats.frames_foreign, 100);
    assert_eq!(stats.frames_stale, 49);
    assert_eq!(stats.frames_received, 50);
    assert_eq!((stats.frames_lost, stats.retries), (0, 0));
    bus.stop();
}

/// Holds the first frame; when the retry arrives, sends the first frame's reply (with its
/// data marked, so that which reply was delivered shows) and then answers the retry.
#[derive(Default)]
struct LateFirstReply {
    held: Option<Vec<u8>>,
    frames: usize,
}

impl Script for LateFirstReply {
    fn on_frame(&mut self, frame: &mut [u8], segment: &mut FakeSegment, link: &mut dyn Link) {
        self.frames += 1;
        match self.frames {
            1 => self.held = Some(frame.to_vec()),
            2 => {
                let mut late = self.held.take().unwrap();
                assert!(segment.process(&mut late));
                // FPRD of 2 bytes: data at 16 + 10.
                late[26..28].copy_from_slice(&[0xEE, 0xEE]);
                link.send(&late).unwrap();
                answer(frame, segment, link);
            }
            _ => answer(frame, segment, link),
        }
    }
}

#[test]
fn a_late_reply_to_the_first_attempt_completes_a_frame_sent_again() {
    let bus = start(
        SLAVES,
        LateFirstReply::default(),
        BusConfig {
            response_timeout: Duration::from_millis(200),
            ..config()
        },
    );
    let reply = finish(bus.handle.fprd(FakeSegment::station(2), 0x0140, 2)).unwrap();
    // The retry went out under the same index, so the first attempt's reply, which came
    // first, is its answer; the retry's own reply then finds nothing in flight.
    assert_eq!(reply.data.as_slice(), [0xEE, 0xEE]);
    // A second request: its reply comes after the retry's on the link, so once it is
    // complete the retry's reply has been read (and counted) too.
    let second = finish(bus.handle.fprd(FakeSegment::station(2), 0x0140, 2)).unwrap();
    assert_eq!(second.data.as_slice(), pattern(2, 0x0140, 2));
    let (stats, _, report) = bus.stop();
    assert_eq!(report.frames, 3);
    assert_eq!(stats.frames_lost, 1);
    assert_eq!(stats.retries, 1);
    assert_eq!(stats.frames_stale, 1, "the retry's reply was not ignored");
    assert_eq!(stats.frames_received, 2);
    assert_eq!(stats.datagrams_sent, 3);
    assert_eq!(stats.datagrams_completed, 2);
    // Karn's rule: the frame sent twice gave no round-trip sample, the second one did.
    assert_eq!(stats.round_trip.count(), 1);
}

/// A segment that answers every frame just too late: each reply goes out only when the
/// next frame arrives, that is after the master's timeout sent the frame again.
#[derive(Default)]
struct AlwaysLate {
    held: Option<Vec<u8>>,
}

impl Script for AlwaysLate {
    fn on_frame(&mut self, frame: &mut [u8], segment: &mut FakeSegment, link: &mut dyn Link) {
        if let Some(mut late) = self.held.take() {
            assert!(segment.process(&mut late));
            link.send(&late).unwrap();
        }
        self.held = Some(frame.to_vec());
    }
}

#[test]
fn a_segment_that_always_answers_after_the_timeout_still_completes_every_request() {
    // Each reply arrives right after the next attempt went out. Had each attempt its own
    // indices, every reply would be stale and each request would fail after its retries.
    let bus = start(
        SLAVES,
        AlwaysLate::default(),
        BusConfig {
            response_timeout: Duration::from_millis(20),
            retries: 3,
            ..config()
        },
    );
    for n in 0..10u16 {
        let ado = 0x0300 + n * 2;
        let reply = finish(bus.handle.fprd(FakeSegment::station(1), ado, 2)).unwrap();
        assert_eq!(reply.data.as_slice(), pattern(1, ado, 2), "request {n}");
    }
    let (stats, _, _) = bus.stop();
    assert_eq!(stats.frames_received, 10);
    assert_eq!(stats.datagrams_completed, 10);
    assert_eq!(stats.datagrams_failed, 0);
}

#[test]
fn bus_completes_every_request_through_5_percent_loss_and_counts_each_loss() {
    let (near, far) = MemoryLink::pair(bus_support::bus::LINK_CAPACITY);
    let faults = FaultConfig {
        drop_tx: 0.025,
        drop_rx: 0.025,
        ..FaultConfig::default()
    };
    let near = FaultInjector::new(near, faults, 0x88a4_0005);
    let bus = start_on(
        near,
        far,
        SLAVES,
        Answer,
        BusConfig {
            // Long enough that no reply is ever merely late, so every loss is a drop.
            response_timeout: Duration::from_millis(250),
            retries: 6,
            ..config()
        },
    );
    std::thread::scope(|scope| {
        for thread in 0..4usize {
            let handle = bus.handle.clone();
            scope.spawn(move || {
                for n in 0..60usize {
                    let slave = (thread + n) % SLAVES;
                    let station = FakeSegment::station(slave);
                    if n % 3 == 0 {
                        // A retried register write is harmless: the same value again.
                        let at = 0x1A00 + (thread * 60 + n) as u16 * 2;
                        let value = [thread as u8, n as u8];
                        let write = DatagramRequest::fpwr(station, at, value).expect_wkc(1);
                        finish(handle.submit(write)).unwrap();
                        let read = finish(handle.fprd(station, at, 2)).unwrap();
                        assert_eq!(read.data.as_slice(), &value);
                    } else {
                        let ado = 0x0100 + (thread * 60 + n) as u16;
                        let reply = finish(handle.fprd(station, ado, 1)).unwrap();
                        assert_eq!(reply.data.as_slice(), pattern(slave, ado, 1));
                    }
                }
            });
        }
    });
    let (stats, near, _) = bus.stop();
    let injected = near.counts();
    let drops = injected.tx_dropped + injected.rx_dropped;
    assert!(drops > 0, "the seed should lose some frames: {injected:?}");
    assert_eq!(stats.frames_lost, drops, "{stats:?}");
    assert_eq!(stats.retries, drops);
    assert_eq!(stats.datagrams_failed, 0);
    assert_eq!(stats.datagrams_completed, 4 * 80);
    assert_eq!(stats.frames_stale, 0);
    assert_eq!(stats.frames_sent, stats.frames_received + drops);
}

#[test]
fn bus_gives_up_with_a_timeout_after_the_retries_on_a_dead_link() {
    let (near, far) = MemoryLink::pair(bus_support::bus::LINK_CAPACITY);
    let dead = FaultInjector::new(
        near,
        FaultConfig {
            drop_tx: 1.0,
            ..FaultConfig::default()
        },
        1,
    );
    let timeout = Duration::from_millis(20);
    let bus = start_on(
        dead,
        far,
        SLAVES,
        Answer,
        BusConfig {
            response_timeout: timeout,
            retries: 2,
            ..config()
        },
    );
    let started = Instant::now();
    let result = finish(bus.handle.fprd(FakeSegment::station(0), 0x0130, 2));
    assert_eq!(result, Err(BusError::Timeout { attempts: 3 }));
    assert!(started.elapsed() >= timeout * 3, "gave up too early");
    let group = bus
        .handle
        .submit_group([DatagramRequest::brd(0, 2), DatagramRequest::brd(2, 2)]);
    for pending in group {
        assert_eq!(finish(pending), Err(BusError::Timeout { attempts: 3 }));
    }
    let (stats, near, report) = bus.stop();
    assert_eq!(report.frames, 0);
    assert_eq!(near.counts().tx_dropped, 6);
    assert_eq!(
        (stats.frames_sent, stats.frames_lost, stats.retries),
        (6, 6, 4)
    );
    assert_eq!(stats.datagrams_failed, 3);
    assert_eq!(stats.datagrams_sent, 9);
}

#[test]
fn bus_reports_a_link_that_refuses_to_send() {
    let (near, far) = MemoryLink::pair(bus_support::bus::LINK_CAPACITY);
    // With the far end gone, every send and receive fails (BrokenPipe).
    drop(far);
    let (handle, thread) = master_core::bus::Bus::start(
        near,
        BusConfig {
            response_timeout: Duration::from_millis(10),
            retries: 1,
            ..config()
        },
    )
    .unwrap();
    // Twice: the failing link must not leave the idle bus deaf to new submissions.
    for _ in 0..2 {
        let result = finish(handle.fprd(0x1001, 0x0130, 2));
        assert_eq!(result, Err(BusError::Link(std::io::ErrorKind::BrokenPipe)));
    }
    handle.shutdown();
    thread.join().unwrap();
    let stats = handle.stats();
    assert!(stats.link_errors >= 4, "{stats:?}");
    // A failing link makes the thread sleep until the next deadline instead of spinning.
    assert!(stats.link_errors < 100, "{stats:?}");
    assert_eq!(stats.frames_sent, 0);
}
