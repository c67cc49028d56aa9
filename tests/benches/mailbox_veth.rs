//! SDO upload latency and throughput through ecatd's mailbox engine on the veth rig, next to
//! pysoem's `sdo_read` on the same simulator and the raw frame round trip.
//!
//! ```text
//! cargo bench -p ecat-tests --bench mailbox_veth
//! ```
//!
//! Needs root and the venv from `scripts/test` (pysoem). The simulator runs 16 drives
//! (CoE slaves with 128-byte mailboxes). Rows:
//! - one FPRD through the bus: the frame round trip, the floor of any exchange;
//! - ecatd, one slave: sequential uploads of 0x1018:01 (an expedited upload: one request
//!   and one answer, so at least two frame round trips: write, then read);
//! - ecatd, 16 slaves in parallel: one caller per slave;
//! - pysoem, one slave: SOEM's blocking `sdo_read` of the same object.
//!
//! `MAILBOX_VETH_COUNT` (default 2000) sets the uploads per row. Not part of CI.

#![allow(missing_docs)]

#[path = "support/latency.rs"]
mod latency;

use std::time::Instant;

use ecat_tests::python::run_script;
use ecat_tests::rig::{MASTER_IFACE, Rig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use ecat_tests::veth_master::VethMaster;
use latency::{Row, row};
use master_core::master::{MasterConfig, SlaveAddress};
use master_core::wire::register::AlState;
use sim::topology::Topology;

const SLAVES: usize = 16;

fn topology() -> Topology {
    let drive = Topology::default_segment().slaves[0].clone();
    let slaves = (0..SLAVES)
        .map(|p| {
            let mut slave = drive.clone();
            slave.serial = p as u32 + 1;
            slave.eoe = None;
            slave
        })
        .collect();
    Topology { slaves }
}

fn print(name: &str, r: &Row) {
    latency::print(name, 44, r);
}

fn main() {
    let count: usize = std::env::var("MAILBOX_VETH_COUNT")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2000)
        .max(10);
    let file =
        std::env::temp_dir().join(format!("ecatd-mailbox-bench-{}.toml", std::process::id()));
    std::fs::write(&file, topology().to_toml().expect("toml")).expect("topology file");
    let path = file.to_str().expect("utf-8 path").to_owned();
    println!(
        "SDO upload of 0x1018:01 over veth against ecat-sim ({SLAVES} drives), {count} per row"
    );
    println!();
    println!(
        "{:<44} {:>10} {:>10} {:>12}",
        "path", "p50 µs", "p99 µs", "uploads/s"
    );

    {
        let rig = Rig::new();
        let _sim = SimProcess::start(&rig.sim, SIM_IFACE, &["--topology", &path]);
        let config = MasterConfig {
            target_state: AlState::PreOp,
            watch_interval: None,
            ..MasterConfig::default()
        };
        let veth = VethMaster::start(&rig, config);
        let report = veth.scan();
        assert!(report.failures.is_empty(), "{:?}", report.failures);
        let master = veth.master();

        // The frame round trip: one FPRD of AL status.
        let mut samples = Vec::with_capacity(count);
        let start = Instant::now();
        for _ in 0..count {
            let t = Instant::now();
            master.bus().fprd(1001, 0x0130, 2).wait().expect("FPRD");
            samples.push(t.elapsed());
        }
        print(
            "one FPRD through the bus (frame round trip)",
            &row(samples, start.elapsed()),
        );

        // One slave, sequential uploads.
        let drive = master.mailbox(SlaveAddress::Position(0)).expect("mailbox");
        for _ in 0..count / 10 {
            veth.block_on(drive.sdo_upload(0x1018, 1)).expect("warm-up");
        }
        let mut samples = Vec::with_capacity(count);
        let start = Instant::now();
        for _ in 0..count {
            let t = Instant::now();
            veth.block_on(drive.sdo_upload(0x1018, 1)).expect("upload");
            samples.push(t.elapsed());
        }
        print(
            "ecatd mailbox engine, 1 slave",
            &row(samples, start.elapsed()),
        );

        // Every slave at once, one caller each.
        let mailboxes: Vec<_> = (0..SLAVES as u16)
            .map(|p| master.mailbox(SlaveAddress::Position(p)).expect("mailbox"))
            .collect();
        let per_slave = count / SLAVES + 1;
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
        print(
            &format!("ecatd mailbox engine, {SLAVES} slaves in parallel"),
            &row(samples, start.elapsed()),
        );
    }

    {
        let rig = Rig::new();
        let _sim = SimProcess::start(&rig.sim, SIM_IFACE, &["--topology", &path]);
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
        );
    }
    let _ = std::fs::remove_file(&file);
}
