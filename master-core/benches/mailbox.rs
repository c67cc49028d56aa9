//! SDO upload latency and throughput through the mailbox engine, against the simulator
//! in-process (no kernel, no wire: what the master itself costs).
//!
//! Prints one table: the raw frame round trip of the bus (one FPRD), then SDO uploads of
//! 0x1018:01 (expedited) from one slave, and from 16 slaves in parallel. An exchange needs
//! at least two frame round trips (write SM0, read SM1); the last column says how many
//! round trips' worth of time one upload takes.
//!
//! Run with `cargo bench -p master-core --bench mailbox`.

#[path = "../tests/mailbox_support/mod.rs"]
mod mailbox_support;

use std::time::{Duration, Instant};

use mailbox_support::{Rig, bus_config, station};
use master_core::link::FaultConfig;
use master_core::mailbox::{MailboxConfig, SlaveMailbox};
use sim::topology::Topology;

const WARMUP: usize = 200;
const UPLOADS: usize = 5000;
const PARALLEL: usize = 16;

fn percentile(sorted: &[Duration], p: f64) -> Duration {
    let at = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[at.min(sorted.len() - 1)]
}

struct Row {
    name: String,
    samples: Vec<Duration>,
    elapsed: Duration,
    operations: usize,
}

impl Row {
    fn print(&mut self, round_trip: Duration) {
        self.samples.sort_unstable();
        let p50 = percentile(&self.samples, 0.50);
        let p99 = percentile(&self.samples, 0.99);
        let rate = self.operations as f64 / self.elapsed.as_secs_f64();
        let trips = p50.as_secs_f64() / round_trip.as_secs_f64();
        println!(
            "{:<34} {:>10.1} {:>10.1} {:>12.0} {:>10.1}",
            self.name,
            p50.as_secs_f64() * 1e6,
            p99.as_secs_f64() * 1e6,
            rate,
            trips
        );
    }
}

async fn uploads(slave: SlaveMailbox, count: usize) -> Vec<Duration> {
    let mut samples = Vec::with_capacity(count);
    for _ in 0..count {
        let start = Instant::now();
        let value = slave.sdo_upload(0x1018, 1).await.expect("upload");
        samples.push(start.elapsed());
        assert_eq!(value.len(), 4);
    }
    samples
}

fn main() {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    // 16 drives: every fifth slave of the repeated default segment. Idle polling is off,
    // so only the measured requests use the bus.
    let config = MailboxConfig {
        idle_poll: None,
        ..MailboxConfig::default()
    };
    let rig = Rig::start_with(
        &Topology::repeated(5 * PARALLEL),
        FaultConfig::default(),
        1,
        bus_config(),
        config,
        |_, _| {},
    );
    let drives: Vec<SlaveMailbox> = (0..PARALLEL).map(|i| rig.slave(i * 5)).collect();

    // The raw frame round trip: one FPRD of the AL status.
    let mut frames = Vec::with_capacity(UPLOADS);
    let start = Instant::now();
    for _ in 0..UPLOADS {
        let t = Instant::now();
        rig.bus.fprd(station(0), 0x0130, 2).wait().expect("fprd");
        frames.push(t.elapsed());
    }
    let mut frame_row = Row {
        name: "bus: FPRD round trip".into(),
        samples: frames,
        elapsed: start.elapsed(),
        operations: UPLOADS,
    };
    let mut sorted = frame_row.samples.clone();
    sorted.sort_unstable();
    let round_trip = percentile(&sorted, 0.5);

    let one = runtime.block_on(async {
        uploads(drives[0].clone(), WARMUP).await;
        let start = Instant::now();
        let samples = uploads(drives[0].clone(), UPLOADS).await;
        Row {
            name: "SDO upload, 1 slave".into(),
            samples,
            elapsed: start.elapsed(),
            operations: UPLOADS,
        }
    });
    let parallel = runtime.block_on(async {
        let per_slave = UPLOADS / PARALLEL * 2;
        let start = Instant::now();
        let tasks: Vec<_> = drives
            .iter()
            .map(|d| tokio::spawn(uploads(d.clone(), per_slave)))
            .collect();
        let mut samples = Vec::new();
        for task in tasks {
            samples.extend(task.await.expect("task"));
        }
        Row {
            name: format!("SDO upload, {PARALLEL} slaves in parallel"),
            samples,
            elapsed: start.elapsed(),
            operations: per_slave * PARALLEL,
        }
    });

    println!(
        "{:<34} {:>10} {:>10} {:>12} {:>10}",
        "in-process simulator", "p50 µs", "p99 µs", "ops/s", "p50/RTT"
    );
    frame_row.print(round_trip);
    let mut one = one;
    one.print(round_trip);
    let mut parallel = parallel;
    parallel.print(round_trip);
    let stats = rig.bus.stats();
    println!(
        "bus: {} frames, {} datagrams ({:.1} per frame), {} lost",
        stats.frames_sent,
        stats.datagrams_sent,
        stats.datagrams_sent as f64 / stats.frames_sent.max(1) as f64,
        stats.frames_lost
    );
}
