//! Time to bring simulated segments of 16, 128 and 512 slaves to OP with the master, over
//! the in-process link (the simulator runs inside the bus thread's `send`, so this measures
//! the master and the simulator, not a network).
//!
//! ```text
//! cargo bench -p master-core --bench bringup
//! ```
//!
//! `BRINGUP_BENCH_RUNS` (default 3) sets the runs per size; the table shows the fastest and
//! the median run, the frames sent and the datagrams per frame. Not part of CI: numbers
//! depend on the machine and its load. The veth variant (the simulator behind a raw socket)
//! comes with `ecat-sim --iface`.

#![allow(missing_docs)]

use std::time::{Duration, Instant};

use master_core::bus::{Bus, BusConfig};
use master_core::master::{Master, MasterConfig};
use master_core::wire::register::AlState;
use sim::link::InProcessLink;
use sim::topology::{Topology, build};

const SIZES: [usize; 3] = [16, 128, 512];

struct Run {
    elapsed: Duration,
    frames: u64,
    datagrams: u64,
}

fn bring_up(count: usize, runtime: &tokio::runtime::Runtime) -> Run {
    let segment = build(&Topology::repeated(count)).expect("topology builds");
    let (bus, thread) = Bus::start(InProcessLink::new(segment), BusConfig::default()).expect("bus");
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
    let stats = bus.stats();
    drop(master);
    bus.shutdown();
    drop(bus);
    drop(thread.join());
    Run {
        elapsed,
        frames: stats.frames_sent,
        datagrams: stats.datagrams_sent,
    }
}

fn main() {
    let runs: usize = std::env::var("BRINGUP_BENCH_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3)
        .max(1);
    // Any executor will do; the master times everything on its own thread.
    let runtime = tokio::runtime::Builder::new_current_thread()
        .build()
        .expect("runtime");
    println!("bring-up to OP, in-process simulator, {runs} run(s) per size");
    println!(
        "{:>7} {:>12} {:>12} {:>10} {:>16}",
        "slaves", "fastest", "median", "frames", "datagrams/frame"
    );
    for count in SIZES {
        let mut results: Vec<Run> = (0..runs).map(|_| bring_up(count, &runtime)).collect();
        results.sort_by_key(|r| r.elapsed);
        let fastest = &results[0];
        let median = &results[results.len() / 2];
        println!(
            "{:>7} {:>9.1} ms {:>9.1} ms {:>10} {:>16.1}",
            count,
            fastest.elapsed.as_secs_f64() * 1e3,
            median.elapsed.as_secs_f64() * 1e3,
            median.frames,
            median.datagrams as f64 / median.frames.max(1) as f64,
        );
    }
}
