//! Stopping the bus: callers still waiting get `Shutdown`, later submissions too, and the
//! thread ends when asked or when the last handle goes.

use crate::bus_support;

use std::sync::mpsc::channel;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use bus_support::bus::{PATIENCE, config, finish};
use master_core::bus::{Bus, BusConfig, BusError, DatagramRequest};
use master_core::link::{Link, MAX_FRAME_LEN, MemoryLink, Wait};

/// Joins `thread`, failing the test if it does not end within the patience.
fn join_soon<T: Send + 'static>(thread: JoinHandle<T>) -> T {
    let (done, ended) = channel();
    std::thread::spawn(move || {
        let _ = done.send(thread.join());
    });
    ended
        .recv_timeout(PATIENCE)
        .expect("the bus thread did not end")
        .expect("the bus thread panicked")
}

#[test]
fn bus_shutdown_fails_callers_in_flight_and_queued() {
    // Nobody answers: the far end is only read, to see what is on the wire.
    let (near, mut far) = MemoryLink::pair(bus_support::bus::LINK_CAPACITY);
    let (handle, thread) = Bus::start(
        near,
        BusConfig {
            response_timeout: Duration::from_secs(60),
            frames_in_flight: 1,
            ..config()
        },
    )
    .unwrap();
    let in_flight = handle.fprd(0x1001, 0x0130, 2);
    let mut buf = [0u8; MAX_FRAME_LEN];
    let sent = far
        .recv(&mut buf, Wait::Until(Instant::now() + PATIENCE))
        .unwrap();
    assert!(sent.is_some(), "the first datagram is on the wire");
    // The only frame record is taken, so these wait in the queue.
    let queued = [handle.brd(0, 2), handle.bwr(0x0120, [0x01, 0x00])];
    let started = Instant::now();
    handle.shutdown();
    assert_eq!(finish(in_flight), Err(BusError::Shutdown));
    for pending in queued {
        assert_eq!(finish(pending), Err(BusError::Shutdown));
    }
    // Noticed long before the 60 s response timeout.
    assert!(started.elapsed() < Duration::from_secs(5));
    let _link = join_soon(thread);
    assert_eq!(finish(handle.fprd(0x1001, 0, 1)), Err(BusError::Shutdown));
    let stats = handle.stats();
    assert_eq!(stats.datagrams_failed, 3);
    assert_eq!(stats.frames_sent, 1);
}

#[test]
fn bus_refuses_submissions_beyond_the_queue_capacity() {
    let (near, mut far) = MemoryLink::pair(bus_support::bus::LINK_CAPACITY);
    let (handle, thread) = Bus::start(
        near,
        BusConfig {
            response_timeout: Duration::from_secs(60),
            frames_in_flight: 1,
            queue_capacity: 4,
            ..config()
        },
    )
    .unwrap();
    let in_flight = handle.fprd(0x1001, 0x0130, 2);
    let mut buf = [0u8; MAX_FRAME_LEN];
    let sent = far
        .recv(&mut buf, Wait::Until(Instant::now() + PATIENCE))
        .unwrap();
    assert!(sent.is_some(), "the first datagram is on the wire");
    // The only frame record is busy, so these stay in the queue, which then is full.
    let queued: Vec<_> = (0..3).map(|n| handle.brd(n * 2, 2)).collect();
    assert_eq!(handle.queued(), 3);
    // A group needs room for all its datagrams at once.
    let group = handle.submit_group([DatagramRequest::brd(0, 2), DatagramRequest::brd(2, 2)]);
    for pending in group {
        assert_eq!(finish(pending), Err(BusError::QueueFull));
    }
    let last = handle.brd(6, 2);
    assert_eq!(handle.queued(), 4);
    assert_eq!(finish(handle.brd(8, 2)), Err(BusError::QueueFull));
    handle.shutdown();
    for pending in [in_flight, last].into_iter().chain(queued) {
        assert_eq!(finish(pending), Err(BusError::Shutdown));
    }
    join_soon(thread);
}

#[test]
fn bus_stops_when_the_last_handle_is_dropped() {
    let (near, _far) = MemoryLink::pair(bus_support::bus::LINK_CAPACITY);
    let (handle, thread) = Bus::start(near, config()).unwrap();
    let other = handle.clone();
    drop(handle);
    // One handle left: still running.
    let pending = other.fprd(0x1001, 0x0130, 2);
    assert!(!thread.is_finished());
    drop(other);
    assert_eq!(finish(pending), Err(BusError::Shutdown));
    join_soon(thread);
}

#[test]
fn bus_start_refuses_an_unusable_configuration() {
    let (near, _far) = MemoryLink::pair(1);
    let err = Bus::start(
        near,
        BusConfig {
            max_frame_len: 20,
            ..config()
        },
    )
    .unwrap_err();
    assert_eq!(err.kind(), std::io::ErrorKind::InvalidInput);
}
