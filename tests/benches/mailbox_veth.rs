//! SDO upload latency and throughput through ecatd's mailbox engine on the veth rig, next to
//! pysoem's `sdo_read` on the same simulator and the raw frame round trip.
//!
//! ```text
//! cargo bench -p ecat-tests --bench mailbox_veth
//! ```
//!
//! Needs root and the venv from `scripts/test` (pysoem). The simulator runs 16 drives
//! (CoE slaves with 128-byte mailboxes). Rows, for each simulated response delay:
//! - one FPRD through the bus: the frame round trip, the floor of any exchange;
//! - ecatd, one slave: sequential uploads of 0x1018:01 (an expedited upload: one request
//!   and one answer; the first read of SM1 rides in the write's frame);
//! - ecatd, 16 slaves in parallel: one caller per slave;
//! - pysoem, one slave: SOEM's blocking `sdo_read` of the same object.
//!
//! Besides p50, p99 and uploads/s, each ecatd row shows the acyclic datagrams per upload
//! (the write and every read of SM1) and the bus thread's own frame round trip (send to
//! receive, p50), so that the time spent outside the wire shows as the difference, and how
//! late the 1 ms cycle started meanwhile (p99 of the bus's cycle-start delay).
//!
//! Environment (all optional):
//! - `MAILBOX_VETH_COUNT` (default 2000): uploads per row;
//! - `MAILBOX_VETH_DELAYS` (default `0,100,1000`): the slaves' response delays in µs
//!   (the topology's `response_delay_us`), one block of rows each;
//! - `MAILBOX_VETH_STATE` (`op`, default, or `preop`): the state ecatd takes the slaves to;
//!   in OP the 1 ms cycle runs and carries the mailbox-status bits;
//! - `MAILBOX_VETH_SPIN_US` (default: the raw socket's default): the master socket's spin
//!   window before it sleeps for a frame (`RawSocketOptions::spin`);
//! - `MAILBOX_VETH_SIM_SPIN_US` (default 0): ecat-sim's `--spin-us`.
//!
//! Not part of CI.

#![allow(missing_docs)]

#[path = "support/latency.rs"]
#[allow(dead_code)]
mod latency;

use std::collections::HashMap;
use std::time::{Duration, Instant};

use ecat_tests::python::run_script;
use ecat_tests::rig::{MASTER_IFACE, Rig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use ecat_tests::veth_master::VethMaster;
use latency::{Row, row};
use master_core::bus::{BusConfig, BusStatsSnapshot, HistogramSnapshot};
use master_core::link::{RawSocket, RawSocketOptions};
use master_core::master::{Master, MasterConfig, SlaveAddress};
use master_core::wire::register::AlState;
use sim::topology::Topology;

const SLAVES: usize = 16;

fn topology(delay_us: u32) -> Topology {
    let drive = Topology::default_segment().slaves[0].clone();
    let slaves = (0..SLAVES)
        .map(|p| {
            let mut slave = drive.clone();
            slave.serial = p as u32 + 1;
            slave.eoe = None;
            slave.esc.response_delay_us = delay_us;
            slave
        })
        .collect();
    Topology {
        slaves,
        ring: false,
    }
}

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|v| v.trim().parse().ok())
}

/// What the bus did during one row.
struct Traffic {
    datagrams_per_upload: f64,
    round_trip_p50_us: f64,
    /// How late cycles started meanwhile (p99): mailbox traffic must not hold them up.
    cycle_delay_p99_us: f64,
}

fn traffic(before: &BusStatsSnapshot, after: &BusStatsSnapshot, uploads: usize) -> Traffic {
    Traffic {
        datagrams_per_upload: (after.datagrams_sent - before.datagrams_sent) as f64
            / uploads as f64,
        round_trip_p50_us: quantile_between(&before.round_trip, &after.round_trip, 0.5),
        cycle_delay_p99_us: quantile_between(
            &before.cycle_start_delay,
            &after.cycle_start_delay,
            0.99,
        ),
    }
}

/// The `q` quantile of what was recorded between two snapshots (bucket middles), in µs.
fn quantile_between(before: &HistogramSnapshot, after: &HistogramSnapshot, q: f64) -> f64 {
    let old: HashMap<Duration, u64> = before.buckets().map(|(low, _, n)| (low, n)).collect();
    let new: Vec<(Duration, Duration, u64)> = after
        .buckets()
        .map(|(low, high, n)| (low, high, n - old.get(&low).copied().unwrap_or(0)))
        .collect();
    let total: u64 = new.iter().map(|b| b.2).sum();
    let mut seen = 0;
    for (low, high, n) in new {
        seen += n;
        if total > 0 && seen as f64 >= q * total as f64 {
            return (low + (high - low) / 2).as_secs_f64() * 1e6;
        }
    }
    f64::NAN
}

fn header() {
    println!(
        "{:<44} {:>10} {:>10} {:>12} {:>10} {:>10} {:>12}",
        "path", "p50 µs", "p99 µs", "uploads/s", "dgrams/op", "bus rtt µs", "cycle late µs"
    );
}

fn print(name: &str, r: &Row, t: Option<&Traffic>) {
    match t {
        Some(t) => println!(
            "{name:<44} {:>10.1} {:>10.1} {:>12.0} {:>10.2} {:>10.1} {:>12.1}",
            r.p50,
            r.p99,
            r.per_second,
            t.datagrams_per_upload,
            t.round_trip_p50_us,
            t.cycle_delay_p99_us
        ),
        None => latency::print(name, 44, r),
    }
}

fn main() {
    let count: usize = env("MAILBOX_VETH_COUNT").unwrap_or(2000).max(10);
    let delays: Vec<u32> = std::env::var("MAILBOX_VETH_DELAYS")
        .unwrap_or_else(|_| "0,100,1000".into())
        .split(',')
        .filter_map(|d| d.trim().parse().ok())
        .collect();
    let state = match std::env::var("MAILBOX_VETH_STATE").as_deref() {
        Ok("preop") => AlState::PreOp,
        _ => AlState::Op,
    };
    let mut socket = RawSocketOptions::default();
    if let Some(us) = env::<u64>("MAILBOX_VETH_SPIN_US") {
        socket.spin = Duration::from_micros(us);
    }
    let sim_spin: u32 = env("MAILBOX_VETH_SIM_SPIN_US").unwrap_or(0);
    println!(
        "SDO upload of 0x1018:01 over veth against ecat-sim ({SLAVES} drives), {count} per row; \
         ecatd in {state:?}, master socket spin {:?}, sim spin {sim_spin} µs",
        socket.spin
    );
    for delay in delays {
        println!();
        println!("slave response delay {delay} µs");
        header();
        block(count, delay, state, socket, sim_spin);
    }
}

fn block(count: usize, delay: u32, state: AlState, socket: RawSocketOptions, sim_spin: u32) {
    let file = std::env::temp_dir().join(format!(
        "ecatd-mailbox-bench-{}-{delay}.toml",
        std::process::id()
    ));
    std::fs::write(&file, topology(delay).to_toml().expect("toml")).expect("topology file");
    let path = file.to_str().expect("utf-8 path").to_owned();
    let spin = sim_spin.to_string();
    let sim_args = ["--topology", path.as_str(), "--spin-us", spin.as_str()];
    {
        let rig = Rig::new();
        let _sim = SimProcess::start(&rig.sim, SIM_IFACE, &sim_args);
        let config = MasterConfig {
            target_state: state,
            watch_interval: None,
            ..MasterConfig::default()
        };
        let link = rig
            .master
            .run_inside(|| RawSocket::open(MASTER_IFACE, socket))
            .expect("raw socket on the master's end");
        let veth = VethMaster::on_link(Box::new(link), BusConfig::default(), config);
        let report = veth.scan();
        assert!(report.failures.is_empty(), "{:?}", report.failures);
        ecatd_rows(&veth, veth.master(), count);
    }
    {
        let rig = Rig::new();
        let _sim = SimProcess::start(&rig.sim, SIM_IFACE, &sim_args);
        let count = count.to_string();
        let r = run_script(
            &rig.master,
            "pysoem_sdo_bench.py",
            &[MASTER_IFACE, "--slave", "0", "--count", &count],
        );
        let value = |k: &str| r[k].as_f64().expect("a number");
        print(
            "pysoem sdo_read, 1 slave",
            &Row {
                p50: value("p50_us"),
                p99: value("p99_us"),
                per_second: value("per_second"),
            },
            None,
        );
    }
    let _ = std::fs::remove_file(&file);
}

fn ecatd_rows(veth: &VethMaster, master: &Master, count: usize) {
    let bus = master.bus();

    // The frame round trip: one FPRD of AL status.
    let mut samples = Vec::with_capacity(count);
    let before = bus.stats();
    let start = Instant::now();
    for _ in 0..count {
        let t = Instant::now();
        bus.fprd(1001, 0x0130, 2).wait().expect("FPRD");
        samples.push(t.elapsed());
    }
    let t = traffic(&before, &bus.stats(), count);
    print(
        "one FPRD through the bus (frame round trip)",
        &row(samples, start.elapsed()),
        Some(&t),
    );

    // One slave, sequential uploads.
    let drive = master.mailbox(SlaveAddress::Position(0)).expect("mailbox");
    for _ in 0..count / 10 {
        veth.block_on(drive.sdo_upload(0x1018, 1)).expect("warm-up");
    }
    let mut samples = Vec::with_capacity(count);
    let before = bus.stats();
    let start = Instant::now();
    for _ in 0..count {
        let t = Instant::now();
        veth.block_on(drive.sdo_upload(0x1018, 1)).expect("upload");
        samples.push(t.elapsed());
    }
    let t = traffic(&before, &bus.stats(), count);
    print(
        "ecatd mailbox engine, 1 slave",
        &row(samples, start.elapsed()),
        Some(&t),
    );

    // Every slave at once, one caller each.
    let mailboxes: Vec<_> = (0..SLAVES as u16)
        .map(|p| master.mailbox(SlaveAddress::Position(p)).expect("mailbox"))
        .collect();
    let per_slave = count / SLAVES + 1;
    let before = bus.stats();
    let start = Instant::now();
    let samples = veth.block_on(async {
        let mut tasks = tokio::task::JoinSet::new();
        for mailbox in mailboxes {
            tasks.spawn(async move {
                let mut samples = Vec::with_capacity(per_slave);
                for _ in 0..per_slave {
                    let t = Instant::now();
                    mailbox.sdo_upload(0x1018, 1).await.expect("upload");
                    samples.push(t.elapsed());
                }
                samples
            });
        }
        let mut all = Vec::new();
        while let Some(joined) = tasks.join_next().await {
            all.extend(joined.expect("caller"));
        }
        all
    });
    let t = traffic(&before, &bus.stats(), per_slave * SLAVES);
    print(
        &format!("ecatd mailbox engine, {SLAVES} slaves in parallel"),
        &row(samples, start.elapsed()),
        Some(&t),
    );
}
