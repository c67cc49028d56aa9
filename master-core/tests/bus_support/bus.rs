//! Starting a bus on one end of an in-memory link with a test responder on the other.

use std::thread::JoinHandle;
use std::time::Duration;

use master_core::bus::{Bus, BusConfig, BusHandle, BusStatsSnapshot, DatagramResult, Pending};
use master_core::link::{Link, MemoryLink};

use super::responder::{Report, Responder, Script};
use super::segment::FakeSegment;

/// Far longer than any result needs; only reached if something is broken.
pub const PATIENCE: Duration = Duration::from_secs(20);

/// Frames each direction of the test link can hold.
pub const LINK_CAPACITY: usize = 64;

/// A configuration for tests on an in-memory link: a response timeout long enough that a
/// busy test machine never makes a reply late, so that counters are exact.
pub fn config() -> BusConfig {
    BusConfig {
        response_timeout: Duration::from_secs(2),
        ..BusConfig::default()
    }
}

/// A bus, its thread, and the responder answering it.
pub struct TestBus<L: Link + 'static> {
    /// The handle the test submits through.
    pub handle: BusHandle,
    /// The bus thread; yields the link when it ends.
    pub thread: JoinHandle<L>,
    /// The far end.
    pub responder: Responder,
}

/// A bus on a memory link, `slaves` fake slaves answering as `script` says.
pub fn start(slaves: usize, script: impl Script, config: BusConfig) -> TestBus<MemoryLink> {
    let (near, far) = MemoryLink::pair(LINK_CAPACITY);
    start_on(near, far, slaves, script, config)
}

/// A bus on `near`, the responder on `far`.
pub fn start_on<L: Link + 'static, F: Link + 'static>(
    near: L,
    far: F,
    slaves: usize,
    script: impl Script,
    config: BusConfig,
) -> TestBus<L> {
    let responder = Responder::spawn(far, FakeSegment::new(slaves), script);
    let (handle, thread) = Bus::start(near, config).expect("start the bus");
    TestBus {
        handle,
        thread,
        responder,
    }
}

impl<L: Link + 'static> TestBus<L> {
    /// Shuts the bus down; returns its final statistics, its link and the responder's
    /// report.
    pub fn stop(self) -> (BusStatsSnapshot, L, Report) {
        self.handle.shutdown();
        let link = self.thread.join().expect("the bus thread panicked");
        // Taken after the thread ended, so final.
        let stats = self.handle.stats();
        let report = self.responder.stop();
        (stats, link, report)
    }
}

/// Waits (at most [`PATIENCE`]) for a result.
pub fn finish(mut pending: Pending) -> DatagramResult {
    pending
        .wait_timeout(PATIENCE)
        .expect("no result within the patience")
}
