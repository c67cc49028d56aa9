//! Cable redundancy on the **veth rig**: the 1 kHz cycle of 16 slaves (`ecat-sim --slaves
//! 16`) on one port, on a closed ring (`--backup-iface`, every frame out of both ports)
//! and on a ring broken in the middle (`break 8`: each half served from its own port).
//!
//! ```text
//! cargo bench -p ecat-tests --bench redundancy_veth
//! ```
//!
//! Prints, per row, over a window of `RUN` after bring-up: the frames the master put on the
//! wire per cycle (both ports counted; acyclic frames of the window included), the cycle
//! time's jitter (|cycle time − 1 ms|) as percentiles, the cycle frame's round trip, and
//! the cycles with a wrong working counter or lost. Needs root; not part of CI (the
//! simulator and the master share this machine's cores).

#![allow(missing_docs)]

#[path = "../../master-core/benches/support/rate.rs"]
#[allow(dead_code)]
mod rate;

use std::thread;
use std::time::Duration;

use ecat_tests::rig::{Rig, SIM_BACKUP_IFACE, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use ecat_tests::veth_master::VethMaster;
use master_core::bus::{BusConfig, HistogramSnapshot};
use master_core::master::MasterConfig;
use rate::micros;

/// How long each row is measured.
const RUN: Duration = Duration::from_secs(3);
const SLAVES: &str = "16";

#[derive(Clone, Copy)]
enum Wiring {
    Line,
    Closed,
    Broken,
}

struct Row {
    frames_per_cycle: f64,
    cycles: u64,
    jitter: HistogramSnapshot,
    round_trip: HistogramSnapshot,
    bad: u64,
    state: String,
}

fn measure(wiring: Wiring) -> Row {
    let config = MasterConfig {
        watch_interval: None,
        ..MasterConfig::default()
    };
    let (rig, mut sim, master, ports) = match wiring {
        Wiring::Line => {
            let rig = Rig::new();
            let sim = SimProcess::start_controlled(&rig.sim, SIM_IFACE, &["--slaves", SLAVES]);
            let master = VethMaster::with_bus(&rig, BusConfig::default(), config);
            (rig, sim, master, 1)
        }
        Wiring::Closed | Wiring::Broken => {
            let rig = Rig::ring();
            let sim = SimProcess::start_controlled(
                &rig.sim,
                SIM_IFACE,
                &["--slaves", SLAVES, "--backup-iface", SIM_BACKUP_IFACE],
            );
            let master = VethMaster::on_ring(&rig, BusConfig::default(), config);
            (rig, sim, master, 2)
        }
    };
    let report = master.scan();
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    if let Wiring::Broken = wiring {
        sim.command("break 8");
    }
    // Settle: the cut seen, the first cycles after it out of the window.
    thread::sleep(Duration::from_millis(200));
    let m = master.master();
    let (bus0, stats0, timing0) = (m.bus().stats(), m.cycle_stats(), m.cycle_timing());
    thread::sleep(RUN);
    let (bus1, stats1, timing1) = (m.bus().stats(), m.cycle_stats(), m.cycle_timing());
    let cycles = stats1.completed - stats0.completed;
    let frames = (bus1.frames_sent - bus0.frames_sent) * ports;
    let state = m
        .bus()
        .ring()
        .map(|ring| {
            let status = ring.status();
            match status.break_after {
                Some(after) => format!("{} after {after}", status.state.name()),
                None => status.state.name().to_string(),
            }
        })
        .unwrap_or_else(|| "off".into());
    let row = Row {
        frames_per_cycle: frames as f64 / cycles.max(1) as f64,
        cycles,
        jitter: timing1.jitter.since(&timing0.jitter),
        round_trip: timing1.round_trip.since(&timing0.round_trip),
        bad: (stats1.wrong_wkc + stats1.lost) - (stats0.wrong_wkc + stats0.lost),
        state,
    };
    drop(master);
    sim.stop();
    drop(rig);
    row
}

fn main() {
    println!("cable redundancy at 1 kHz, {SLAVES} slaves, veth (jitter = |cycle time − 1 ms|, µs)");
    println!(
        "{:<22} {:<16} {:>7} {:>13} {:>7} {:>7} {:>7} {:>8} {:>8} {:>8} {:>5}",
        "",
        "ring",
        "cycles",
        "frames/cycle",
        "p50",
        "p90",
        "p99",
        "max",
        "rtt p50",
        "rtt p99",
        "bad"
    );
    for (name, wiring) in [
        ("one port", Wiring::Line),
        ("ring closed", Wiring::Closed),
        ("ring broken after 8", Wiring::Broken),
    ] {
        let row = measure(wiring);
        let j = &row.jitter;
        println!(
            "{:<22} {:<16} {:>7} {:>13.2} {:>7.1} {:>7.1} {:>7.1} {:>8.1} {:>8.1} {:>8.1} {:>5}",
            name,
            row.state,
            row.cycles,
            row.frames_per_cycle,
            micros(j.quantile(0.5)),
            micros(j.quantile(0.9)),
            micros(j.quantile(0.99)),
            micros(j.quantile(1.0)),
            micros(row.round_trip.quantile(0.5)),
            micros(row.round_trip.quantile(0.99)),
            row.bad,
        );
    }
}
