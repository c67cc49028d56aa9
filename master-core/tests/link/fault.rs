//! The fault injector: what it says it injected is exactly what went missing or changed,
//! the same seed gives the same faults, and delays are kept.

use crate::bus_support;

use std::time::{Duration, Instant};

use bus_support::frames::{MIN_FRAME_LEN, seq_of, test_frame};
use master_core::link::{
    FaultConfig, FaultCounts, FaultInjector, Link, MAX_FRAME_LEN, MemoryLink, Wait,
};
use master_core::wire::ethernet::HEADER_LEN as ETHERNET_HEADER_LEN;

const FRAMES: u32 = 1000;
const SEED: u64 = 0x88a4;

/// Sends `FRAMES` frames from `a` to `b`, with the injector on the sending end (`on_tx`) or
/// on the receiving end, and returns what it counted and which frames arrived.
fn run(config: FaultConfig, seed: u64, on_tx: bool) -> (FaultCounts, Vec<u32>) {
    let (a, b) = MemoryLink::pair(8);
    let mut buf = [0u8; MAX_FRAME_LEN];
    let mut arrived = Vec::new();
    let counts = if on_tx {
        let mut a = FaultInjector::new(a, config, seed);
        let mut b = b;
        for seq in 0..FRAMES {
            a.send(&test_frame(seq, MIN_FRAME_LEN)).unwrap();
            while let Some(len) = b.recv(&mut buf, Wait::NoWait).unwrap() {
                arrived.push(seq_of(&buf[..len]));
            }
        }
        a.counts()
    } else {
        let mut a = a;
        let mut b = FaultInjector::new(b, config, seed);
        for seq in 0..FRAMES {
            a.send(&test_frame(seq, MIN_FRAME_LEN)).unwrap();
            while let Some(len) = b.recv(&mut buf, Wait::NoWait).unwrap() {
                arrived.push(seq_of(&buf[..len]));
            }
        }
        assert_eq!(a.dropped(), 0, "the queue itself must not lose frames here");
        b.counts()
    };
    (counts, arrived)
}

fn assert_half_dropped(dropped: u64, arrived: &[u32]) {
    assert_eq!(dropped, u64::from(FRAMES) - arrived.len() as u64);
    // A fair coin over 1000 throws stays well inside this range.
    assert!(
        (400..=600).contains(&dropped),
        "dropped {dropped} of {FRAMES}"
    );
    assert!(arrived.windows(2).all(|w| w[0] < w[1]), "order kept");
}

#[test]
fn link_fault_tx_drops_equal_missing_frames_and_repeat_per_seed() {
    let config = FaultConfig {
        drop_tx: 0.5,
        ..FaultConfig::default()
    };
    let (counts, arrived) = run(config, SEED, true);
    assert_half_dropped(counts.tx_dropped, &arrived);
    assert_eq!(
        counts,
        FaultCounts {
            tx_dropped: counts.tx_dropped,
            ..FaultCounts::default()
        }
    );

    let (again, arrived_again) = run(config, SEED, true);
    assert_eq!(again, counts);
    assert_eq!(arrived_again, arrived, "same seed, same frames lost");

    let (_, other) = run(config, SEED + 1, true);
    assert_ne!(other, arrived, "another seed loses other frames");
}

#[test]
fn link_fault_rx_drops_equal_missing_frames_and_repeat_per_seed() {
    let config = FaultConfig {
        drop_rx: 0.5,
        ..FaultConfig::default()
    };
    let (counts, arrived) = run(config, SEED, false);
    assert_half_dropped(counts.rx_dropped, &arrived);
    assert_eq!(counts.tx_dropped, 0);

    let (again, arrived_again) = run(config, SEED, false);
    assert_eq!(again, counts);
    assert_eq!(arrived_again, arrived);
}

#[test]
fn link_fault_with_no_faults_passes_everything() {
    let (counts, arrived) = run(FaultConfig::default(), SEED, true);
    assert_eq!(counts, FaultCounts::default());
    assert_eq!(arrived, (0..FRAMES).collect::<Vec<_>>());
}

#[test]
fn link_fault_corruption_changes_exactly_one_byte_after_the_header() {
    let (mut a, b) = MemoryLink::pair(8);
    let config = FaultConfig {
        corrupt: 1.0,
        ..FaultConfig::default()
    };
    let mut b = FaultInjector::new(b, config, SEED);
    let mut buf = [0u8; MAX_FRAME_LEN];
    let mut offsets = Vec::new();
    for seq in 0..200 {
        let frame = test_frame(seq, MIN_FRAME_LEN + (seq as usize % 40));
        a.send(&frame).unwrap();
        let len = b
            .recv(&mut buf, Wait::NoWait)
            .unwrap()
            .expect("corrupted, not lost");
        assert_eq!(len, frame.len());
        let changed: Vec<usize> = (0..len).filter(|&i| buf[i] != frame[i]).collect();
        assert_eq!(changed.len(), 1, "frame {seq}: bytes {changed:?} changed");
        assert!(
            changed[0] >= ETHERNET_HEADER_LEN,
            "the Ethernet header is left alone"
        );
        offsets.push(changed[0]);
    }
    assert_eq!(b.counts().corrupted, 200);
    // The offset really is random, not always the same byte.
    offsets.sort_unstable();
    offsets.dedup();
    assert!(offsets.len() > 10, "only offsets {offsets:?} were hit");
}

#[test]
fn link_fault_delay_holds_a_frame_until_it_is_due() {
    let delay = Duration::from_millis(150);
    let (mut a, b) = MemoryLink::pair(8);
    let config = FaultConfig {
        delay: Some(delay),
        ..FaultConfig::default()
    };
    let mut b = FaultInjector::new(b, config, SEED);
    let mut buf = [0u8; MAX_FRAME_LEN];

    let frame = test_frame(42, MIN_FRAME_LEN);
    let sent_at = Instant::now();
    a.send(&frame).unwrap();

    // An earlier deadline sees nothing, though the frame is already in the link.
    let early = Wait::Until(sent_at + delay / 3);
    assert_eq!(b.recv(&mut buf, early).unwrap(), None);
    assert_eq!(b.held(), 1);
    assert_eq!(b.recv(&mut buf, Wait::NoWait).unwrap(), None);

    // A later deadline gets it, once due and not before.
    let late = Wait::Until(sent_at + delay * 20);
    let len = b.recv(&mut buf, late).unwrap().expect("the delayed frame");
    let released_at = Instant::now();
    assert_eq!(&buf[..len], &frame[..]);
    assert!(
        released_at >= sent_at + delay,
        "released after {:?}",
        released_at - sent_at
    );
    assert!(released_at < sent_at + delay * 20);
    assert_eq!(b.held(), 0);
    assert_eq!(b.counts().delayed, 1);
}

#[test]
fn link_fault_delayed_frames_keep_their_order() {
    let delay = Duration::from_millis(20);
    let (mut a, b) = MemoryLink::pair(8);
    let config = FaultConfig {
        delay: Some(delay),
        ..FaultConfig::default()
    };
    let mut b = FaultInjector::new(b, config, SEED);
    let mut buf = [0u8; MAX_FRAME_LEN];
    for seq in 0..5 {
        a.send(&test_frame(seq, MIN_FRAME_LEN)).unwrap();
    }
    let deadline = Wait::Until(Instant::now() + Duration::from_secs(5));
    for seq in 0..5 {
        let len = b.recv(&mut buf, deadline).unwrap().expect("delayed frame");
        assert_eq!(seq_of(&buf[..len]), seq);
    }
    assert_eq!(b.counts().delayed, 5);
}
