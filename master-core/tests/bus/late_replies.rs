//! A reply that is already waiting in the link when a frame's deadline passes is taken, not
//! counted lost: on a loaded machine the bus thread can be scheduled after the deadline of
//! a frame whose answer came back in time.

use std::io;
use std::time::Duration;

use master_core::bus::{Bus, BusConfig};
use master_core::link::{Link, Wait};
use sim::link::InProcessLink;
use sim::topology::{Topology, build};

/// Hides each returned frame from the first `recv` after it came back, as if the bus
/// thread had looked just before it arrived.
struct LateLink {
    inner: InProcessLink,
    hidden_once: bool,
}

impl Link for LateLink {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.hidden_once = false;
        self.inner.send(frame)
    }

    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> io::Result<Option<usize>> {
        if !self.hidden_once && self.inner.pending() > 0 {
            self.hidden_once = true;
            return Ok(None);
        }
        self.inner.recv(buf, wait)
    }
}

#[test]
fn a_reply_waiting_at_the_deadline_is_taken_not_counted_lost() {
    let segment = build(&Topology::default_segment()).expect("topology builds");
    let link = LateLink {
        inner: InProcessLink::new(segment),
        hidden_once: false,
    };
    // Every deadline has passed by the time the loop looks again.
    let config = BusConfig {
        response_timeout: Duration::from_nanos(1),
        ..BusConfig::default()
    };
    let (bus, thread) = Bus::start(link, config).expect("bus starts");
    for _ in 0..20 {
        let reply = bus.brd(0x0130, 2).wait().expect("BRD");
        assert_eq!(reply.wkc, 5, "every slave answered");
    }
    let stats = bus.stats();
    assert_eq!(
        (stats.frames_lost, stats.retries, stats.frames_stale),
        (0, 0, 0),
        "{stats:?}"
    );
    assert_eq!(stats.frames_received, 20);
    bus.shutdown();
    drop(bus);
    drop(thread.join());
}
