//! The cyclic exchange against `ecat-sim` on the **veth rig** (two network namespaces, the
//! simulator as its own process, raw sockets and the kernel between them); the in-process
//! numbers are `cargo bench -p master-core --bench cycle`.
//!
//! ```text
//! cargo bench -p ecat-tests --bench cycle_veth
//! ```
//!
//! Prints two tables:
//! 1. the highest sustainable cycle rate for 1, 16 and 64 slaves (`ecat-sim --slaves N`):
//!    the shortest period (of a fixed list) at which no cycle is lost, every working
//!    counter is right and at least 90 % of the periods run;
//! 2. the cycle-time jitter at 1 kHz (16 slaves) as percentiles of |cycle time − period|,
//!    quiet and while another thread runs SDO uploads back to back on every drive, with the
//!    bus thread at inherited priority and asking for `SCHED_FIFO` (`rt`: granted).
//!
//! Needs root. Not part of CI: the simulator, the master and the storm share this
//! machine's cores, and the numbers depend on its load.

#![allow(missing_docs)]

#[path = "../../master-core/benches/support/rate.rs"]
mod rate;
#[path = "../../master-core/benches/support/storm.rs"]
mod storm;

use std::thread;
use std::time::Duration;

use ecat_tests::rig::{Rig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use ecat_tests::veth_master::VethMaster;
use master_core::bus::{BusConfig, HistogramSnapshot, ThreadPriority};
use master_core::master::MasterConfig;
use rate::{fastest_period, micros};
use storm::Storm;

/// How long each jitter measurement runs.
const RUN: Duration = Duration::from_secs(2);
/// Periods tried for the highest rate, longest first.
const PERIODS_US: [u64; 7] = [1000, 500, 250, 100, 50, 25, 10];
/// How long each period is tried.
const TRY: Duration = Duration::from_millis(500);

/// A rig, the simulator with `slaves` slaves and a scanned master.
struct Setup {
    master: VethMaster,
    _sim: SimProcess,
    _rig: Rig,
}

fn setup(slaves: usize, priority: ThreadPriority) -> Setup {
    let rig = Rig::new();
    let count = slaves.to_string();
    let sim = SimProcess::start(&rig.sim, SIM_IFACE, &["--slaves", &count]);
    let master = VethMaster::with_bus(
        &rig,
        BusConfig {
            priority,
            ..BusConfig::default()
        },
        MasterConfig {
            watch_interval: None,
            ..MasterConfig::default()
        },
    );
    let report = master.scan();
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    Setup {
        master,
        _sim: sim,
        _rig: rig,
    }
}

/// The shortest sustainable period, the cycles per second achieved there, the round-trip
/// median and the image size.
fn max_rate(slaves: usize) -> (Duration, f64, f64, usize) {
    let setup = setup(slaves, ThreadPriority::Inherit);
    let master = setup.master.master();
    let image = master.cycle_stats().image_len;
    let (period, rate, round_trip) = fastest_period(master, &PERIODS_US, TRY);
    (period, rate, round_trip, image)
}

struct JitterRun {
    jitter: HistogramSnapshot,
    start_delay: HistogramSnapshot,
    round_trip: HistogramSnapshot,
    uploads: u64,
    late: u64,
    lost: u64,
    held: u64,
    realtime: bool,
}

/// Jitter at 1 kHz over `RUN` on 16 slaves, with `storm` uploads running meanwhile.
fn jitter(storm: bool, priority: ThreadPriority) -> JitterRun {
    let slaves = 16;
    let setup = setup(slaves, priority);
    let master = setup.master.master();
    // Every drive (every fifth slave) gets uploads.
    let storm = storm.then(|| Storm::start(master, (0..slaves as u16).step_by(5)));
    // A fresh master: its histograms hold this run (and the few cycles of its bring-up).
    thread::sleep(RUN);
    let uploads = storm.map_or(0, Storm::stop);
    let bus = master.bus().stats();
    let timing = master.cycle_timing();
    JitterRun {
        jitter: timing.jitter,
        start_delay: timing.start_delay,
        round_trip: timing.round_trip,
        uploads,
        late: bus.cycles_late,
        lost: master.cycle_stats().lost,
        held: bus.acyclic_held,
        realtime: bus.realtime,
    }
}

fn jitter_row(name: &str, run: &JitterRun) {
    let j = &run.jitter;
    let rate = run.uploads as f64 / RUN.as_secs_f64();
    println!(
        "{:<26} {:>3} {:>6} {:>7.1} {:>7.1} {:>7.1} {:>8.1} {:>8.1} {:>9.1} {:>7.1} {:>5} {:>5} {:>6} {:>9.0}",
        name,
        if run.realtime { "yes" } else { "no" },
        j.count(),
        micros(j.quantile(0.5)),
        micros(j.quantile(0.9)),
        micros(j.quantile(0.99)),
        micros(j.quantile(0.999)),
        micros(j.quantile(1.0)),
        micros(run.start_delay.quantile(0.99)),
        micros(run.round_trip.quantile(0.5)),
        run.late,
        run.lost,
        run.held,
        rate,
    );
}

fn main() {
    println!(
        "highest sustainable cycle rate (veth, ecat-sim --slaves N: no cycle lost, ≥ 90 % of periods run)"
    );
    println!(
        "{:<8} {:>12} {:>12} {:>12} {:>16}",
        "slaves", "image bytes", "period µs", "cycles/s", "round trip µs"
    );
    for slaves in [1, 16, 64] {
        let (period, rate, round_trip, image) = max_rate(slaves);
        println!(
            "{:<8} {:>12} {:>12} {:>12.0} {:>16.1}",
            slaves,
            image,
            period.as_micros(),
            rate,
            round_trip
        );
    }
    println!();
    println!("cycle-time jitter at 1 kHz, 16 slaves, veth (|cycle time − 1 ms|, µs)");
    println!(
        "{:<26} {:>3} {:>6} {:>7} {:>7} {:>7} {:>8} {:>8} {:>9} {:>7} {:>5} {:>5} {:>6} {:>9}",
        "",
        "rt",
        "cycles",
        "p50",
        "p90",
        "p99",
        "p99.9",
        "max",
        "start p99",
        "rtt p50",
        "late",
        "lost",
        "held",
        "uploads/s"
    );
    for (name, priority) in [
        ("inherited priority", ThreadPriority::Inherit),
        ("SCHED_FIFO asked", ThreadPriority::Realtime(80)),
    ] {
        jitter_row(&format!("quiet, {name}"), &jitter(false, priority));
        jitter_row(&format!("storm, {name}"), &jitter(true, priority));
    }
}
