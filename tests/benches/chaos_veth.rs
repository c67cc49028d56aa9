//! Issue 35's chaos soak: ecatd on the veth rig while the cable is cut every 20 s and the
//! simulator is killed (SIGKILL: a segment losing power) and started again every 90 s,
//! with every kind of client at work the whole time.
//!
//! ```text
//! cargo bench -p ecat-tests --bench chaos_veth
//! CHAOS_SECONDS=120 cargo bench -p ecat-tests --bench chaos_veth
//! ```
//!
//! The rig is the EoE one (`tests/tests/eoe_support/rig.rs`): ecatd `--iface` in its own
//! namespace, `ecat-sim --eoe-tap --control` in another, `iperf3 -s -1` on the simulator's
//! side behind the drive's EoE. For `CHAOS_SECONDS` (default 600) these run without pause:
//! - two ETG.8200 gateway clients, SDO uploads of 0x1018:01 (the drive, and the segment's
//!   other CoE slave);
//! - a REST client and a gRPC client, the same upload from the drive;
//! - an FoE loop over REST: 64 KiB written to the drive and read back;
//! - iperf3 TCP for 5 s at a time through the drive's EoE (after a power loss the device
//!   has lost its IP settings: the bench sets them again through the API once the slaves
//!   are back, as an operator's script would, and so does the loop after a failed run; both
//!   are counted; each run has an `iperf3 -s -1` of its own, since iperf3's server serves
//!   one test at a time and would hold a test broken by a fault until an idle timeout);
//! - an application-interface owner (`ecat-app`) writing a pattern to the DO8 every cycle,
//!   claiming the outputs again whenever it lost them.
//!
//! Every request ends in one of three ways: answered (the expected value), failed with a
//! clear error (a problem+json body, a gRPC status with a message, a gateway mailbox error
//! or SDO abort, iperf3's own error), or lost (no answer within the client's deadline, or a
//! wrong value). After each fault the bench waits until every slave is present and in OP
//! again (the time it took is printed; 60 s at most). On each cut it checks that the safe
//! outputs were applied at both ends: ecatd's application watchdog tripped
//! (`ecat_app_watchdog_trips_total`), so the frames after the cut carry the safe outputs,
//! and the DO8 itself went to 00 (its SyncManager watchdog, reported by `ecat-sim
//! --control`). ecatd's resident memory is sampled after the first fault and at the end.
//!
//! Goals, judged in the printout, not asserted: 0 lost, every slave back in OP after every
//! fault, the safe outputs on every cut, RSS flat (≤ 4 MiB growth). Needs root and `iperf3`.
//! Not part of CI (10 minutes, and the figures depend on the machine).

#![allow(missing_docs)]

#[path = "../tests/eoe_support/mod.rs"]
mod eoe_support;
#[path = "../tests/server_support/mod.rs"]
mod server_support;

use std::collections::BTreeMap;
use std::net::{Ipv4Addr, SocketAddr};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ecat_tests::netns::NetNs;
use ecat_tests::rig::{MASTER_IFACE, Rig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use eoe_support::EcatdInNs;
use eoe_support::rig::{DEVICE_IP, SET_IP};
use master_core::wire::coe::{CoeRepr, SdoFrame, SdoPayload, SdoRequest, SdoResponse};
use master_core::wire::mailbox::MailboxType;
use server_support::gateway_client::{GatewayClient, coe_bytes};
use sim::topology::{Protocol, SIM_VENDOR_ID, Topology};

const TAP: &str = "eoedev0";
const GATEWAY: &str = "127.0.0.1:34980";
const HTTP: &str = "http://127.0.0.1:8080";
const GRPC: &str = "http://127.0.0.1:50051";
/// The DO8 and its outputs (the default segment's slave 1, 0x7000:01..08).
const DO8: u16 = 1;
/// What the owner writes to the DO8's eight outputs (bit per output).
const PATTERN: u8 = 0xA5;
/// How long a cut lasts: well beyond the slaves' SyncManager watchdog (100 ms) and
/// ecatd's application watchdog (10 cycles).
const CUT: Duration = Duration::from_secs(3);
/// The longest a client waits for one answer before it counts the request lost.
const ANSWER_DEADLINE: Duration = Duration::from_secs(30);
/// The longest the segment may take to be back in OP after a fault.
const RECOVERY_DEADLINE: Duration = Duration::from_secs(60);
/// Growth of ecatd's resident set that still counts as flat.
const FLAT_KIB: u64 = 4 << 10;

/// ecatd's configuration: the drive's EoE interface, the owner's socket.
fn config(socket: &Path) -> String {
    format!(
        r#"
[eoe]
name_scheme = "position"

[[eoe.slave]]
slave = "0"
host_address = "10.78.0.1/24"

[app]
socket = "{}"
"#,
        socket.display()
    )
}

/// How the requests of one client ended.
#[derive(Default)]
struct Tally {
    answered: AtomicU64,
    failed: AtomicU64,
    lost: AtomicU64,
    /// Failures and losses by their message (the first words), for the printout.
    why: Mutex<BTreeMap<String, u64>>,
}

impl Tally {
    fn answered(&self) {
        self.answered.fetch_add(1, Ordering::Relaxed);
    }

    fn failed(&self, why: &str) {
        self.failed.fetch_add(1, Ordering::Relaxed);
        self.note(why);
    }

    fn lost(&self, why: &str) {
        self.lost.fetch_add(1, Ordering::Relaxed);
        self.note(&format!("LOST: {why}"));
    }

    fn note(&self, why: &str) {
        let short: String = why.chars().take(90).collect();
        *self.why.lock().unwrap().entry(short).or_default() += 1;
    }
}

/// The clients' tallies, by name, in the order printed.
struct Tallies(Vec<(&'static str, Arc<Tally>)>);

impl Tallies {
    fn add(&mut self, name: &'static str) -> Arc<Tally> {
        let tally = Arc::new(Tally::default());
        self.0.push((name, Arc::clone(&tally)));
        tally
    }
}

// --- the clients ----------------------------------------------------------------------------

/// SDO uploads of 0x1018:01 from `station` through the gateway.
fn gateway_client(ns: &NetNs, station: u16, host: u8, tally: &Tally, stop: &AtomicBool) {
    ns.enter_current_thread();
    let server: SocketAddr = GATEWAY.parse().unwrap();
    let mut client = GatewayClient::from_host(Ipv4Addr::new(127, 0, 0, host), server);
    let request = coe_bytes(&CoeRepr::SdoRequest(SdoRequest::InitiateUpload {
        index: 0x1018,
        subindex: 1,
        complete_access: false,
    }));
    while !stop.load(Ordering::Relaxed) {
        client.send(station, MailboxType::Coe, &request);
        let Some(reply) = client.recv_within(ANSWER_DEADLINE) else {
            tally.lost("no gateway reply");
            // A reply that comes after all must not be taken for the next request's.
            while client.recv_within(Duration::ZERO).is_some() {}
            continue;
        };
        if reply.header.mailbox_type != MailboxType::Coe {
            // A mailbox error reply (ETG.8200): the gateway's clear "could not".
            tally.failed(&format!(
                "gateway: {:?} {:02x?}",
                reply.header.mailbox_type,
                &reply.data[..reply.data.len().min(4)]
            ));
            continue;
        }
        let Ok(sdo) = SdoFrame::new_checked(&reply.data[..]) else {
            tally.lost("gateway: not an SDO frame");
            continue;
        };
        match SdoResponse::parse(&sdo) {
            Ok(SdoResponse::InitiateUpload {
                payload: SdoPayload::Expedited(data),
                ..
            }) if data == SIM_VENDOR_ID.to_le_bytes() => tally.answered(),
            Ok(SdoResponse::Abort { code, .. }) => {
                tally.failed(&format!("gateway: SDO abort {:#010x}", u32::from(code)));
            }
            other => tally.lost(&format!("gateway: unexpected {other:?}")),
        }
    }
}

/// A REST agent that returns error statuses as answers (their bodies are the point).
fn rest_agent() -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(ANSWER_DEADLINE))
        .build()
        .into()
}

/// One REST answer: 200 with its body, or a clear error (problem+json), or lost.
fn rest_outcome(
    result: Result<ureq::http::Response<ureq::Body>, ureq::Error>,
    tally: &Tally,
) -> Option<Vec<u8>> {
    let mut response = match result {
        Ok(response) => response,
        Err(err) => {
            tally.lost(&format!("REST: {err}"));
            return None;
        }
    };
    let status = response.status().as_u16();
    let problem = response
        .headers()
        .get("content-type")
        .is_some_and(|v| v.as_bytes().starts_with(b"application/problem+json"));
    let body = match response
        .body_mut()
        .with_config()
        .limit(1 << 20)
        .read_to_vec()
    {
        Ok(body) => body,
        Err(err) => {
            tally.lost(&format!("REST body: {err}"));
            return None;
        }
    };
    if status == 200 {
        return Some(body);
    }
    let detail = serde_json::from_slice::<serde_json::Value>(&body)
        .ok()
        .and_then(|v| v["detail"].as_str().map(str::to_owned));
    match (problem, detail) {
        (true, Some(detail)) => tally.failed(&format!("REST {status}: {detail}")),
        _ => tally.lost(&format!(
            "REST {status} without a problem: {}",
            String::from_utf8_lossy(&body)
        )),
    }
    None
}

/// SDO uploads of 0x1018:01 from the drive over REST.
fn rest_client(ns: &NetNs, tally: &Tally, stop: &AtomicBool) {
    ns.enter_current_thread();
    let agent = rest_agent();
    let url = format!("{HTTP}/api/v1/slaves/0/coe/sdo/0x1018/1");
    while !stop.load(Ordering::Relaxed) {
        let result = agent.get(&url).header("X-Ecat-Client", "chaos").call();
        if let Some(body) = rest_outcome(result, tally) {
            let upload: serde_json::Value = serde_json::from_slice(&body).unwrap_or_default();
            let vendor: String = SIM_VENDOR_ID
                .to_le_bytes()
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect();
            if upload["data"] == vendor.as_str() {
                tally.answered();
            } else {
                tally.lost(&format!("REST: wrong value {upload}"));
            }
        }
    }
}

/// SDO uploads of 0x1018:01 from the drive over gRPC (one HTTP/2 connection).
fn grpc_client(ns: &NetNs, tally: &Tally, stop: &AtomicBool) {
    use proto::v1::UploadRequest;
    use proto::v1::coe_service_client::CoeServiceClient;
    ns.enter_current_thread();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime");
    // The lazy channel spawns its connection task on the current runtime.
    let channel = {
        let _runtime = runtime.enter();
        tonic::transport::Endpoint::from_static(GRPC)
            .timeout(ANSWER_DEADLINE)
            .connect_lazy()
    };
    let mut client = CoeServiceClient::new(channel);
    while !stop.load(Ordering::Relaxed) {
        let request = UploadRequest {
            slave: "0".into(),
            index: 0x1018,
            subindex: 1,
            ..UploadRequest::default()
        };
        // The timer is the runtime's: the timeout is made inside it.
        let call = async { tokio::time::timeout(ANSWER_DEADLINE, client.upload(request)).await };
        match runtime.block_on(call) {
            Ok(Ok(answer)) if answer.get_ref().data == SIM_VENDOR_ID.to_le_bytes() => {
                tally.answered()
            }
            Ok(Ok(answer)) => tally.lost(&format!("gRPC: wrong value {:?}", answer.get_ref())),
            Ok(Err(status)) if !status.message().is_empty() => {
                tally.failed(&format!("gRPC {:?}: {}", status.code(), status.message()))
            }
            Ok(Err(status)) => tally.lost(&format!("gRPC {:?} without a message", status.code())),
            Err(_) => tally.lost("gRPC: no answer"),
        }
    }
}

/// 64 KiB written to the drive over FoE and read back, again and again.
fn foe_client(ns: &NetNs, tally: &Tally, stop: &AtomicBool) {
    ns.enter_current_thread();
    let agent = rest_agent();
    let url = format!("{HTTP}/api/v1/slaves/0/foe/chaos.bin");
    let mut round = 0u8;
    while !stop.load(Ordering::Relaxed) {
        round = round.wrapping_add(1);
        let data: Vec<u8> = (0..64 << 10).map(|i: u32| (i as u8) ^ round).collect();
        let put = agent
            .put(&url)
            .header("X-Ecat-Client", "chaos")
            .header("content-type", "application/octet-stream")
            .send(&data[..]);
        if rest_outcome(put, tally).is_none() {
            continue;
        }
        let get = agent.get(&url).header("X-Ecat-Client", "chaos").call();
        match rest_outcome(get, tally) {
            Some(back) if back == data => tally.answered(),
            Some(back) => tally.lost(&format!(
                "FoE: read back {} bytes, not the file",
                back.len()
            )),
            None => {}
        }
    }
}

/// iperf3 TCP through the drive's EoE, 5 s at a time; sets the device's IP again when a
/// run could not reach it (a device that lost power lost its settings).
fn eoe_client(ns: &NetNs, sim_ns: &NetNs, tally: &Tally, set_ip: &AtomicU64, stop: &AtomicBool) {
    ns.enter_current_thread();
    let agent = rest_agent();
    while !stop.load(Ordering::Relaxed) {
        // A server of its own for each run: a test broken by a fault ends with its server.
        let server = IperfServer::start(sim_ns);
        if !server.listening(sim_ns) {
            tally.failed("iperf3 -s did not listen within 5 s");
            continue;
        }
        let out = Command::new("ip")
            .args(["netns", "exec", ns.name(), "timeout", "40"])
            .args(["iperf3", "-c", DEVICE_IP, "-t", "5", "-J"])
            .args(["--connect-timeout", "3000", "--snd-timeout", "10000"])
            .output()
            .expect("iperf3 runs");
        drop(server);
        let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_default();
        let bits = report["end"]["sum_received"]["bits_per_second"]
            .as_f64()
            .unwrap_or(0.0);
        match (out.status.code(), report["error"].as_str()) {
            (Some(0), _) if bits > 0.0 => {
                tally.answered();
                continue;
            }
            (Some(124), _) => tally.lost("iperf3 did not end (killed after 40 s)"),
            // It ended and reported: nothing came through (the fault cut the whole run).
            (Some(0), None) => tally.failed("iperf3: the run ended with 0 bits received"),
            (_, Some(error)) => tally.failed(&format!("iperf3: {error}")),
            (code, None) => {
                let said = String::from_utf8_lossy(&out.stderr);
                let said = said.lines().next().unwrap_or("");
                tally.lost(&format!("iperf3 exit {code:?} without a report: {said}"))
            }
        }
        // The device may have lost its settings: set them again (not counted as a request).
        set_device_ip(&agent, set_ip);
    }
}

/// Gives the drive's EoE device its IP settings through the API (a device that lost power
/// lost them), counting each time it was done.
fn set_device_ip(agent: &ureq::Agent, set_ip: &AtomicU64) {
    let put = agent
        .put(format!("{HTTP}/api/v1/slaves/0/eoe/ip"))
        .header("content-type", "application/json")
        .send(SET_IP);
    if put.is_ok_and(|r| r.status() == 200) {
        set_ip.fetch_add(1, Ordering::Relaxed);
    }
}

/// What the application-interface owner saw.
#[derive(Default)]
struct OwnerTally {
    commits: AtomicU64,
    claims: AtomicU64,
    why: Mutex<BTreeMap<String, u64>>,
}

/// Owns the DO8 and writes [`PATTERN`] every cycle; on any error, attaches and claims again.
fn owner(socket: &Path, tally: &OwnerTally, stop: &AtomicBool) {
    while !stop.load(Ordering::Relaxed) {
        let error = match own(socket, tally, stop) {
            Ok(()) => return,
            Err(error) => error,
        };
        let short: String = error.to_string().chars().take(90).collect();
        *tally.why.lock().unwrap().entry(short).or_default() += 1;
        // Back-off before attaching again (not a synchronisation: the next attempt decides).
        std::thread::sleep(Duration::from_millis(100));
    }
}

fn own(socket: &Path, tally: &OwnerTally, stop: &AtomicBool) -> Result<(), ecat_app::Error> {
    let mut app = ecat_app::App::connect(Some(socket), false)?;
    let outputs = (1..=8)
        .map(|ch| app.entry(DO8, 0x7000, ch))
        .collect::<Result<Vec<_>, _>>()?;
    app.claim()?;
    tally.claims.fetch_add(1, Ordering::Relaxed);
    while !stop.load(Ordering::Relaxed) {
        app.wait(Duration::from_secs(1))?;
        for (bit, entry) in outputs.iter().enumerate() {
            app.write(entry, i64::from(PATTERN >> bit & 1))?;
        }
        app.commit()?;
        tally.commits.fetch_add(1, Ordering::Relaxed);
    }
    app.release()
}

// --- the faults ------------------------------------------------------------------------------

/// The simulator's command line (after `--iface`).
fn sim_args() -> Vec<&'static str> {
    vec!["--eoe-tap", TAP]
}

/// `iperf3 -s -1` (one test) in the simulator's namespace on every address (the device's
/// TAP is made anew by a restarted simulator), killed on drop.
struct IperfServer(Child);

impl IperfServer {
    fn start(ns: &NetNs) -> IperfServer {
        let child = Command::new("ip")
            .args(["netns", "exec", ns.name(), "iperf3", "-s", "-1"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("iperf3 -s starts");
        IperfServer(child)
    }

    /// Whether it listens on iperf3's port within 5 s (asked of `ss`).
    fn listening(&self, ns: &NetNs) -> bool {
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            let out = Command::new("ip")
                .args(["netns", "exec", ns.name(), "ss", "-Hltn", "sport = :5201"])
                .output()
                .expect("ss runs");
            if !out.stdout.is_empty() {
                return true;
            }
            // The check's poll interval (the loop ends on the condition or the deadline).
            std::thread::sleep(Duration::from_millis(10));
        }
        false
    }
}

impl Drop for IperfServer {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// REST, from the master's namespace (the main thread entered it).
fn get_json(agent: &ureq::Agent, path: &str) -> Option<serde_json::Value> {
    let mut response = agent.get(format!("{HTTP}{path}")).call().ok()?;
    (response.status() == 200).then_some(())?;
    serde_json::from_slice(&response.body_mut().read_to_vec().ok()?).ok()
}

/// Whether every slave of the segment is present and in OP.
fn all_in_op(agent: &ureq::Agent, count: usize) -> bool {
    get_json(agent, "/api/v1/slaves").is_some_and(|v| {
        let slaves = v.as_array().or_else(|| v["slaves"].as_array()).cloned();
        slaves.is_some_and(|s| {
            s.len() == count
                && s.iter()
                    .all(|slave| slave["state"] == "OP" && slave["present"] != false)
        })
    })
}

/// One sample from ecatd's /metrics.
fn metric(agent: &ureq::Agent, name: &str) -> f64 {
    let Ok(mut response) = agent.get(format!("{HTTP}/metrics")).call() else {
        return f64::NAN;
    };
    let text = response.body_mut().read_to_string().unwrap_or_default();
    text.lines()
        .find_map(|l| l.strip_prefix(name)?.strip_prefix(' ')?.trim().parse().ok())
        .unwrap_or(f64::NAN)
}

fn rss_kib(pid: u32) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmRSS:"))
                .and_then(|v| v.split_whitespace().next()?.parse().ok())
        })
        .unwrap_or(0)
}

/// ecatd's pid: the child of `ip netns exec` is ecatd itself (ip execs it).
fn ecatd_pid(ns: &NetNs) -> u32 {
    let out = Command::new("ip")
        .args(["netns", "pids", ns.name()])
        .output()
        .expect("ip netns pids");
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.trim().parse::<u32>().ok())
        .find(|pid| {
            std::fs::read_to_string(format!("/proc/{pid}/comm")).is_ok_and(|c| c.trim() == "ecatd")
        })
        .expect("ecatd runs in its namespace")
}

const CABLE_CUT: &str = "cable cut";
const POWER_LOSS: &str = "power loss";

/// The faults in order: the simulator killed every 90 s, the cable cut every 20 s except
/// within 10 s of a kill.
fn schedule(length: Duration) -> Vec<(Duration, &'static str)> {
    let every = |period: u64| {
        (1..)
            .map(move |k| Duration::from_secs(k * period))
            .take_while(move |&at| at < length)
    };
    let kills: Vec<Duration> = every(90).collect();
    let mut faults: Vec<_> = every(20)
        .filter(|cut| {
            kills
                .iter()
                .all(|kill| cut.abs_diff(*kill) >= Duration::from_secs(10))
        })
        .map(|at| (at, CABLE_CUT))
        .chain(kills.iter().map(|&at| (at, POWER_LOSS)))
        .collect();
    faults.sort();
    faults
}

/// One fault and what followed it.
struct Fault {
    at: Duration,
    kind: &'static str,
    /// ecatd noticed it (a slave left OP or was lost) within 10 s.
    seen: bool,
    /// Time from the end of the fault to every slave in OP again (`None`: not within
    /// [`RECOVERY_DEADLINE`]).
    recovered: Option<Duration>,
    /// On a cut: ecatd's application watchdog tripped (the safe outputs into the frames).
    master_safe: Option<bool>,
    /// On a cut: the DO8 showed 00 (its own watchdog).
    slave_safe: Option<bool>,
}

/// Whether ecatd has seen the fault: a slave not in OP now, or slave events since the
/// fault began (`events`: their count before it).
fn noticed(agent: &ureq::Agent, count: usize, events: f64) -> bool {
    !all_in_op(agent, count) || slave_events(agent) > events
}

/// ecatd's events about slaves so far (lost, found, state changes, AL errors).
fn slave_events(agent: &ureq::Agent) -> f64 {
    ["slave_lost", "slave_found", "state_changed", "al_error"]
        .iter()
        .map(|kind| metric(agent, &format!("ecat_events_total{{kind=\"{kind}\"}}")))
        .filter(|v| v.is_finite())
        .sum()
}

/// Waits until every slave is in OP again, at most [`RECOVERY_DEADLINE`], once ecatd has
/// noticed the fault (at most 10 s: a fault it never notices is reported as such).
fn recover(agent: &ureq::Agent, count: usize, events: f64) -> (bool, Option<Duration>) {
    let start = Instant::now();
    let mut seen = false;
    while start.elapsed() < Duration::from_secs(10) {
        if noticed(agent, count, events) {
            seen = true;
            break;
        }
        // The check's poll interval (the loop ends on the condition or the deadline).
        std::thread::sleep(Duration::from_millis(20));
    }
    while start.elapsed() < RECOVERY_DEADLINE {
        if all_in_op(agent, count) {
            return (seen, Some(start.elapsed()));
        }
        // The check's poll interval (the loop ends on the condition or the deadline).
        std::thread::sleep(Duration::from_millis(50));
    }
    (seen, None)
}

/// Whether the simulator reported the DO8's outputs as `want` within `patience` (reports
/// already read are passed over).
fn saw_outputs(sim: &mut SimProcess, want: &str, patience: Duration) -> bool {
    let line = format!("ecat-sim: outputs {DO8} {want}");
    sim.wait_line(patience, |l| l == line).is_some()
}

fn env_secs(name: &str, default: u64) -> Duration {
    Duration::from_secs(
        std::env::var(name)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
            .max(1),
    )
}

fn main() {
    if Command::new("iperf3").arg("--version").output().is_err() {
        eprintln!("chaos_veth: iperf3 is not installed (Debian: apt-get install iperf3)");
        return;
    }
    let length = env_secs("CHAOS_SECONDS", 600);
    let topology = Topology::default_segment();
    let count = topology.slaves.len();
    let coe: Vec<u16> = topology
        .slaves
        .iter()
        .enumerate()
        .filter(|(_, s)| s.protocols.contains(&Protocol::Coe))
        .map(|(p, _)| 1001 + p as u16)
        .take(2)
        .collect();

    let bin_dir = server_support::bin_dir();
    let Rig {
        sim: sim_ns,
        master,
    } = Rig::new();
    let mut sim = Some(SimProcess::start_controlled(
        &sim_ns,
        SIM_IFACE,
        &sim_args(),
    ));
    let socket = std::env::temp_dir().join(format!("ecatd-chaos-{}.sock", std::process::id()));
    let config_path = std::env::temp_dir().join(format!("ecatd-chaos-{}.toml", std::process::id()));
    std::fs::write(&config_path, config(&socket)).expect("config written");
    let ecatd = EcatdInNs::start_in(
        master,
        bin_dir,
        &[
            "--iface",
            MASTER_IFACE,
            "--config",
            config_path.to_str().unwrap(),
            "--gateway-listen",
            GATEWAY,
        ],
    );
    let _ = std::fs::remove_file(&config_path);
    let pid = ecatd_pid(&ecatd.ns);
    // The main thread works from ecatd's namespace too (its REST checks).
    ecatd.ns.enter_current_thread();
    let agent = rest_agent();
    assert!(
        recover(&agent, count, f64::INFINITY).1.is_some(),
        "the segment is not in OP at the start:\n{}",
        ecatd.log()
    );

    println!(
        "chaos soak: {} s on the veth rig ({count} slaves), the cable cut for {} s every 20 s, \
         the simulator killed and restarted every 90 s",
        length.as_secs(),
        CUT.as_secs()
    );

    let stop = AtomicBool::new(false);
    let mut tallies = Tallies(Vec::new());
    let owner_tally = OwnerTally::default();
    let set_ip = AtomicU64::new(0);
    let gateways: Vec<_> = coe
        .iter()
        .enumerate()
        .map(|(i, &station)| {
            let name = if i == 0 {
                "gateway (drive)"
            } else {
                "gateway (2nd CoE)"
            };
            (station, tallies.add(name))
        })
        .collect();
    let rest = tallies.add("REST SDO");
    let grpc = tallies.add("gRPC SDO");
    let foe = tallies.add("FoE 64 KiB");
    let eoe = tallies.add("EoE iperf3 5 s");
    let mut faults: Vec<Fault> = Vec::new();
    let mut rss_first = None;
    let mut panicked = Vec::new();
    let ns = &ecatd.ns;
    std::thread::scope(|scope| {
        let mut clients = Vec::new();
        for (i, (station, tally)) in gateways.iter().enumerate() {
            let host = 10 + i as u8;
            let stop = &stop;
            let client = scope.spawn(move || gateway_client(ns, *station, host, tally, stop));
            clients.push(("gateway", client));
        }
        clients.push(("REST", scope.spawn(|| rest_client(ns, &rest, &stop))));
        clients.push(("gRPC", scope.spawn(|| grpc_client(ns, &grpc, &stop))));
        clients.push(("FoE", scope.spawn(|| foe_client(ns, &foe, &stop))));
        let eoe_loop = || eoe_client(ns, &sim_ns, &eoe, &set_ip, &stop);
        clients.push(("EoE", scope.spawn(eoe_loop)));
        clients.push(("owner", scope.spawn(|| owner(&socket, &owner_tally, &stop))));

        let start = Instant::now();
        for (at, kind) in schedule(length) {
            // The schedule itself (faults at fixed times), not a synchronisation.
            std::thread::sleep(at.saturating_sub(start.elapsed()));
            let at = start.elapsed();
            eprintln!("[{:>6.1} s] {kind}", at.as_secs_f64());
            let fault = match kind {
                POWER_LOSS => {
                    let events = slave_events(&agent);
                    drop(sim.take());
                    sim = Some(SimProcess::start_controlled(
                        &sim_ns,
                        SIM_IFACE,
                        &sim_args(),
                    ));
                    let (seen, recovered) = recover(&agent, count, events);
                    // As an operator's script would at once, so that a TCP connection of
                    // the running iperf3 can go on instead of waiting for its own timeout.
                    set_device_ip(&agent, &set_ip);
                    Fault {
                        at,
                        kind,
                        seen,
                        recovered,
                        master_safe: None,
                        slave_safe: None,
                    }
                }
                _ => {
                    let trips = metric(&agent, "ecat_app_watchdog_trips_total");
                    let events = slave_events(&agent);
                    let live = sim.as_mut().expect("the simulator runs");
                    live.clear_lines();
                    sim_ns.ip(&["link", "set", "dev", SIM_IFACE, "down"]);
                    let slave_safe = saw_outputs(live, "00", CUT);
                    // The cut lasts its time whatever the check saw.
                    std::thread::sleep(CUT.saturating_sub(start.elapsed() - at));
                    sim_ns.ip(&["link", "set", "dev", SIM_IFACE, "up"]);
                    let (seen, recovered) = recover(&agent, count, events);
                    let master_safe = metric(&agent, "ecat_app_watchdog_trips_total") > trips;
                    Fault {
                        at,
                        kind,
                        seen,
                        recovered,
                        master_safe: Some(master_safe),
                        slave_safe: Some(slave_safe),
                    }
                }
            };
            eprintln!(
                "[{:>6.1} s] back in OP after {}",
                start.elapsed().as_secs_f64(),
                fault
                    .recovered
                    .map_or("(not within 60 s)".into(), |d| format!(
                        "{:.1} s",
                        d.as_secs_f64()
                    ))
            );
            faults.push(fault);
            rss_first.get_or_insert_with(|| rss_kib(pid));
        }
        std::thread::sleep(length.saturating_sub(start.elapsed()));
        stop.store(true, Ordering::Relaxed);
        // Each client ends after the request it is in (at most its deadline).
        for (name, client) in clients {
            if client.join().is_err() {
                eprintln!("the {name} client panicked");
                panicked.push(name);
            }
            eprintln!(
                "[{:>6.1} s] {name} client stopped",
                start.elapsed().as_secs_f64()
            );
        }
    });
    let rss_end = rss_kib(pid);
    print_report(&tallies, &owner_tally, &set_ip, &faults, rss_first, rss_end);
    if !panicked.is_empty() {
        println!("clients that panicked (their counts end there): {panicked:?}");
    }
    drop(sim);
    let _ = std::fs::remove_file(&socket);
    drop(ecatd);
}

fn print_report(
    tallies: &Tallies,
    owner: &OwnerTally,
    set_ip: &AtomicU64,
    faults: &[Fault],
    rss_first: Option<u64>,
    rss_end: u64,
) {
    println!();
    println!(
        "{:<20} {:>10} {:>22} {:>6}",
        "client", "answered", "failed, clear error", "lost"
    );
    let mut lost = 0;
    for (name, tally) in &tallies.0 {
        let l = tally.lost.load(Ordering::Relaxed);
        lost += l;
        println!(
            "{:<20} {:>10} {:>22} {:>6}",
            name,
            tally.answered.load(Ordering::Relaxed),
            tally.failed.load(Ordering::Relaxed),
            l
        );
    }
    println!(
        "EoE: the device's IP set again {} times; owner: {} commits, {} claims",
        set_ip.load(Ordering::Relaxed),
        owner.commits.load(Ordering::Relaxed),
        owner.claims.load(Ordering::Relaxed)
    );
    println!();
    println!("why requests failed (count: message):");
    for (name, tally) in &tallies.0 {
        for (why, n) in tally.why.lock().unwrap().iter() {
            println!("  {name}: {n}: {why}");
        }
    }
    for (why, n) in owner.why.lock().unwrap().iter() {
        println!("  owner: {n}: {why}");
    }
    println!();
    println!(
        "{:>8}  {:<11} {:>8} {:>14} {:>22} {:>16}",
        "at s", "fault", "noticed", "back in OP s", "ecatd safe outputs", "DO8 went to 00"
    );
    let yes_no = |v: Option<bool>| match v {
        Some(true) => "yes",
        Some(false) => "NO",
        None => "-",
    };
    for f in faults {
        println!(
            "{:>8.1}  {:<11} {:>8} {:>14} {:>22} {:>16}",
            f.at.as_secs_f64(),
            f.kind,
            yes_no(Some(f.seen)),
            f.recovered
                .map_or("NOT".into(), |d| format!("{:.1}", d.as_secs_f64())),
            yes_no(f.master_safe),
            yes_no(f.slave_safe)
        );
    }
    let growth = rss_first.map(|first| rss_end as i64 - first as i64);
    println!();
    println!(
        "ecatd VmRSS after the first fault {} KiB, at the end {rss_end} KiB",
        rss_first.unwrap_or(0)
    );
    let verdict = |met: bool| if met { "met" } else { "NOT MET" };
    let cuts: Vec<_> = faults.iter().filter(|f| f.kind == CABLE_CUT).collect();
    println!();
    println!("goal: 0 lost: {} ({lost})", verdict(lost == 0));
    println!(
        "goal: every fault noticed and every slave back in OP after it: {} ({} of {})",
        verdict(faults.iter().all(|f| f.seen && f.recovered.is_some())),
        faults
            .iter()
            .filter(|f| f.seen && f.recovered.is_some())
            .count(),
        faults.len()
    );
    println!(
        "goal: the safe outputs on every cut: {} (ecatd {} of {}, the DO8 {} of {})",
        verdict(
            cuts.iter()
                .all(|f| f.master_safe == Some(true) && f.slave_safe == Some(true))
        ),
        cuts.iter().filter(|f| f.master_safe == Some(true)).count(),
        cuts.len(),
        cuts.iter().filter(|f| f.slave_safe == Some(true)).count(),
        cuts.len()
    );
    println!(
        "goal: RSS flat (≤ {} KiB growth): {} ({} KiB)",
        FLAT_KIB,
        verdict(growth.is_some_and(|g| g <= FLAT_KIB as i64)),
        growth.unwrap_or(0)
    );
}
