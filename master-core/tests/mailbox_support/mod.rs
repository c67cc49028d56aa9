//! A simulated segment brought to PREOP by the master (`Master::scan`), whose mailbox
//! engine then serves every mailbox slave: the real bus, bring-up and engine, with faults
//! injected only into the mailbox traffic.

#![allow(dead_code)]

// The master's `block_on`: no runtime of our own, so it also works inside a tokio test.
#[path = "../master_support/mod.rs"]
mod master_support;

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use master_core::bus::{Bus, BusConfig, BusHandle};
use master_core::link::{FaultConfig, FaultCounts, FaultInjector, Link};
use master_core::mailbox::{MailboxConfig, MailboxEngine, SlaveMailbox, SlaveMailboxConfig};
use master_core::master::{Master, MasterConfig, SiiLayout, SlaveAddress};
use master_core::wire::register::AlState;
use sim::link::{InProcessLink, SharedSegment};
use sim::segment::Segment;
use sim::topology::{SlaveHandles, Topology, build_with_handles};

use master_support::block_on;

/// Station address of the slave at ring position `position`.
pub fn station(position: usize) -> u16 {
    0x1001 + position as u16
}

/// The default topology's slaves with a mailbox.
pub const DRIVE: usize = 0;
pub const COE_STORE: usize = 3;
pub const EOE_PORT: usize = 4;

/// A link whose fault counts stay readable while the bus owns it.
pub struct Shared<L: Link>(Arc<Mutex<L>>);

impl<L: Link> Link for Shared<L> {
    fn send(&mut self, frame: &[u8]) -> std::io::Result<()> {
        lock(&self.0).send(frame)
    }

    fn recv(
        &mut self,
        buf: &mut [u8],
        wait: master_core::link::Wait,
    ) -> std::io::Result<Option<usize>> {
        lock(&self.0).recv(buf, wait)
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// The running rig.
pub struct Rig {
    pub bus: BusHandle,
    pub master: Master,
    pub segment: SharedSegment,
    pub handles: Vec<SlaveHandles>,
    pub slaves: Vec<(usize, SlaveMailboxConfig)>,
    faults: Arc<Mutex<FaultInjector<InProcessLink>>>,
}

impl Rig {
    /// The default topology, no faults.
    pub fn default_segment() -> Rig {
        Rig::start(
            &Topology::default_segment(),
            FaultConfig::default(),
            1,
            bus_config(),
        )
    }

    /// `topology` behind a fault injector seeded with `seed`.
    pub fn start(topology: &Topology, faults: FaultConfig, seed: u64, bus: BusConfig) -> Rig {
        Rig::start_with(
            topology,
            faults,
            seed,
            bus,
            MailboxConfig::default(),
            |_, _| {},
        )
    }

    /// As [`Rig::start`], with a mailbox configuration and a hook that may change the
    /// segment before the bring-up (replace a slave's device, say).
    pub fn start_with(
        topology: &Topology,
        faults: FaultConfig,
        seed: u64,
        bus: BusConfig,
        mailbox: MailboxConfig,
        prepare: impl FnOnce(&mut Segment, &[SlaveHandles]),
    ) -> Rig {
        Rig::build(topology, faults, seed, bus, mailbox, true, prepare)
    }

    /// As [`Rig::start_with`] without faults, with the "mailbox full" bits left out of the
    /// cyclic frame: a send mailbox is read only while a request waits or when the test
    /// says so ([`SlaveMailbox::notify_mailbox_full`]). For tests whose slaves have
    /// messages to send from the start: with the bits mapped, the engine reads them as
    /// soon as the slave is in PREOP, before the test can subscribe to them.
    pub fn start_without_status_bits(
        topology: &Topology,
        mailbox: MailboxConfig,
        prepare: impl FnOnce(&mut Segment, &[SlaveHandles]),
    ) -> Rig {
        let faults = FaultConfig::default();
        Rig::build(topology, faults, 1, bus_config(), mailbox, false, prepare)
    }

    fn build(
        topology: &Topology,
        faults: FaultConfig,
        seed: u64,
        bus: BusConfig,
        mailbox: MailboxConfig,
        map_mailbox_status: bool,
        prepare: impl FnOnce(&mut Segment, &[SlaveHandles]),
    ) -> Rig {
        let mut built = build_with_handles(topology).expect("topology builds");
        prepare(&mut built.segment, &built.slaves);
        let segment: SharedSegment = Arc::new(Mutex::new(built.segment));
        let link = InProcessLink::shared(Arc::clone(&segment), 64);
        // Bring-up without faults; the faults start with the mailbox traffic.
        let injector = Arc::new(Mutex::new(FaultInjector::new(
            link,
            FaultConfig::default(),
            seed,
        )));
        let (bus, _thread) = Bus::start(Shared(Arc::clone(&injector)), bus).expect("bus starts");
        let (master, slaves) = scan_with(&bus, mailbox, map_mailbox_status);
        lock(&injector).set_config(faults);
        Rig {
            bus,
            master,
            segment,
            handles: built.slaves,
            slaves,
            faults: injector,
        }
    }

    /// The mailbox engine the master runs.
    pub fn engine(&self) -> &MailboxEngine {
        self.master.mailbox_engine()
    }

    /// The mailbox of the slave at `position`.
    pub fn slave(&self, position: usize) -> SlaveMailbox {
        self.master
            .mailbox(SlaveAddress::Position(position as u16))
            .expect("a mailbox slave")
    }

    /// Faults injected so far.
    pub fn fault_counts(&self) -> FaultCounts {
        lock(&self.faults).counts()
    }

    /// Locks the simulated segment.
    pub fn segment(&self) -> MutexGuard<'_, Segment> {
        lock(&self.segment)
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.engine().shutdown();
        self.bus.shutdown();
    }
}

/// Bus settings for the in-process segment: replies come back during the send, so a
/// short response timeout only matters when a frame is lost.
pub fn bus_config() -> BusConfig {
    BusConfig {
        response_timeout: Duration::from_millis(2),
        retries: 8,
        ..BusConfig::default()
    }
}

/// Waits for `condition` with a deadline (no sleeps as synchronisation).
pub fn wait_until(what: &str, timeout: Duration, mut condition: impl FnMut() -> bool) {
    let deadline = Instant::now() + timeout;
    while !condition() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::yield_now();
    }
}

/// A master on `bus` that brings the segment to PREOP (stations from [`station`]`(0)`), and
/// the mailbox slaves its engine then serves, by position.
pub fn scan_to_preop(
    bus: &BusHandle,
    mailbox: MailboxConfig,
) -> (Master, Vec<(usize, SlaveMailboxConfig)>) {
    scan_with(bus, mailbox, true)
}

/// [`scan_to_preop`], the "mailbox full" bits mapped into the cyclic frame or not.
fn scan_with(
    bus: &BusHandle,
    mailbox: MailboxConfig,
    map_mailbox_status: bool,
) -> (Master, Vec<(usize, SlaveMailboxConfig)>) {
    let config = MasterConfig {
        station_base: station(0),
        target_state: AlState::PreOp,
        watch_interval: None,
        mailbox,
        map_mailbox_status,
        ..MasterConfig::default()
    };
    // The process-data layout from the SII: some tests replace a slave's device with one
    // that speaks only the protocol under test, so the scan must not need CoE.
    let master = Master::with_layout_source(bus.clone(), config, Box::new(SiiLayout))
        .expect("master starts");
    let report = block_on(master.scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let slaves = report
        .slaves
        .iter()
        .filter_map(|info| {
            let mailbox = master.mailbox(SlaveAddress::Position(info.position)).ok()?;
            Some((usize::from(info.position), *mailbox.config()))
        })
        .collect();
    (master, slaves)
}
