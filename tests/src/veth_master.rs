//! ecatd's own master on the master's end of a [`Rig`]: a raw socket opened inside the
//! master's namespace, the bus thread on it, and a [`Master`] over the bus.

use std::thread::JoinHandle;
use std::time::Duration;

use master_core::bus::{Bus, BusConfig, BusHandle, redundancy};
use master_core::link::{Link, RawSocket, RawSocketOptions};
use master_core::master::{Master, MasterConfig, ScanReport};

use crate::rig::{MASTER_BACKUP_IFACE, MASTER_IFACE, Rig};

/// Starts a bus on the master's end of `rig`.
///
/// # Panics
/// If the raw socket or the bus thread cannot be made.
pub fn open_bus(rig: &Rig, config: BusConfig) -> (BusHandle, JoinHandle<RawSocket>) {
    Bus::start(open_socket(rig), config).expect("bus starts")
}

/// A raw socket on the master's end of `rig`.
///
/// # Panics
/// If it cannot be opened (no root).
pub fn open_socket(rig: &Rig) -> RawSocket {
    // The socket belongs to the namespace of the thread that opens it.
    rig.master
        .run_inside(|| RawSocket::open(MASTER_IFACE, RawSocketOptions::default()))
        .expect("raw socket on the master's end")
}

/// Waits for a bus thread when called.
fn joiner<L: Send + 'static>(thread: JoinHandle<L>) -> Box<dyn FnOnce() + Send> {
    Box::new(move || {
        let _ = thread.join();
    })
}

/// A master over veth; dropping it stops the master and its bus.
pub struct VethMaster {
    master: Option<Master>,
    bus_thread: Option<Box<dyn FnOnce() + Send>>,
    runtime: tokio::runtime::Runtime,
}

impl VethMaster {
    /// A master (not yet scanned) on `rig`, with the default bus settings.
    pub fn start(rig: &Rig, config: MasterConfig) -> VethMaster {
        VethMaster::with_bus(rig, BusConfig::default(), config)
    }

    /// A master on `rig` with the given bus settings.
    pub fn with_bus(rig: &Rig, bus: BusConfig, config: MasterConfig) -> VethMaster {
        VethMaster::on_link(Box::new(open_socket(rig)), bus, config)
    }

    /// A master on `link` (the rig's raw socket in a wrapper, such as a fault injector).
    pub fn on_link(link: Box<dyn Link>, bus: BusConfig, config: MasterConfig) -> VethMaster {
        let (bus, bus_thread) = Bus::start(link, bus).expect("bus starts");
        VethMaster::over(bus, joiner(bus_thread), config)
    }

    /// A master on the ring of `rig` ([`Rig::ring`]): the bus on both raw sockets
    /// (`Bus::start_ring` with the default grace, as ecatd runs a ring).
    pub fn on_ring(rig: &Rig, bus: BusConfig, config: MasterConfig) -> VethMaster {
        let backup = rig
            .master
            .run_inside(|| RawSocket::open(MASTER_BACKUP_IFACE, RawSocketOptions::default()))
            .expect("raw socket on the master's backup port");
        let (bus, bus_thread) =
            Bus::start_ring(open_socket(rig), backup, bus, redundancy::DEFAULT_GRACE)
                .expect("bus starts");
        VethMaster::over(bus, joiner(bus_thread), config)
    }

    fn over(bus: BusHandle, joiner: Box<dyn FnOnce() + Send>, config: MasterConfig) -> VethMaster {
        let master = Master::start(bus, config).expect("master starts");
        VethMaster {
            master: Some(master),
            bus_thread: Some(joiner),
            // Any executor can await the master; the tests drive it with this one.
            runtime: tokio::runtime::Builder::new_current_thread()
                .enable_time()
                .build()
                .expect("runtime"),
        }
    }

    /// The master.
    pub fn master(&self) -> &Master {
        self.master.as_ref().expect("running")
    }

    /// Runs `future` to completion (the master's calls, a mailbox request).
    pub fn block_on<F: std::future::Future>(&self, future: F) -> F::Output {
        self.runtime.block_on(future)
    }

    /// Runs `future` with a deadline, failing the test if it is not met.
    ///
    /// # Panics
    /// When `patience` runs out.
    pub fn within<F: std::future::Future>(&self, patience: Duration, future: F) -> F::Output {
        self.runtime.block_on(async {
            tokio::time::timeout(patience, future)
                .await
                .expect("finished in time")
        })
    }

    /// Scans the segment.
    ///
    /// # Panics
    /// If the scan fails as a whole (slaves refusing states are in the report).
    pub fn scan(&self) -> ScanReport {
        self.block_on(self.master().scan()).expect("scan")
    }
}

impl Drop for VethMaster {
    fn drop(&mut self) {
        if let Some(master) = self.master.take() {
            let bus = master.bus().clone();
            drop(master);
            bus.shutdown();
        }
        if let Some(join) = self.bus_thread.take() {
            join();
        }
    }
}
