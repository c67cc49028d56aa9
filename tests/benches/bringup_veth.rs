//! The master against `ecat-sim` on the veth rig (two network namespaces): the round trip
//! of one datagram through the bus to a simulated segment and back, and the time to bring
//! 16, 128 and 512 simulated slaves to OP.
//!
//! ```text
//! cargo bench -p ecat-tests --bench bringup_veth
//! ```
//!
//! Needs root. `BRINGUP_VETH_RUNS` (default 3) sets the runs per size; the table shows the
//! fastest and the median. The plain-socket floor of this machine (raw ping-pong over a
//! veth pair, same frame size) is printed by `cargo bench -p master-core --bench
//! bus_roundtrip`; the in-process bring-up by `cargo bench -p master-core --bench bringup`.
//! Not part of CI: the numbers depend on the machine and its load.

#![allow(missing_docs)]

use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ecat_tests::rig::{Rig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use ecat_tests::veth_master;
use master_core::bus::{BusConfig, BusHandle};
use master_core::link::RawSocket;
use master_core::master::{Master, MasterConfig};
use master_core::wire::register::AlState;

const SIZES: [usize; 3] = [16, 128, 512];
const ROUND_TRIPS: usize = 5_000;

fn open_bus(rig: &Rig) -> (BusHandle, JoinHandle<RawSocket>) {
    // A simulated segment of hundreds of slaves takes about a millisecond per frame (every
    // emulated ESC sees every datagram), so with four frames in flight the bus's default
    // 10 ms would count frames queued in the simulator as lost.
    let config = BusConfig {
        response_timeout: Duration::from_millis(100),
        ..BusConfig::default()
    };
    veth_master::open_bus(rig, config)
}

fn stop(bus: BusHandle, thread: JoinHandle<RawSocket>) {
    bus.shutdown();
    drop(bus);
    drop(thread.join());
}

/// p50 and p99 in µs of one BRD (2 bytes of AL status) through the bus, caller's view.
fn round_trip(slaves: usize) -> (f64, f64) {
    let rig = Rig::new();
    let count = slaves.to_string();
    let _sim = SimProcess::start(&rig.sim, SIM_IFACE, &["--slaves", &count]);
    let (bus, thread) = open_bus(&rig);
    let mut samples = Vec::with_capacity(ROUND_TRIPS);
    for i in 0..ROUND_TRIPS + ROUND_TRIPS / 10 {
        let start = Instant::now();
        let reply = bus.brd(0x0130, 2).wait().expect("BRD");
        let elapsed = start.elapsed();
        assert_eq!(usize::from(reply.wkc), slaves, "every slave answers");
        if i >= ROUND_TRIPS / 10 {
            samples.push(elapsed);
        }
    }
    stop(bus, thread);
    samples.sort();
    let at = |q: f64| samples[((samples.len() - 1) as f64 * q) as usize].as_secs_f64() * 1e6;
    (at(0.50), at(0.99))
}

fn bring_up(count: usize, runtime: &tokio::runtime::Runtime) -> (Duration, u64) {
    let rig = Rig::new();
    let slaves = count.to_string();
    let _sim = SimProcess::start(&rig.sim, SIM_IFACE, &["--slaves", &slaves]);
    let (bus, thread) = open_bus(&rig);
    let config = MasterConfig {
        watch_interval: None,
        ..MasterConfig::default()
    };
    let master = Master::start(bus.clone(), config).expect("master");
    let start = Instant::now();
    let report = runtime.block_on(master.scan()).expect("scan");
    let elapsed = start.elapsed();
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    assert_eq!(report.slaves.len(), count);
    assert!(report.slaves.iter().all(|s| s.al_state == AlState::Op));
    let frames = bus.stats().frames_sent;
    drop(master);
    stop(bus, thread);
    (elapsed, frames)
}

fn main() {
    let runs: usize = std::env::var("BRINGUP_VETH_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3)
        .max(1);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .build()
        .expect("runtime");
    println!("master against ecat-sim over veth (poll mode)");
    println!();
    println!(
        "{:<40} {:>10} {:>10}",
        "one BRD through the bus", "p50 µs", "p99 µs"
    );
    for slaves in [1, 16] {
        let (p50, p99) = round_trip(slaves);
        println!(
            "{:<40} {:>10.1} {:>10.1}",
            format!("  {slaves} simulated slave(s)"),
            p50,
            p99
        );
    }
    println!();
    println!("bring-up to OP, {runs} run(s) per size");
    println!(
        "{:>7} {:>12} {:>12} {:>10}",
        "slaves", "fastest", "median", "frames"
    );
    for count in SIZES {
        let mut results: Vec<(Duration, u64)> =
            (0..runs).map(|_| bring_up(count, &runtime)).collect();
        results.sort();
        let (fastest, _) = results[0];
        let (median, frames) = results[results.len() / 2];
        println!(
            "{:>7} {:>9.1} ms {:>9.1} ms {:>10}",
            count,
            fastest.as_secs_f64() * 1e3,
            median.as_secs_f64() * 1e3,
            frames
        );
    }
}
