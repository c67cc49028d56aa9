//! A simulated segment with its mailbox slaves in PREOP, driven through the real bus and
//! the mailbox engine.
//!
//! Until the master's bring-up (`Master::scan`) lands, [`Rig::start`] does the few steps a
//! mailbox needs by hand, with bus datagrams: station address, the mailbox SyncManagers
//! from each slave's SII (words 0x18-0x1C), AL control → PREOP.

#![allow(dead_code)]

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use master_core::bus::{Bus, BusConfig, BusHandle};
use master_core::link::{FaultConfig, FaultCounts, FaultInjector, Link};
use master_core::mailbox::{
    MailboxArea, MailboxConfig, MailboxEngine, MailboxProtocols, SlaveMailbox, SlaveMailboxConfig,
};
use master_core::wire::register::address::{AL_CONTROL, AL_STATUS, STATION_ADDRESS};
use master_core::wire::register::eeprom::{
    EepromControl, EepromRequest, EepromRequestRepr, data_words,
};
use master_core::wire::register::sync_manager::{SyncManager, SyncManagerRepr};
use sim::link::{InProcessLink, SharedSegment};
use sim::segment::Segment;
use sim::topology::{SlaveHandles, Topology, build_with_handles};

/// Station address of the slave at ring position `position`.
pub fn station(position: usize) -> u16 {
    0x1001 + position as u16
}

/// The default topology's slaves with a mailbox.
pub const DRIVE: usize = 0;
pub const COE_STORE: usize = 3;
pub const EOE_PORT: usize = 4;

/// EEPROM control/status (0x0502), address (0x0504), data (0x0508).
const EEPROM_CONTROL: u16 = 0x0502;
const EEPROM_DATA: u16 = 0x0508;

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
    pub engine: MailboxEngine,
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
        let slaves = bring_up(&bus, topology.slaves.len());
        lock(&injector).set_config(faults);
        let engine = MailboxEngine::start(bus.clone(), mailbox).expect("engine starts");
        for (_, config) in &slaves {
            engine.add_slave(*config);
        }
        Rig {
            bus,
            engine,
            segment,
            handles: built.slaves,
            slaves,
            faults: injector,
        }
    }

    /// The mailbox of the slave at `position`.
    pub fn slave(&self, position: usize) -> SlaveMailbox {
        self.engine
            .slave(station(position))
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
        self.engine.shutdown();
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

/// Station addresses, mailbox SyncManagers from the SII, PREOP: returns the mailbox slaves.
pub fn bring_up(bus: &BusHandle, count: usize) -> Vec<(usize, SlaveMailboxConfig)> {
    let mut slaves = Vec::new();
    for position in 0..count {
        let station = station(position);
        let reply = bus
            .apwr(position as u16, STATION_ADDRESS, station.to_le_bytes())
            .wait()
            .unwrap();
        assert_eq!(reply.wkc, 1, "slave {position} takes its station address");
        let words = read_sii(bus, station, 0x18, 5);
        let (write, read) = (
            MailboxArea {
                start: words[0],
                len: words[1],
            },
            MailboxArea {
                start: words[2],
                len: words[3],
            },
        );
        if write.len == 0 {
            continue;
        }
        let mut sms = [0u8; 16];
        SyncManagerRepr::mailbox_out(write.start, write.len)
            .emit(&mut SyncManager::new_unchecked(&mut sms[..8]))
            .unwrap();
        SyncManagerRepr::mailbox_in(read.start, read.len)
            .emit(&mut SyncManager::new_unchecked(&mut sms[8..]))
            .unwrap();
        assert_eq!(bus.fpwr(station, 0x0800, sms).wait().unwrap().wkc, 1);
        assert_eq!(
            bus.fpwr(station, AL_CONTROL, 0x0002u16.to_le_bytes())
                .wait()
                .unwrap()
                .wkc,
            1
        );
        let status = bus.fprd(station, AL_STATUS, 2).wait().unwrap();
        assert_eq!(
            status.data.as_slice()[0] & 0x1F,
            0x02,
            "slave {position} in PREOP"
        );
        slaves.push((
            position,
            SlaveMailboxConfig {
                station,
                write,
                read,
                protocols: MailboxProtocols(words[4]),
            },
        ));
    }
    slaves
}

/// `n` SII words from `word` on, through the EEPROM interface.
fn read_sii(bus: &BusHandle, station: u16, word: u16, n: usize) -> Vec<u16> {
    let mut words = Vec::new();
    while words.len() < n {
        let address = word + words.len() as u16;
        let mut request = [0u8; 6];
        EepromRequestRepr::read(address)
            .emit(&mut EepromRequest::new_unchecked(&mut request[..]))
            .unwrap();
        assert_eq!(
            bus.fpwr(station, EEPROM_CONTROL, request)
                .wait()
                .unwrap()
                .wkc,
            1
        );
        let control = (0..100)
            .map(|_| {
                let raw = bus.fprd(station, EEPROM_CONTROL, 2).wait().unwrap();
                EepromControl::parse(raw.data.as_slice()).unwrap()
            })
            .find(|control| !control.busy)
            .expect("the EEPROM read finishes");
        assert!(!control.has_error());
        let data = bus
            .fprd(station, EEPROM_DATA, control.read_size())
            .wait()
            .unwrap();
        words.extend(data_words(data.data.as_slice()));
    }
    words.truncate(n);
    words
}
