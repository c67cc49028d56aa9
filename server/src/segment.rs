//! Opening the segment: the in-process simulator or a raw socket, the bus and the master.

use std::sync::Arc;
use std::thread::JoinHandle;

use master_core::bus::{Bus, BusConfig, BusHandle};
use master_core::link::{RawSocket, RawSocketOptions};
use master_core::master::{Master, MasterConfig};
use sim::link::InProcessLink;
use sim::topology::{Topology, build_with_handles};

use crate::sim_hooks::SimHooks;

use crate::config::Segment;

/// A running bus and master; [`Running::stop`] shuts them down.
pub struct Running {
    /// The master.
    pub master: Arc<Master>,
    /// Hooks into the simulated slaves (`--simulate` only).
    pub sim: Option<SimHooks>,
    bus: BusHandle,
    thread: Box<dyn FnOnce() + Send>,
}

impl Running {
    /// Stops the master and the bus and waits for the bus thread (the socket closes with it).
    pub fn stop(self) {
        let Running {
            master,
            bus,
            thread,
            ..
        } = self;
        drop(master);
        bus.shutdown();
        thread();
    }
}

fn joiner<L: Send + 'static>(thread: JoinHandle<L>) -> Box<dyn FnOnce() + Send> {
    Box::new(move || {
        let _ = thread.join();
    })
}

/// Starts the bus and master on `segment`.
pub fn open(segment: &Segment) -> Result<Running, String> {
    let mut sim = None;
    let (bus, thread) = match segment {
        Segment::Simulate { topology } => {
            let topology = match topology {
                None => Topology::default_segment(),
                Some(path) => {
                    let text = std::fs::read_to_string(path)
                        .map_err(|err| format!("cannot read topology {}: {err}", path.display()))?;
                    Topology::from_toml(&text)
                        .map_err(|err| format!("topology {}: {err}", path.display()))?
                }
            };
            let built = build_with_handles(&topology).map_err(|err| format!("topology: {err}"))?;
            sim = Some(SimHooks::new(&built.slaves));
            let segment = built.segment;
            let (bus, thread) = Bus::start(InProcessLink::new(segment), BusConfig::default())
                .map_err(|err| format!("cannot start the bus: {err}"))?;
            (bus, joiner(thread))
        }
        Segment::Iface { name } => {
            let socket = RawSocket::open(name, RawSocketOptions::default())
                .map_err(|err| format!("cannot open {name}: {err}"))?;
            let (bus, thread) = Bus::start(socket, BusConfig::default())
                .map_err(|err| format!("cannot start the bus: {err}"))?;
            (bus, joiner(thread))
        }
    };
    let master = Master::start(bus.clone(), MasterConfig::default())
        .map_err(|err| format!("cannot start the master: {err}"))?;
    Ok(Running {
        master: Arc::new(master),
        sim,
        bus,
        thread,
    })
}
