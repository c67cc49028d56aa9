//! The in-process link: frames cross intact, a full queue drops without blocking, deadlines
//! are honoured, and a vanished peer is reported.

use crate::bus_support;

use std::io;
use std::time::{Duration, Instant};

use bus_support::frames::{MIN_FRAME_LEN, seq_of, test_frame};
use master_core::link::{Link, MAX_FRAME_LEN, MemoryLink, Wait};

/// Far longer than any healthy test needs; only reached if something is broken.
const PATIENCE: Duration = Duration::from_secs(5);

fn soon() -> Wait {
    Wait::Until(Instant::now() + PATIENCE)
}

#[test]
fn link_memory_frames_cross_byte_identical_both_ways() {
    let (mut a, mut b) = MemoryLink::pair(16);
    let mut buf = [0u8; MAX_FRAME_LEN];
    for (seq, len) in [(1, MIN_FRAME_LEN), (2, 100), (3, MAX_FRAME_LEN)] {
        let frame = test_frame(seq, len);
        a.send(&frame).unwrap();
        let got = b.recv(&mut buf, soon()).unwrap().expect("a frame a -> b");
        assert_eq!(&buf[..got], &frame[..]);

        let reply = test_frame(seq + 100, len);
        b.send(&reply).unwrap();
        let got = a.recv(&mut buf, soon()).unwrap().expect("a frame b -> a");
        assert_eq!(&buf[..got], &reply[..]);
    }
    // Nothing echoes back to the sender.
    assert_eq!(a.recv(&mut buf, Wait::NoWait).unwrap(), None);
    assert_eq!(b.recv(&mut buf, Wait::NoWait).unwrap(), None);
}

#[test]
fn link_memory_full_queue_drops_and_counts_without_blocking() {
    let (mut a, mut b) = MemoryLink::pair(4);
    for seq in 0..10 {
        a.send(&test_frame(seq, MIN_FRAME_LEN)).unwrap();
    }
    assert_eq!(a.dropped(), 6);
    assert_eq!(b.pending(), 4);
    assert_eq!(b.dropped(), 0);

    // The first four survived, in order; the rest are gone like frames on a busy wire.
    let mut buf = [0u8; MAX_FRAME_LEN];
    for seq in 0..4 {
        let got = b
            .recv(&mut buf, Wait::NoWait)
            .unwrap()
            .expect("queued frame");
        assert_eq!(seq_of(&buf[..got]), seq);
    }
    assert_eq!(b.recv(&mut buf, Wait::NoWait).unwrap(), None);

    // Room again: the ring wraps around and carries on.
    for seq in 10..13 {
        a.send(&test_frame(seq, MIN_FRAME_LEN)).unwrap();
        let got = b
            .recv(&mut buf, Wait::NoWait)
            .unwrap()
            .expect("frame after wrap");
        assert_eq!(seq_of(&buf[..got]), seq);
    }
    assert_eq!(a.dropped(), 6);
}

#[test]
fn link_memory_past_deadline_returns_none_at_once() {
    let (_a, mut b) = MemoryLink::pair(4);
    let mut buf = [0u8; MAX_FRAME_LEN];
    let past = Instant::now();
    let started = Instant::now();
    assert_eq!(b.recv(&mut buf, Wait::Until(past)).unwrap(), None);
    assert_eq!(b.recv(&mut buf, Wait::NoWait).unwrap(), None);
    assert!(started.elapsed() < Duration::from_millis(100));
}

#[test]
fn link_memory_waits_until_the_deadline_then_gives_up() {
    let (_a, mut b) = MemoryLink::pair(4);
    let mut buf = [0u8; MAX_FRAME_LEN];
    let deadline = Instant::now() + Duration::from_millis(30);
    assert_eq!(b.recv(&mut buf, Wait::Until(deadline)).unwrap(), None);
    let now = Instant::now();
    assert!(now >= deadline, "returned before the deadline");
    assert!(now < deadline + PATIENCE);
}

#[test]
fn link_memory_wakes_a_receiver_waiting_on_another_thread() {
    let (mut a, mut b) = MemoryLink::pair(4);
    let receiver = std::thread::spawn(move || {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let got = b
            .recv(&mut buf, soon())
            .unwrap()
            .expect("frame from the other thread");
        buf[..got].to_vec()
    });
    let frame = test_frame(7, MIN_FRAME_LEN);
    a.send(&frame).unwrap();
    assert_eq!(receiver.join().unwrap(), frame);
}

#[test]
fn link_memory_cuts_a_frame_to_a_short_buffer() {
    let (mut a, mut b) = MemoryLink::pair(4);
    let frame = test_frame(9, 100);
    a.send(&frame).unwrap();
    let mut small = [0u8; 40];
    assert_eq!(b.recv(&mut small, Wait::NoWait).unwrap(), Some(40));
    assert_eq!(&small[..], &frame[..40]);
}

#[test]
fn link_memory_refuses_a_frame_longer_than_it_carries() {
    let (mut a, b) = MemoryLink::pair(4);
    let err = a.send(&vec![0u8; MAX_FRAME_LEN + 1]).unwrap_err();
    assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
    assert_eq!(b.pending(), 0);
}

#[test]
fn link_memory_reports_a_dropped_peer_after_delivering_what_was_queued() {
    let (mut a, mut b) = MemoryLink::pair(4);
    b.send(&test_frame(1, MIN_FRAME_LEN)).unwrap();
    drop(b);

    let mut buf = [0u8; MAX_FRAME_LEN];
    let got = a
        .recv(&mut buf, Wait::NoWait)
        .unwrap()
        .expect("frame sent before the drop");
    assert_eq!(seq_of(&buf[..got]), 1);
    let err = a.recv(&mut buf, soon()).unwrap_err();
    assert_eq!(err.kind(), io::ErrorKind::BrokenPipe);
    let err = a.send(&test_frame(2, MIN_FRAME_LEN)).unwrap_err();
    assert_eq!(err.kind(), io::ErrorKind::BrokenPipe);
}

#[test]
fn link_memory_wakes_a_waiting_receiver_when_the_peer_is_dropped() {
    let (a, mut b) = MemoryLink::pair(4);
    let receiver = std::thread::spawn(move || {
        let mut buf = [0u8; MAX_FRAME_LEN];
        b.recv(&mut buf, soon()).map_err(|err| err.kind())
    });
    drop(a);
    assert_eq!(receiver.join().unwrap(), Err(io::ErrorKind::BrokenPipe));
}

#[test]
fn link_memory_works_behind_a_box() {
    let (a, b) = MemoryLink::pair(4);
    let mut a: Box<dyn Link> = Box::new(a);
    let mut b: Box<dyn Link> = Box::new(b);
    let frame = test_frame(3, MIN_FRAME_LEN);
    a.send(&frame).unwrap();
    let mut buf = [0u8; MAX_FRAME_LEN];
    let got = b
        .recv(&mut buf, Wait::NoWait)
        .unwrap()
        .expect("frame through the box");
    assert_eq!(&buf[..got], &frame[..]);
}
