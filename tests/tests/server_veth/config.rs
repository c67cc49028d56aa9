//! ecatd configured from a file, on the veth rig: `ecatd --iface` on one end, `ecat-sim`
//! (recording every frame with `--pcap`) on the other. What the file says is checked on
//! the wire (the capture's SDO downloads and cycle), in the slaves (CoE, SoE, ESC
//! registers read back through ecatd's REST API), again after a power cycle of the drive;
//! an ENI gives the same result as the TOML; a slave other than the one configured stays
//! in PREOP with an event, a metric and a log line; bad files are refused at start with
//! nothing applied.

use crate::server_support;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use ecat_tests::rig::{HostRig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use serde_json::Value;
use server_support::{bin_dir, curl};

/// How long a step may take (start, bring-up after a power cycle); far more than needed.
const PATIENCE: Duration = Duration::from_secs(60);

/// The drive's station address (position 0).
const DRIVE: u16 = 1001;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data/config")
        .join(name)
}

fn temp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("ecatd-config-{}-{name}", std::process::id()))
}

/// `ecat-sim` on its namespace's end of the pair, capturing to a pcap file.
struct Segment {
    sim: SimProcess,
    rig: HostRig,
    pcap: PathBuf,
}

impl Segment {
    fn start(name: &str, topology: Option<&Path>) -> Segment {
        let rig = HostRig::new();
        let pcap = temp(&format!("{name}.pcap"));
        let mut args = vec!["--pcap".to_owned(), pcap.display().to_string()];
        if let Some(topology) = topology {
            args.extend(["--topology".to_owned(), topology.display().to_string()]);
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let sim = SimProcess::start_controlled(&rig.sim, SIM_IFACE, &args);
        Segment { sim, rig, pcap }
    }

    /// Stops the simulator (flushing the capture) and returns the frames it received
    /// from the master, with their times.
    fn frames(mut self) -> Vec<(Duration, Vec<u8>)> {
        self.sim.stop();
        let file = std::fs::File::open(&self.pcap).expect("the capture");
        let mut reader = pcap_file::pcap::PcapReader::new(file).expect("a pcap file");
        let mut frames = Vec::new();
        while let Some(packet) = reader.next_packet() {
            let packet = packet.expect("a packet");
            frames.push((packet.timestamp, packet.data.into_owned()));
        }
        let _ = std::fs::remove_file(&self.pcap);
        drop(self.rig);
        frames
    }
}

/// A running ecatd, stopped on drop.
struct Daemon {
    child: Child,
    http: String,
    grpc: String,
    log: Arc<Mutex<Vec<String>>>,
}

impl Daemon {
    fn start(segment: &Segment, args: &[&str]) -> Daemon {
        let mut child = Command::new(bin_dir().join("ecatd"))
            .args(["--iface", &segment.rig.master_iface])
            .args([
                "--grpc-listen",
                "127.0.0.1:0",
                "--http-listen",
                "127.0.0.1:0",
            ])
            .args(["--no-gateway", "--log-format", "json", "--log", "info"])
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("ecatd starts");
        let stderr = child.stderr.take().expect("piped");
        let log = Arc::new(Mutex::new(Vec::new()));
        let (tx, rx) = mpsc::channel();
        let keep = Arc::clone(&log);
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if let Ok(v) = serde_json::from_str::<Value>(&line) {
                    let _ = tx.send(v);
                }
                keep.lock().unwrap().push(line);
            }
        });
        let listening = loop {
            match rx.recv_timeout(PATIENCE) {
                Ok(v) if v["fields"]["message"] == "listening" => break v,
                Ok(_) => continue,
                Err(_) => panic!("ecatd did not listen:\n{}", log.lock().unwrap().join("\n")),
            }
        };
        let http = format!("http://{}", listening["fields"]["http"].as_str().unwrap());
        let grpc = format!("http://{}", listening["fields"]["grpc"].as_str().unwrap());
        let daemon = Daemon {
            child,
            http,
            grpc,
            log,
        };
        daemon.wait(|| curl(&["-s", &format!("{}/readyz", daemon.http)]).0 == 200);
        daemon
    }

    fn log(&self) -> String {
        self.log.lock().unwrap().join("\n")
    }

    /// Polls `done` until it holds or the patience runs out.
    fn wait(&self, mut done: impl FnMut() -> bool) {
        let deadline = Instant::now() + PATIENCE;
        while !done() {
            assert!(
                Instant::now() < deadline,
                "not in time; log:\n{}",
                self.log()
            );
            // The poll interval of the condition, not a synchronisation by time.
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    fn get(&self, path: &str) -> Value {
        let (status, body) = curl(&["-s", &format!("{}{path}", self.http)]);
        assert_eq!(status, 200, "GET {path}: {body}");
        serde_json::from_str(&body).unwrap_or(Value::String(body))
    }

    fn text(&self, path: &str) -> String {
        let (status, body) = curl(&["-s", &format!("{}{path}", self.http)]);
        assert_eq!(status, 200, "GET {path}: {body}");
        body
    }

    /// The hex data of a CoE upload.
    fn sdo(&self, slave: u16, index: u16, subindex: u8) -> String {
        let v = self.get(&format!(
            "/api/v1/slaves/{slave}/coe/sdo/{index:#06x}/{subindex}"
        ));
        v["data"].as_str().unwrap().to_owned()
    }

    /// [`Daemon::sdo`] that may fail (a slave on its way back up).
    fn try_sdo(&self, slave: u16, index: u16, subindex: u8) -> Option<String> {
        let url = format!(
            "{}/api/v1/slaves/{slave}/coe/sdo/{index:#06x}/{subindex}",
            self.http
        );
        let (status, body) = curl(&["-s", &url]);
        let v: Value = serde_json::from_str(&body).ok()?;
        (status == 200).then(|| v["data"].as_str().map(str::to_owned))?
    }

    /// The hex data of an ESC register read.
    fn register(&self, slave: u16, address: u16, length: usize) -> String {
        let v = self.get(&format!(
            "/api/v1/slaves/{slave}/registers/{address:#06x}?length={length}"
        ));
        v["data"].as_str().unwrap().to_owned()
    }

    fn states(&self) -> Vec<String> {
        self.get("/api/v1/slaves")
            .as_array()
            .expect("a list of slaves")
            .iter()
            .map(|s| s["state"].as_str().unwrap_or("?").to_owned())
            .collect()
    }

    fn stop(mut self) {
        // SAFETY: kill has no memory preconditions; the pid is our own unreaped child.
        unsafe { libc::kill(self.child.id() as libc::pid_t, libc::SIGTERM) };
        let _ = self.child.wait();
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The datagrams of an EtherCAT frame: command, ADP, ADO, data and working counter.
fn datagrams(frame: &[u8]) -> Vec<(u8, u16, u16, &[u8], u16)> {
    let mut out = Vec::new();
    if frame.len() < 16 || frame[12..14] != [0x88, 0xA4] {
        return out;
    }
    let mut at = 16;
    while at + 10 <= frame.len() {
        let cmd = frame[at];
        let adp = u16::from_le_bytes([frame[at + 2], frame[at + 3]]);
        let ado = u16::from_le_bytes([frame[at + 4], frame[at + 5]]);
        let len_word = u16::from_le_bytes([frame[at + 6], frame[at + 7]]);
        let len = usize::from(len_word & 0x07FF);
        let (Some(data), Some(wkc)) = (
            frame.get(at + 10..at + 10 + len),
            frame.get(at + 10 + len..at + 12 + len),
        ) else {
            break;
        };
        out.push((cmd, adp, ado, data, u16::from_le_bytes([wkc[0], wkc[1]])));
        if len_word & 0x8000 == 0 {
            break;
        }
        at += 10 + len + 2;
    }
    out
}

const FPWR: u8 = 5;
const LRW: u8 = 12;

/// The CoE SDO downloads written into the mailbox of `station` (at `sm0`), in order:
/// (index, subindex, data). Each frame appears twice in the capture (received and
/// answered, the data unchanged), and a request may be repeated: consecutive repeats are
/// one write.
fn sdo_downloads(
    frames: &[(Duration, Vec<u8>)],
    station: u16,
    sm0: u16,
) -> Vec<(u16, u8, Vec<u8>)> {
    let mut out: Vec<(u16, u8, Vec<u8>)> = Vec::new();
    let mut last: Option<Vec<u8>> = None;
    for (_, frame) in frames {
        for (cmd, adp, ado, data, _) in datagrams(frame) {
            if cmd != FPWR || adp != station || ado != sm0 || data.len() < 16 {
                continue;
            }
            // Mailbox header: length, address, channel, type (3: CoE) and counter.
            let len = usize::from(u16::from_le_bytes([data[0], data[1]]));
            if data[5] & 0x0F != 3 || len < 10 {
                continue;
            }
            if last.as_deref() == Some(data) {
                continue;
            }
            last = Some(data.to_vec());
            let coe = &data[6..6 + len];
            // CoE service 2 (SDO request), command specifier 1 (initiate download).
            if coe[1] >> 4 != 2 || coe[2] >> 5 != 1 {
                continue;
            }
            let flags = coe[2];
            let index = u16::from_le_bytes([coe[3], coe[4]]);
            let subindex = coe[5];
            let value = if flags & 0x02 != 0 {
                let n = if flags & 0x01 != 0 {
                    4 - usize::from((flags >> 2) & 0x03)
                } else {
                    4
                };
                coe[6..6 + n].to_vec()
            } else {
                let size = u32::from_le_bytes([coe[6], coe[7], coe[8], coe[9]]) as usize;
                coe[10..(10 + size).min(coe.len())].to_vec()
            };
            // A request sent again (its mailbox counter differs) is one write too.
            if out.last() != Some(&(index, subindex, value.clone())) {
                out.push((index, subindex, value));
            }
        }
    }
    out
}

/// The median time between two cyclic exchanges (LRW frames), each received once.
fn cycle_on_the_wire(frames: &[(Duration, Vec<u8>)]) -> Duration {
    // The capture holds each frame twice, as it came and as it went back. The copy sent
    // back has its LRW's working counter above 0 once the slave exchanges process data,
    // so it never counts as a cycle of its own, however late a loaded simulator sends it;
    // before that (both copies at 0) a copy within half a period of a cycle is its answer.
    let mut starts: Vec<Duration> = Vec::new();
    for (t, frame) in frames {
        if lrw_working_counter(frame) == Some(0)
            && starts
                .last()
                .is_none_or(|&s| *t - s > Duration::from_micros(250))
        {
            starts.push(*t);
        }
    }
    let mut gaps: Vec<Duration> = starts.windows(2).map(|w| w[1] - w[0]).collect();
    assert!(gaps.len() > 100, "too few cycles captured: {}", gaps.len());
    gaps.sort();
    gaps[gaps.len() / 2]
}

/// The working counter of the frame's LRW datagram, if it has one.
fn lrw_working_counter(frame: &[u8]) -> Option<u16> {
    datagrams(frame)
        .into_iter()
        .find(|d| d.0 == LRW)
        .map(|d| d.4)
}

fn le(value: u32, len: usize) -> Vec<u8> {
    value.to_le_bytes()[..len].to_vec()
}

/// What the sample configuration writes to the drive at every bring-up, in order: the
/// PDO assignment (ETG.1000.6 §5.6.7.4.7-8: clear, map, assign, count), then the start-up
/// SDO of PREOP -> SAFEOP.
fn drive_downloads() -> Vec<(u16, u8, Vec<u8>)> {
    let assign = |sm: u16, pdo: u16, entry: u32| {
        vec![
            (sm, 0, vec![0]),
            (pdo, 0, vec![0]),
            (pdo, 1, le(entry, 4)),
            (pdo, 0, vec![1]),
            (sm, 1, le(u32::from(pdo), 2)),
            (sm, 0, vec![1]),
        ]
    };
    let mut all = assign(0x1C12, 0x1600, 0x6040_0010);
    all.extend(assign(0x1C13, 0x1A00, 0x6041_0010));
    all.push((0x607A, 0, le(123_456, 4)));
    all
}

/// What follows the first complete run of `once` at the start of `writes`, if there is
/// one: before it only runs of `once` cut short (an attempt a transient on the bus ended,
/// e.g. a mailbox timeout while the machine is loaded, which the watch starts again from
/// the first command), never a command out of order or one that is not in `once`.
fn applied_whole<'a, T: PartialEq>(writes: &'a [T], once: &[T]) -> Option<&'a [T]> {
    let mut rest = writes;
    loop {
        let matched = rest.iter().zip(once).take_while(|(a, b)| a == b).count();
        if matched == once.len() {
            return Some(&rest[matched..]);
        }
        if matched == 0 {
            return None;
        }
        rest = &rest[matched..];
    }
}

/// Reads back, through ecatd, what the sample configuration sets in the slaves.
fn check_applied(ecatd: &Daemon) {
    assert_eq!(ecatd.sdo(0, 0x1C12, 0), "01");
    assert_eq!(ecatd.sdo(0, 0x1C12, 1), "0016");
    assert_eq!(ecatd.sdo(0, 0x1600, 0), "01");
    assert_eq!(ecatd.sdo(0, 0x1600, 1), "10004060");
    assert_eq!(ecatd.sdo(0, 0x1C13, 1), "001a");
    assert_eq!(ecatd.sdo(0, 0x1A00, 1), "10004160");
    assert_eq!(ecatd.sdo(0, 0x607A, 0), "40e20100", "123456");
    assert_eq!(ecatd.sdo(3, 0x2001, 0), "0df0feca", "0xCAFEF00D");
    let idn = ecatd.get("/api/v1/slaves/0/soe/0/32");
    assert_eq!(idn["data"], "08000000");
    // SYNC0 on the drive only: activation 0x0981 (cyclic + SYNC0), cycle 0x09A0 = 500 us.
    let activation = u8::from_str_radix(&ecatd.register(0, 0x0981, 1), 16).unwrap();
    assert_eq!(activation & 0x03, 0x03, "SYNC0 active: {activation:#04x}");
    assert_eq!(ecatd.register(0, 0x09A0, 4), "20a10700", "500000 ns");
    assert_eq!(ecatd.register(1, 0x0981, 1), "00", "no SYNC0 on the DO8");
    // The drive exchanges 2 bytes each way (SM2 and SM3 lengths, 0x0812 and 0x081A).
    assert_eq!(ecatd.register(0, 0x0812, 2), "0200");
    assert_eq!(ecatd.register(0, 0x081A, 2), "0200");
}

#[test]
fn a_configuration_file_is_applied_and_applied_again_after_a_power_cycle() {
    let mut segment = Segment::start("toml", None);
    let config = data("drive-500us.toml");
    let ecatd = Daemon::start(&segment, &["--config", config.to_str().unwrap()]);
    ecatd.wait(|| ecatd.states().iter().all(|s| s == "OP"));
    check_applied(&ecatd);

    // Undo what the file set where the slave lets us, then power the drive off and on:
    // the watch brings it back up and everything is written again.
    let (status, body) = curl(&[
        "-s",
        "-X",
        "PUT",
        "-H",
        "content-type: application/json",
        "-d",
        r#"{"data":"01000000"}"#,
        &format!("{}/api/v1/slaves/0/coe/sdo/0x607a/0", ecatd.http),
    ]);
    assert_eq!(status, 200, "{body}");
    assert_eq!(ecatd.sdo(0, 0x607A, 0), "01000000");
    segment.sim.command("power-cycle 0");
    ecatd.wait(|| {
        ecatd.try_sdo(0, 0x607A, 0).as_deref() == Some("40e20100")
            && ecatd.states().iter().all(|s| s == "OP")
    });
    check_applied(&ecatd);
    ecatd.stop();

    let frames = segment.frames();
    let writes = sdo_downloads(&frames, DRIVE, 0x1000);
    let once = drive_downloads();
    // The IDN write goes by SoE: the CoE writes are the assignment and 0x607A, at the
    // start and again after the power cycle, with the test's own write in between.
    // An attempt cut short by a transient (a mailbox timeout on a loaded machine) is
    // started again from the first command; what counts is that each run is in order and
    // the last one is whole.
    let undo = [(0x607A, 0, vec![1, 0, 0, 0])];
    let rest = applied_whole(&writes, &once).unwrap_or_else(|| panic!("{writes:?}"));
    let rest = rest
        .strip_prefix(&undo[..])
        .unwrap_or_else(|| panic!("{writes:?}"));
    assert_eq!(applied_whole(rest, &once), Some(&[][..]), "{writes:?}");
    let cycle = cycle_on_the_wire(&frames);
    assert!(
        cycle > Duration::from_micros(400) && cycle < Duration::from_micros(600),
        "median cycle on the wire {cycle:?}, configured 500 us"
    );
}

/// The effective configuration as `ecat config` (gRPC) prints it, checked against the
/// REST route's.
fn shown_config(ecatd: &Daemon) -> server::config::Config {
    let output = Command::new(bin_dir().join("ecat"))
        .args(["--address", &ecatd.grpc, "--json", "config", "--toml"])
        .output()
        .expect("ecat runs");
    assert!(output.status.success(), "{output:?}");
    let by_grpc: Value = serde_json::from_slice(&output.stdout).unwrap();
    let by_rest = ecatd.get("/api/v1/config");
    assert_eq!(by_grpc, by_rest);
    toml::from_str(by_rest["toml"].as_str().unwrap()).expect("the shown TOML reads back")
}

/// What one run of ecatd on the default segment did: the drive's SDO downloads, the
/// store's, the cycle on the wire, and the slaves of the effective configuration.
type WireResult = (
    Vec<(u16, u8, Vec<u8>)>,
    Vec<(u16, u8, Vec<u8>)>,
    Duration,
    Vec<master_core::master::SlaveConfig>,
);

/// The [`WireResult`] of ecatd with `args`, after reading back what the sample sets.
fn wire_result(name: &str, args: &[&str]) -> WireResult {
    let segment = Segment::start(name, None);
    let ecatd = Daemon::start(&segment, args);
    ecatd.wait(|| ecatd.states().iter().all(|s| s == "OP"));
    check_applied(&ecatd);
    let config = shown_config(&ecatd);
    assert_eq!(config.bus.cycle, Duration::from_micros(500));
    let setup = config
        .segment_setup()
        .expect("the shown configuration is good");
    ecatd.stop();
    let frames = segment.frames();
    (
        sdo_downloads(&frames, DRIVE, 0x1000),
        sdo_downloads(&frames, DRIVE + 3, 0x1000),
        cycle_on_the_wire(&frames),
        setup.slaves.slaves,
    )
}

#[test]
fn an_eni_gives_the_same_wire_result_as_the_equivalent_toml() {
    let toml = data("drive-500us.toml");
    let eni = data("default-segment.eni.xml");
    let (drive, store, cycle, shown) =
        wire_result("eni-toml", &["--config", toml.to_str().unwrap()]);
    assert_eq!(drive, drive_downloads());
    assert_eq!(store, vec![(0x2001, 0, le(0xCAFE_F00D, 4))]);
    let (eni_drive, eni_store, eni_cycle, eni_shown) =
        wire_result("eni", &["--eni", eni.to_str().unwrap()]);
    assert_eq!(eni_drive, drive);
    assert_eq!(eni_store, store);
    // `ecat config` shows the same slaves (identity, PDOs, DC, start-up commands) either
    // way.
    assert_eq!(eni_shown, shown);
    for cycle in [cycle, eni_cycle] {
        assert!(
            cycle > Duration::from_micros(400) && cycle < Duration::from_micros(600),
            "median cycle on the wire {cycle:?}, configured 500 us"
        );
    }
}

/// The default topology with another product code at position 2.
fn wrong_product_topology() -> PathBuf {
    let default = Path::new(env!("CARGO_MANIFEST_DIR")).join("../sim/topologies/default.toml");
    let text = std::fs::read_to_string(default).unwrap();
    assert_eq!(text.matches("product_code = 3\n").count(), 1);
    let path = temp("wrong-product.toml");
    std::fs::write(
        &path,
        text.replace("product_code = 3\n", "product_code = 99\n"),
    )
    .unwrap();
    path
}

#[test]
fn a_slave_other_than_the_one_configured_stays_in_preop_with_event_metric_and_log() {
    let topology = wrong_product_topology();
    let segment = Segment::start("mismatch", Some(&topology));
    let config = data("drive-500us.toml");
    let ecatd = Daemon::start(&segment, &["--config", config.to_str().unwrap()]);
    ecatd.wait(|| ecatd.states() == ["OP", "OP", "PREOP", "OP", "OP"]);
    // The log line, from the scan.
    let line = ecatd
        .log()
        .lines()
        .find(|l| l.contains("not the one the configuration expects"))
        .map(str::to_owned)
        .unwrap_or_else(|| panic!("no mismatch line:\n{}", ecatd.log()));
    let line: Value = serde_json::from_str(&line).unwrap();
    assert_eq!(line["fields"]["position"], 2);
    assert_eq!(line["level"], "WARN");
    let problem = line["fields"]["problem"].as_str().unwrap();
    assert!(
        problem.contains("product code 0x00000003 expected, 0x00000063 found"),
        "{problem}"
    );
    // The metric.
    let metrics = ecatd.text("/metrics");
    assert!(
        metrics
            .contains(r#"ecat_slave_config_mismatch_total{station="1003",problem="identity"} 1"#),
        "{metrics}"
    );
    // The event: subscribed, then a rescan finds the same.
    let mut events = Command::new("curl")
        .args([
            "-sN",
            "--max-time",
            "60",
            "-H",
            "accept: text/event-stream",
            &format!("{}/api/v1/events", ecatd.http),
        ])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let stdout = events.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if let Some(data) = line.strip_prefix("data: ") {
                let _ = tx.send(serde_json::from_str::<Value>(data).unwrap());
            }
        }
    });
    let deadline = Instant::now() + PATIENCE;
    let event = 'found: loop {
        assert!(Instant::now() < deadline, "no topology_mismatch event");
        let (status, body) = curl(&["-s", "-X", "POST", &format!("{}/api/v1/rescan", ecatd.http)]);
        assert_eq!(status, 200, "{body}");
        while let Ok(event) = rx.recv_timeout(Duration::from_secs(2)) {
            if event["kind"] == "topology_mismatch" {
                break 'found event;
            }
        }
    };
    let _ = events.kill();
    let _ = events.wait();
    assert_eq!(
        (event["position"].as_u64(), event["station"].as_u64()),
        (Some(2), Some(1003))
    );
    assert_eq!(event["identity"]["product_code"], 99);
    ecatd.wait(|| ecatd.states() == ["OP", "OP", "PREOP", "OP", "OP"]);
    ecatd.stop();
    drop(segment);
    let _ = std::fs::remove_file(topology);
}

/// Runs ecatd with `args` expecting it to refuse to start; returns its exit code and
/// what it said.
fn refused(args: &[&str]) -> (i32, String) {
    let output = Command::new(bin_dir().join("ecatd"))
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("ecatd runs");
    let code = output.status.code().expect("an exit code");
    (code, String::from_utf8_lossy(&output.stderr).into_owned())
}

#[test]
fn bad_files_are_refused_with_what_is_wrong_and_where() {
    let file = |name: &str, text: &str| {
        let path = temp(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let unknown = file("unknown.toml", "[bus]\ncycle = \"1ms\"\ncycel = \"2ms\"\n");
    let (code, said) = refused(&["--config", unknown.to_str().unwrap(), "--check-config"]);
    assert_eq!(code, i32::from(server::exit::CONFIGURATION), "{said}");
    assert!(
        said.contains(unknown.to_str().unwrap())
            && said.contains("line 3")
            && said.contains("unknown field `cycel`"),
        "{said}"
    );
    let wrong_type = file("type.toml", "[bus]\ncycle = 500\n");
    let (code, said) = refused(&["--config", wrong_type.to_str().unwrap(), "--check-config"]);
    assert_eq!(code, i32::from(server::exit::CONFIGURATION), "{said}");
    assert!(
        said.contains("line 2") && said.contains("invalid type: integer `500`"),
        "{said}"
    );
    let bad_value = file(
        "value.toml",
        "[[slave]]\nposition = 0\n[[slave.startup]]\ntransition = \"PS\"\nindex = 0x6060\nvalue = 300\ntype = \"i8\"\n",
    );
    let (code, said) = refused(&["--config", bad_value.to_str().unwrap(), "--check-config"]);
    assert_eq!(code, i32::from(server::exit::CONFIGURATION), "{said}");
    assert!(
        said.contains("[[slave]] #1 (position 0): startup #1: value 300 does not fit type i8"),
        "{said}"
    );
    let good = data("drive-500us.toml");
    let (code, said) = refused(&["--config", good.to_str().unwrap(), "--check-config"]);
    assert_eq!(code, 0, "{said}");
    for path in [unknown, wrong_type, bad_value] {
        let _ = std::fs::remove_file(path);
    }
}

/// Whether any frame the master sent asked a slave for more than INIT (an AL control
/// write, 0x0120, of PREOP, SAFEOP or OP) or wrote a mailbox.
fn anything_applied(frames: &[(Duration, Vec<u8>)]) -> bool {
    frames.iter().any(|(_, f)| {
        datagrams(f).iter().any(|&(cmd, _, ado, data, _)| {
            let writes = matches!(cmd, 2 | 5 | 8); // APWR, FPWR, BWR
            writes
                && ((ado == 0x0120 && data.first().is_some_and(|s| matches!(s & 0x0F, 2 | 4 | 8)))
                    || ado == 0x1000)
        })
    })
}

#[test]
fn a_pdo_the_slave_does_not_have_or_an_unknown_eni_slave_stop_the_start_with_nothing_applied() {
    let pdo = temp("pdo.toml");
    std::fs::write(
        &pdo,
        "[[slave]]\nposition = 0\n[[slave.pdo_assign]]\nsm = 2\npdos = [{ index = 0x1605 }]\n",
    )
    .unwrap();
    let eni_text = std::fs::read_to_string(data("default-segment.eni.xml")).unwrap();
    let eni = temp("unknown-slave.eni.xml");
    std::fs::write(
        &eni,
        eni_text.replace(
            "<ProductCode>3</ProductCode>",
            "<ProductCode>#x77</ProductCode>",
        ),
    )
    .unwrap();
    for (name, args, wanted) in [
        (
            "pdo",
            ["--config", pdo.to_str().unwrap()],
            "slave 0: ECATD-SIM Drive (1001) has no PDO 0x1605 (SM2); it offers 0x1600, 0x1a00",
        ),
        (
            "eni-unknown",
            ["--eni", eni.to_str().unwrap()],
            "slave 2: ECATD-SIM DI8 (1003): not the slave expected: product code 0x00000077 expected, 0x00000003 found",
        ),
    ] {
        let segment = Segment::start(name, None);
        let mut full = vec!["--iface", segment.rig.master_iface.as_str()];
        full.extend([
            "--grpc-listen",
            "127.0.0.1:0",
            "--http-listen",
            "127.0.0.1:0",
            "--no-gateway",
        ]);
        full.extend(args);
        let (code, said) = refused(&full);
        // A configuration error: systemd does not restart on it.
        assert_eq!(code, i32::from(server::exit::CONFIGURATION), "{said}");
        assert!(said.contains(wanted), "{name}: {said}");
        let frames = segment.frames();
        assert!(!frames.is_empty(), "the scan ran");
        assert!(!anything_applied(&frames), "{name}: a slave was configured");
    }
    let _ = std::fs::remove_file(pdo);
    let _ = std::fs::remove_file(eni);
}
