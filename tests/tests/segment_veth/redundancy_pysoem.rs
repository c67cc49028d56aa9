//! pysoem (SOEM's cable redundancy) on a ring: `ecat-sim --iface sim0 --backup-iface sim1`
//! in one network namespace, pysoem opened on both ports (`mst0` primary, `mst1` backup) in
//! the other, two veth pairs between them. pysoem brings the segment to OP and keeps the
//! process-data cycle running while the test cuts a cable in the middle of the ring
//! (`break`) and then reconnects it (`heal`) through ecat-sim's `--control`; it reports
//! over its stdout (tests/py/pysoem_ring.py) and waits for the test's word on its stdin.
//! Every expected value comes from the built-in topology.
//!
//! Needs root and the venv from `scripts/test` (see tests/README.md).

use std::io::{BufRead, BufReader, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use ecat_tests::netns::NetNs;
use ecat_tests::pysoem_session::{plan, u};
use ecat_tests::python::{python, script};
use ecat_tests::rig::{MASTER_BACKUP_IFACE, MASTER_IFACE, Rig, SIM_BACKUP_IFACE, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use serde_json::Value;
use sim::topology::Topology;

/// The cable the test cuts: the one after this many slaves.
const BREAK_AFTER: usize = 2;
/// How long one step of the script may take (bring-up, or its cycles after a change).
const STEP_PATIENCE: Duration = Duration::from_secs(120);
/// Cycles with a short working counter the test accepts around a change: SOEM resends a
/// frame that came back partial within its 2 ms timeout, which a loaded machine can miss
/// now and then; a broken redundancy misses every cycle (hundreds).
const BAD_CYCLES_ALLOWED: u64 = 30;

/// The pysoem script, running in the master's namespace.
struct Script {
    child: Child,
    stdin: ChildStdin,
    lines: mpsc::Receiver<String>,
    stderr_path: std::path::PathBuf,
}

impl Script {
    fn start(ns: &NetNs, sdo_slave: usize) -> Script {
        let stderr_path =
            std::env::temp_dir().join(format!("pysoem-ring-{}.stderr", std::process::id()));
        let stderr = std::fs::File::create(&stderr_path).expect("create the stderr file");
        let mut child = Command::new("ip")
            .args(["netns", "exec", ns.name()])
            .arg(python())
            .arg(script("pysoem_ring.py"))
            .args([MASTER_IFACE, MASTER_BACKUP_IFACE, "--sdo"])
            .arg(sdo_slave.to_string())
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .unwrap_or_else(|e| panic!("cannot run pysoem_ring.py through `ip netns exec`: {e}"));
        let stdout = child.stdout.take().expect("piped stdout");
        let stdin = child.stdin.take().expect("piped stdin");
        // A reader thread hands over lines, so each wait has a deadline.
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Script {
            child,
            stdin,
            lines,
            stderr_path,
        }
    }

    /// Waits for the report of `step` (other lines, the library's own, are passed over).
    fn report(&mut self, step: &str) -> Value {
        let deadline = Instant::now() + STEP_PATIENCE;
        let mut seen = Vec::new();
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let Ok(line) = self.lines.recv_timeout(left) else {
                panic!(
                    "no {step:?} report from pysoem_ring.py within {STEP_PATIENCE:?} (or it \
                     ended); stdout: {seen:?}; stderr: {}",
                    std::fs::read_to_string(&self.stderr_path).unwrap_or_default()
                );
            };
            if let Ok(report) = serde_json::from_str::<Value>(&line)
                && report["step"] == step
            {
                return report;
            }
            seen.push(line);
        }
    }

    /// Tells the script the next change is made.
    fn tell(&mut self, word: &str) {
        writeln!(self.stdin, "{word}").expect("write to pysoem_ring.py's stdin");
        self.stdin.flush().expect("flush pysoem_ring.py's stdin");
    }

    /// Waits for the script to end and checks it succeeded.
    fn finish(mut self) {
        let deadline = Instant::now() + STEP_PATIENCE;
        loop {
            if let Some(status) = self.child.try_wait().expect("wait for pysoem_ring.py") {
                assert!(
                    status.success(),
                    "pysoem_ring.py failed ({status}): {}",
                    std::fs::read_to_string(&self.stderr_path).unwrap_or_default()
                );
                return;
            }
            assert!(Instant::now() < deadline, "pysoem_ring.py did not end");
            // A bounded poll of the exit status, not a synchronisation sleep.
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

impl Drop for Script {
    fn drop(&mut self) {
        // Never panic here: we may be unwinding from a failed assertion.
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
        let _ = std::fs::remove_file(&self.stderr_path);
    }
}

/// The cycle counts of a report: every slave in OP, the last cycles' working counters
/// full, and at most a few short ones since the last report.
fn check_cycles(report: &Value, slaves: usize) {
    let step = report["step"].as_str().unwrap_or("?");
    let expected = u(&report["expected_wkc"]);
    assert!(expected > 0, "{step}: expected working counter");
    let bad = u(&report["bad_cycles"]);
    println!(
        "{step}: {bad} of {} cycles with a working counter other than {expected}",
        u(&report["cycles"])
    );
    assert!(bad <= BAD_CYCLES_ALLOWED, "{step}: {bad} short cycles");
    let last: Vec<u64> = report["last_wkc"]
        .as_array()
        .unwrap()
        .iter()
        .map(u)
        .collect();
    assert!(!last.is_empty());
    assert!(
        last.iter().all(|&wkc| wkc == expected),
        "{step}: last cycles {last:?}"
    );
    let states: Vec<u64> = report["states"].as_array().unwrap().iter().map(u).collect();
    assert_eq!(states, vec![8; slaves], "{step}: every slave in OP");
}

/// DL status 0x0110's physical link bits of ports 0 and 1, by slave.
fn links(report: &Value) -> Vec<(bool, bool)> {
    report["dl_status"]
        .as_array()
        .unwrap()
        .iter()
        .map(|status| {
            let status = u(status);
            (status & 0x10 != 0, status & 0x20 != 0)
        })
        .collect()
}

#[test]
fn pysoem_keeps_every_slave_in_op_across_a_cable_break_in_the_ring() {
    let topology = Topology::default_segment();
    let n = topology.slaves.len();
    assert!(BREAK_AFTER > 0 && BREAK_AFTER < n);
    // A CoE slave behind the break: after it, only the backup port reaches it.
    let sdo_slave = *plan(&topology).coe.last().expect("a CoE slave");
    assert!(
        sdo_slave >= BREAK_AFTER,
        "the SDO slave sits behind the break"
    );
    let vendor = u64::from(topology.slaves[sdo_slave].vendor_id);

    let rig = Rig::ring();
    let mut sim =
        SimProcess::start_controlled(&rig.sim, SIM_IFACE, &["--backup-iface", SIM_BACKUP_IFACE]);
    assert!(
        sim.banner.iter().any(|line| line.contains("ring:")),
        "ecat-sim says it serves a ring: {:?}",
        sim.banner
    );
    let mut pysoem = Script::start(&rig.master, sdo_slave);

    // The closed ring: every slave found through it, in OP with a full working counter.
    let op = pysoem.report("op");
    assert_eq!(u(&op["slave_count"]), n as u64);
    for (p, spec) in topology.slaves.iter().enumerate() {
        let seen = &op["slaves"][p];
        assert_eq!(seen["name"], spec.name.as_str(), "slave {p}");
        assert_eq!(u(&seen["vendor"]), u64::from(spec.vendor_id), "slave {p}");
        assert_eq!(
            u(&seen["product"]),
            u64::from(spec.product_code),
            "slave {p}"
        );
    }
    assert_eq!(u(&op["safeop"]), 4, "SAFEOP reached");
    assert_eq!(u(&op["op"]), 8, "OP reached");
    assert_eq!(u(&op["vendor"]), vendor, "0x1018:01 of slave {sdo_slave}");
    assert!(
        links(&op).iter().all(|&l| l == (true, true)),
        "a closed ring: {op}"
    );
    check_cycles(&op, n);

    // Cut the cable after BREAK_AFTER slaves while pysoem cycles.
    sim.command(&format!("break {BREAK_AFTER}"));
    pysoem.tell("broken");
    let broken = pysoem.report("broken");
    check_cycles(&broken, n);
    assert_eq!(u(&broken["vendor"]), vendor, "SDO read behind the break");
    let seen = links(&broken);
    for (p, &(port0, port1)) in seen.iter().enumerate() {
        assert_eq!(
            port0,
            p != BREAK_AFTER,
            "slave {p} port 0 after the break: {seen:?}"
        );
        assert_eq!(
            port1,
            p + 1 != BREAK_AFTER,
            "slave {p} port 1 after the break: {seen:?}"
        );
    }

    // Reconnect it.
    sim.command("heal");
    pysoem.tell("healed");
    let healed = pysoem.report("healed");
    check_cycles(&healed, n);
    assert_eq!(u(&healed["vendor"]), vendor);
    assert!(
        links(&healed).iter().all(|&l| l == (true, true)),
        "healed: {healed}"
    );

    pysoem.finish();
    let status = sim.stop();
    assert!(status.success(), "ecat-sim exit after SIGTERM: {status}");
}
