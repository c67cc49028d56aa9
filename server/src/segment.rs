//! Opening the segment: the in-process simulator or a raw socket, the bus and the master.

use std::sync::Arc;
use std::thread::JoinHandle;

use master_core::bus::{Bus, BusHandle, redundancy};
use master_core::link::{CaptureHub, CaptureTap, RawSocket, RawSocketOptions};
use master_core::master::Master;

use crate::config::{Segment, SegmentSetup};
use crate::sim_hooks::SimHooks;

/// A running bus and master; [`Running::stop`] shuts them down.
pub struct Running {
    /// The master.
    pub master: Arc<Master>,
    /// Hooks into the simulated slaves (`--simulate` only).
    pub sim: Option<SimHooks>,
    /// The live capture of the bus's frames (`ecat pcap`).
    pub capture: Arc<CaptureHub>,
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

/// Starts the bus and master on `segment` with `setup` (the master applies the slaves'
/// configuration from its first scan on).
pub fn open(segment: &Segment, setup: &SegmentSetup) -> Result<Running, String> {
    let mut sim = None;
    let capture = CaptureHub::new();
    let (bus, thread) = match segment {
        Segment::Simulate { topology, ring } => {
            let (bus, thread, hooks) = simulate(topology.as_deref(), *ring, setup, &capture)?;
            sim = Some(hooks);
            (bus, thread)
        }
        Segment::Iface { name } => {
            let socket = open_socket(name)?;
            // The live capture sees the primary port's frames: what the bus sends, and the
            // copy that comes back there (docs/redundancy.md, "Limits").
            let socket = CaptureTap::new(socket, Arc::clone(&capture));
            match &setup.backup_iface {
                None => {
                    let (bus, thread) = on_cpu(setup.cpu, || Bus::start(socket, setup.bus))?
                        .map_err(|err| format!("cannot start the bus: {err}"))?;
                    (bus, joiner(thread))
                }
                Some(backup) => {
                    let backup = open_socket(backup)?;
                    let (bus, thread) = on_cpu(setup.cpu, || {
                        Bus::start_ring(socket, backup, setup.bus, redundancy::DEFAULT_GRACE)
                    })?
                    .map_err(|err| format!("cannot start the bus on the ring: {err}"))?;
                    (bus, joiner(thread))
                }
            }
        }
    };
    let master = Master::start(bus.clone(), setup.master)
        .map_err(|err| format!("cannot start the master: {err}"))?;
    master.set_slave_configs(setup.slaves.clone());
    for (address, assignments) in &setup.pdos {
        master.set_pdo_assignment(*address, assignments.clone());
    }
    master.set_groups(setup.groups.clone());
    Ok(Running {
        master: Arc::new(master),
        sim,
        capture,
        bus,
        thread,
    })
}

/// The raw socket on interface `name`.
fn open_socket(name: &str) -> Result<RawSocket, String> {
    RawSocket::open(name, RawSocketOptions::default())
        .map_err(|err| format!("cannot open {name}: {err}"))
}

type Started = (BusHandle, Box<dyn FnOnce() + Send>, SimHooks);

/// Runs `start` with the calling thread pinned to `cpu`, so that the threads it spawns
/// (the bus thread) inherit the pinning; the caller's own affinity is restored after.
fn on_cpu<T>(cpu: Option<usize>, start: impl FnOnce() -> T) -> Result<T, String> {
    let Some(cpu) = cpu else {
        return Ok(start());
    };
    if cpu >= libc::CPU_SETSIZE as usize {
        return Err(format!("[bus] cpu = {cpu}: no such CPU"));
    }
    // SAFETY: `cpu_set_t` is plain data; the calls get its size and a valid pointer.
    unsafe {
        let mut before: libc::cpu_set_t = std::mem::zeroed();
        let size = std::mem::size_of::<libc::cpu_set_t>();
        if libc::sched_getaffinity(0, size, &mut before) != 0 {
            return Err(format!(
                "cannot read the CPU affinity: {}",
                std::io::Error::last_os_error()
            ));
        }
        let mut only: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut only);
        if libc::sched_setaffinity(0, size, &only) != 0 {
            return Err(format!(
                "[bus] cpu = {cpu}: cannot pin the bus thread there: {}",
                std::io::Error::last_os_error()
            ));
        }
        let started = start();
        libc::sched_setaffinity(0, size, &before);
        Ok(started)
    }
}

/// The bus on the in-process simulator: the built-in segment, or the topology file given;
/// a ring into the master's two ports when the topology says `ring = true` or `ring` is
/// set (`--ring`).
#[cfg(feature = "simulate")]
fn simulate(
    topology: Option<&std::path::Path>,
    ring: bool,
    setup: &SegmentSetup,
    capture: &Arc<CaptureHub>,
) -> Result<Started, String> {
    use sim::link::{DEFAULT_QUEUE, InProcessLink, RingPort};
    use sim::topology::{Topology, build_with_handles};

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
    let mut hooks = SimHooks::new(&built.slaves);
    if !(ring || topology.ring) {
        let link = CaptureTap::new(InProcessLink::new(built.segment), Arc::clone(capture));
        let (bus, thread) = on_cpu(setup.cpu, || Bus::start(link, setup.bus))?
            .map_err(|err| format!("cannot start the bus: {err}"))?;
        return Ok((bus, joiner(thread), hooks));
    }
    let segment = Arc::new(std::sync::Mutex::new(built.segment));
    // Pairing wires the last slave back to the backup port (`set_ring`).
    let (primary, backup) = RingPort::pair(Arc::clone(&segment), DEFAULT_QUEUE);
    hooks.set_ring(segment);
    let primary = CaptureTap::new(primary, Arc::clone(capture));
    // Both copies of an in-process frame are back once `send` returns: no grace needed.
    let (bus, thread) = on_cpu(setup.cpu, || {
        Bus::start_ring(primary, backup, setup.bus, std::time::Duration::ZERO)
    })?
    .map_err(|err| format!("cannot start the bus on the ring: {err}"))?;
    Ok((bus, joiner(thread), hooks))
}

/// Without the simulator built in, `--simulate` is refused before anything starts.
#[cfg(not(feature = "simulate"))]
fn simulate(
    _topology: Option<&std::path::Path>,
    _ring: bool,
    _setup: &SegmentSetup,
    _: &Arc<CaptureHub>,
) -> Result<Started, String> {
    Err(NO_SIMULATOR.into())
}

/// Why `--simulate` is refused by an ecatd built without the `simulate` feature.
pub const NO_SIMULATOR: &str = "this ecatd was built without the simulator (cargo feature \
     `simulate`): --simulate is not available; run on a segment with --iface NAME, or \
     rebuild with the default features";

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(not(feature = "simulate"))]
    #[test]
    fn simulate_is_refused_without_the_simulator() {
        let setup = crate::config::Config::default().segment_setup().unwrap();
        let refused = open(
            &Segment::Simulate {
                topology: None,
                ring: false,
            },
            &setup,
        )
        .err();
        assert_eq!(refused.as_deref(), Some(NO_SIMULATOR));
    }

    #[cfg(feature = "simulate")]
    #[test]
    fn simulate_runs_the_built_in_segment_with_its_hooks() {
        let setup = crate::config::Config::default().segment_setup().unwrap();
        let running = open(
            &Segment::Simulate {
                topology: None,
                ring: false,
            },
            &setup,
        )
        .expect("simulated segment");
        assert!(running.sim.is_some());
        assert!(running.master.bus().ring().is_none(), "a line has no ring");
        running.stop();
    }

    #[cfg(feature = "simulate")]
    #[test]
    fn simulate_with_ring_runs_the_segment_as_a_ring_the_hooks_can_cut() {
        let setup = crate::config::Config::default().segment_setup().unwrap();
        let running = open(
            &Segment::Simulate {
                topology: None,
                ring: true,
            },
            &setup,
        )
        .expect("simulated ring");
        let watch = running.master.bus().ring().expect("a ring").clone();
        let hooks = running.sim.clone().expect("hooks");
        // The first frame back through the bus shows the ring closed, the first after the
        // cut broken (the ring link reads it from every frame).
        let _ = running.master.bus().brd(0x0000, 2).wait();
        let status = watch.status();
        assert_eq!(status.state.name(), "closed");
        assert_eq!(status.ring_slaves, 5);
        hooks
            .ring(crate::sim_hooks::RingCut::Break { cable: 3 })
            .unwrap();
        let _ = running.master.bus().brd(0x0000, 2).wait();
        let status = watch.status();
        assert_eq!(status.state.name(), "broken");
        assert_eq!(status.break_after, Some(3));
        running.stop();
    }
}
