//! A guest of the bus thread (`bus::Guest`, what the mailbox gateway uses to serve UDP
//! from the bus thread): woken beside the link while the bus sleeps, run on the bus thread,
//! dropped when removed; refused by a bus that cannot wait on a descriptor.

use crate::bus_support;

use std::io;
use std::os::fd::{AsFd, BorrowedFd};
use std::os::unix::net::UnixDatagram;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::time::{Duration, Instant};

use bus_support::bus::{PATIENCE, config, finish};
use master_core::bus::{Bus, BusConfig, Guest, WaitMode};
use master_core::link::{EventFd, Link, MemoryLink, Wait, which_readable};

/// A link over a datagram socket pair, whose far end a thread sends straight back: a
/// segment without slaves that can be waited on with a descriptor.
struct SocketLink(UnixDatagram);

impl SocketLink {
    fn echoed() -> SocketLink {
        let (near, far) = UnixDatagram::pair().expect("socket pair");
        std::thread::spawn(move || {
            let mut buf = [0u8; 2048];
            // Ends when the near end is closed (the bus dropped the link).
            while let Ok(len) = far.recv(&mut buf) {
                if len == 0 || far.send(&buf[..len]).is_err() {
                    break;
                }
            }
        });
        near.set_nonblocking(true).expect("non-blocking");
        SocketLink(near)
    }
}

impl Link for SocketLink {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.0.send(frame).map(|_| ())
    }

    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> io::Result<Option<usize>> {
        if let Wait::Until(until) = wait {
            let timeout = until.saturating_duration_since(Instant::now());
            which_readable(&[self.0.as_fd()], timeout)?;
        }
        match self.0.recv(buf) {
            Ok(len) => Ok(Some(len)),
            Err(err) if err.kind() == io::ErrorKind::WouldBlock => Ok(None),
            Err(err) => Err(err),
        }
    }

    fn wait_fd(&self) -> Option<BorrowedFd<'_>> {
        Some(self.0.as_fd())
    }
}

/// Reports each turn that found its descriptor readable, with the thread it ran on; with
/// `follow_up`, each such turn leaves work for one more turn that it knows of without its
/// descriptor (as a task woken on the bus thread), reported as "follow-up".
struct Recorder {
    wake: Arc<EventFd>,
    turns: Sender<String>,
    follow_up: bool,
    owed: bool,
}

impl Guest for Recorder {
    fn wait_fd(&self) -> BorrowedFd<'_> {
        self.wake.as_fd()
    }

    fn has_work(&self) -> bool {
        self.owed
    }

    fn turn(&mut self, readable: bool, _until: Option<Instant>) {
        if self.owed {
            self.owed = false;
            let _ = self.turns.send("follow-up".into());
        }
        if readable {
            self.wake.drain();
            let thread = std::thread::current().name().unwrap_or("").to_owned();
            let _ = self.turns.send(thread);
            self.owed = self.follow_up;
        }
    }
}

fn recorder(follow_up: bool) -> (Recorder, Arc<EventFd>, Receiver<String>) {
    let wake = Arc::new(EventFd::new().expect("eventfd"));
    let (turns, seen) = channel();
    let guest = Recorder {
        wake: Arc::clone(&wake),
        turns,
        follow_up,
        owed: false,
    };
    (guest, wake, seen)
}

#[test]
fn a_guest_wakes_the_sleeping_bus_runs_on_it_and_is_dropped_when_removed() {
    let (bus, thread) = Bus::start(SocketLink::echoed(), config()).expect("bus");
    assert!(bus.can_host_guest());
    let (guest, wake, turns) = recorder(false);
    assert!(bus.set_guest(Some(Box::new(guest))).is_ok());
    for _ in 0..3 {
        // Nothing is in flight: the bus sleeps until the guest's descriptor wakes it.
        wake.signal();
        let ran_on = turns.recv_timeout(PATIENCE).expect("a turn after the wake");
        assert_eq!(ran_on, "ecat-bus");
        assert_eq!(
            turns.recv_timeout(Duration::ZERO),
            Err(RecvTimeoutError::Timeout),
            "one wake, one readable turn"
        );
    }
    // Frames still go and come back beside the guest.
    let reply = finish(bus.brd(0x0000, 2)).expect("an echoed BRD");
    assert_eq!(reply.wkc, 0);
    // Removed: the bus drops it, which closes its end of the channel.
    assert!(bus.set_guest(None).is_ok());
    let deadline = Instant::now() + PATIENCE;
    loop {
        match turns.recv_timeout(deadline.saturating_duration_since(Instant::now())) {
            Err(RecvTimeoutError::Disconnected) => break,
            Ok(_) => continue,
            Err(RecvTimeoutError::Timeout) => panic!("the guest was not dropped"),
        }
    }
    bus.shutdown();
    drop(thread.join());
}

#[test]
fn work_a_guest_knows_of_gets_its_turn_before_the_bus_sleeps() {
    let (bus, thread) = Bus::start(SocketLink::echoed(), config()).expect("bus");
    let (guest, wake, turns) = recorder(true);
    assert!(bus.set_guest(Some(Box::new(guest))).is_ok());
    for _ in 0..3 {
        wake.signal();
        assert_eq!(turns.recv_timeout(PATIENCE).expect("woken"), "ecat-bus");
        // Nothing wakes the bus for this one: it must not have gone to sleep.
        assert_eq!(
            turns.recv_timeout(PATIENCE).expect("the follow-up turn"),
            "follow-up"
        );
    }
    bus.shutdown();
    drop(thread.join());
}

#[test]
fn a_bus_that_cannot_wait_on_a_descriptor_refuses_a_guest() {
    let (near, _far) = MemoryLink::pair(bus_support::bus::LINK_CAPACITY);
    let (bus, thread) = Bus::start(near, config()).expect("bus");
    assert!(!bus.can_host_guest(), "a memory link has no descriptor");
    let (guest, _wake, _turns) = recorder(false);
    assert!(bus.set_guest(Some(Box::new(guest))).is_err());
    bus.shutdown();
    drop(thread.join());

    let busy = BusConfig {
        wait_mode: WaitMode::BusyPoll,
        ..config()
    };
    let (bus, thread) = Bus::start(SocketLink::echoed(), busy).expect("bus");
    assert!(!bus.can_host_guest(), "a bus that never sleeps");
    let (guest, _wake, _turns) = recorder(false);
    assert!(bus.set_guest(Some(Box::new(guest))).is_err());
    bus.shutdown();
    drop(thread.join());
}
