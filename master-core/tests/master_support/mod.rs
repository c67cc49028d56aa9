//! Shared by the master's integration tests: a master on the in-process simulator, a
//! minimal `block_on` (the master's async API must not need any runtime of the caller's),
//! and waiting on conditions with a deadline.
#![allow(dead_code)]

use std::future::Future;
use std::io;
use std::pin::pin;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::task::{Context, Poll, Wake, Waker};
use std::thread::{JoinHandle, Thread};
use std::time::{Duration, Instant};

use master_core::bus::redundancy::RingLink;
use master_core::bus::{Bus, BusConfig, BusHandle};
use master_core::link::{Link, Wait};
use master_core::master::{Master, MasterConfig, MasterEvent};
use sim::esc::ManualTime;
use sim::link::{InProcessLink, RingPort, SharedSegment};
use sim::segment::Segment;
use sim::topology::{SlaveHandles, Topology, build_with_handles};
use tokio::sync::broadcast;

/// How long a test waits for anything before it fails.
pub const PATIENCE: Duration = Duration::from_secs(20);

struct ThreadWaker(Thread);

impl Wake for ThreadWaker {
    fn wake(self: Arc<Self>) {
        self.0.unpark();
    }
}

/// Runs a future to completion on the calling thread, with no runtime at all.
pub fn block_on<F: Future>(future: F) -> F::Output {
    let waker = Waker::from(Arc::new(ThreadWaker(std::thread::current())));
    let mut cx = Context::from_waker(&waker);
    let mut future = pin!(future);
    loop {
        if let Poll::Ready(out) = future.as_mut().poll(&mut cx) {
            return out;
        }
        std::thread::park();
    }
}

/// Polls `condition` until it holds or `PATIENCE` runs out; returns whether it held.
pub fn wait_until(mut condition: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + PATIENCE;
    while Instant::now() < deadline {
        if condition() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    condition()
}

/// Takes events until one satisfies `wanted` (returned) or `PATIENCE` runs out (`None`).
pub fn next_event(
    events: &mut broadcast::Receiver<MasterEvent>,
    mut wanted: impl FnMut(&MasterEvent) -> bool,
) -> Option<MasterEvent> {
    let deadline = Instant::now() + PATIENCE;
    while Instant::now() < deadline {
        match events.try_recv() {
            Ok(event) if wanted(&event) => return Some(event),
            Ok(_) | Err(broadcast::error::TryRecvError::Lagged(_)) => {}
            Err(broadcast::error::TryRecvError::Empty) => {
                std::thread::sleep(Duration::from_millis(2))
            }
            Err(broadcast::error::TryRecvError::Closed) => return None,
        }
    }
    None
}

/// A link shared between the bus thread and the test (to look into a wrapper such as the
/// fault injector while the bus owns it).
pub struct SharedLink<L>(pub Arc<Mutex<L>>);

impl<L> SharedLink<L> {
    pub fn lock(&self) -> MutexGuard<'_, L> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl<L> Clone for SharedLink<L> {
    fn clone(&self) -> Self {
        SharedLink(Arc::clone(&self.0))
    }
}

impl<L: Link> Link for SharedLink<L> {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.lock().send(frame)
    }

    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> io::Result<Option<usize>> {
        self.lock().recv(buf, wait)
    }
}

/// A master on a simulated segment.
pub struct Rig<L: Link + 'static> {
    pub master: Option<Master>,
    pub segment: SharedSegment,
    pub handles: Vec<SlaveHandles>,
    pub topology: Topology,
    /// The segment's time base (advance it to let watchdogs run out).
    pub time: ManualTime,
    bus_thread: Option<JoinHandle<L>>,
}

impl<L: Link + 'static> Rig<L> {
    pub fn master(&self) -> &Master {
        self.master.as_ref().expect("master running")
    }

    pub fn segment(&self) -> MutexGuard<'_, Segment> {
        self.segment.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Stops master and bus; returns the link.
    pub fn stop(mut self) -> L {
        let master = self.master.take().expect("master running");
        let bus = master.bus().clone();
        drop(master);
        bus.shutdown();
        drop(bus);
        self.bus_thread
            .take()
            .expect("bus running")
            .join()
            .expect("bus thread")
    }
}

impl<L: Link + 'static> Drop for Rig<L> {
    fn drop(&mut self) {
        if let Some(master) = self.master.take() {
            let bus = master.bus().clone();
            drop(master);
            bus.shutdown();
        }
        if let Some(thread) = self.bus_thread.take() {
            let _ = thread.join();
        }
    }
}

/// A master (not yet scanned) on the segment `topology` builds, with the link made by
/// `wrap` around the in-process link.
pub fn rig_with<L: Link + 'static>(
    topology: Topology,
    config: MasterConfig,
    bus_config: BusConfig,
    wrap: impl FnOnce(InProcessLink) -> L,
) -> Rig<L> {
    let built = build_with_handles(&topology).expect("topology builds");
    let segment: SharedSegment = Arc::new(Mutex::new(built.segment));
    let link = wrap(InProcessLink::shared(Arc::clone(&segment), 64));
    let (bus, bus_thread) = Bus::start(link, bus_config).expect("bus starts");
    assemble(
        bus,
        bus_thread,
        config,
        segment,
        built.slaves,
        topology,
        built.time,
    )
}

/// A rig around a started bus: the master started on it.
fn assemble<L: Link + 'static>(
    bus: BusHandle,
    bus_thread: JoinHandle<L>,
    config: MasterConfig,
    segment: SharedSegment,
    handles: Vec<SlaveHandles>,
    topology: Topology,
    time: ManualTime,
) -> Rig<L> {
    let master = Master::start(bus, config).expect("master starts");
    Rig {
        master: Some(master),
        segment,
        handles,
        topology,
        time,
        bus_thread: Some(bus_thread),
    }
}

/// A master on a segment the test built itself (described by `topology`, for the
/// expectations), on the plain in-process link.
pub fn rig_on(
    segment: Segment,
    time: ManualTime,
    topology: Topology,
    config: MasterConfig,
) -> Rig<InProcessLink> {
    let segment: SharedSegment = Arc::new(Mutex::new(segment));
    let link = InProcessLink::shared(Arc::clone(&segment), 64);
    let (bus, bus_thread) = Bus::start(link, BusConfig::default()).expect("bus starts");
    let master = Master::start(bus, config).expect("master starts");
    Rig {
        master: Some(master),
        segment,
        handles: Vec::new(),
        topology,
        time,
        bus_thread: Some(bus_thread),
    }
}

/// A master on `topology` wired as a ring between two in-process ports (cable
/// redundancy): the bus runs on the ring link, whose watch is `rig.master().bus().ring()`.
pub fn rig_ring(topology: Topology, config: MasterConfig) -> Rig<RingLink<RingPort, RingPort>> {
    let built = build_with_handles(&topology).expect("topology builds");
    let segment: SharedSegment = Arc::new(Mutex::new(built.segment));
    let (primary, backup) = RingPort::pair(Arc::clone(&segment), 64);
    let (bus, bus_thread) =
        Bus::start_ring(primary, backup, BusConfig::default(), Duration::ZERO).expect("bus starts");
    assemble(
        bus,
        bus_thread,
        config,
        segment,
        built.slaves,
        topology,
        built.time,
    )
}

/// A master on the plain in-process link.
pub fn rig(topology: Topology, config: MasterConfig) -> Rig<InProcessLink> {
    rig_with(topology, config, BusConfig::default(), |link| link)
}
