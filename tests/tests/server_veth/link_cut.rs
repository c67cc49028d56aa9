//! A cut cable in the middle of a transfer, on the veth rig (`ecatd --iface` on one end of
//! a veth pair, `ecat-sim` on the other): the simulator's end goes down for 2 s
//! (`ip link set sim0 down` in its namespace), once during an FoE write and once during a
//! segmented SDO download, both through REST.
//!
//! Each transfer ends with a clean error (HTTP 502, `bus_error`: the bus found no frame coming
//! back), never a hang or a success; the segment comes back to OP by itself (the topology
//! watch); and the next transfer of the same kind is correct (the file read back, the
//! object read back).

use crate::server_support;

use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

use server_support::streaming::Streaming;
use server_support::{Ecatd, curl};
use sim::topology::Topology;

/// How long the cable stays cut.
const CUT: Duration = Duration::from_secs(2);
/// Position of the CoE store slave in the built-in segment, and its station address.
const STORE: u16 = 3;
const STORE_STATION: u16 = 1001 + STORE;
/// Size of the CoE store's large object here (segments of at most 121 bytes in its
/// 128-byte mailbox: thousands of exchanges).
const LARGE: usize = 512 << 10;

/// A scratch directory, removed on drop.
struct Scratch(PathBuf);

impl Scratch {
    fn new() -> Scratch {
        let dir = std::env::temp_dir().join(format!("ecatd-link-cut-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The built-in segment with room for a 4 MiB file on the drive and a large object of
/// [`LARGE`] bytes on the CoE store.
fn topology(scratch: &Scratch) -> String {
    let mut topology = Topology::default_segment();
    topology.slaves[0].foe_capacity = Some(16 << 20);
    let large = topology.slaves[usize::from(STORE)]
        .objects
        .iter_mut()
        .find(|o| o.index == 0x2000)
        .expect("the CoE store's large object");
    large.size = Some(LARGE);
    let path = scratch.0.join("topology.toml");
    std::fs::write(&path, topology.to_toml().unwrap()).unwrap();
    path.to_str().unwrap().to_owned()
}

fn pattern(len: usize, seed: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u32).wrapping_mul(2_654_435_761).to_le_bytes()[2] ^ seed)
        .collect()
}

/// A background `curl` (status code on its last line), with `X-Ecat-Client` as a
/// non-browser client sends it.
fn background_curl(args: &[&str]) -> Streaming {
    Streaming::start(
        Command::new("curl")
            .args(["-s", "-H", "X-Ecat-Client: tests", "-w", "\n%{http_code}"])
            .args(args),
    )
}

/// Waits for the background request to end; its status and body.
fn finished(mut request: Streaming) -> (u16, String) {
    assert!(
        request.ended_by(Instant::now() + Duration::from_secs(60)),
        "the request did not end after the cut: {}",
        request.text()
    );
    let text = request.text();
    let (body, code) = text.rsplit_once('\n').unwrap_or(("", text.as_str()));
    (code.trim().parse().unwrap_or(0), body.to_owned())
}

/// Cuts the cable for [`CUT`]; the duration is the fault under test, not a wait for
/// something.
fn cut(ecatd: &Ecatd) {
    ecatd.set_sim_link(false);
    std::thread::sleep(CUT);
    ecatd.set_sim_link(true);
}

/// Waits until ecatd reports every slave present and in OP again.
fn wait_all_op(ecatd: &Ecatd, slaves: usize) {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let (status, body) = curl(&["-s", &format!("{}/api/v1/slaves", ecatd.http)]);
        if status == 200 {
            let listed: serde_json::Value = serde_json::from_str(&body).unwrap();
            // A slave lost during the cut is listed ABSENT until it is found again, and
            // then passes through INIT: only present slaves in OP count as back.
            let states: Vec<&str> = listed
                .as_array()
                .unwrap()
                .iter()
                .filter(|s| s["present"] == true)
                .filter_map(|s| s["state"].as_str())
                .collect();
            if states.len() == slaves && states.iter().all(|s| *s == "OP") {
                return;
            }
            assert!(
                Instant::now() < deadline,
                "the segment did not come back to OP: {body}"
            );
        }
        // Poll interval of the state check; the loop ends on OP or the deadline.
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The number in the `/metrics` line `name{station="..."}` of `station`.
fn station_counter(ecatd: &Ecatd, name: &str, station: u16) -> f64 {
    let (status, text) = curl(&["-s", &format!("{}/metrics", ecatd.http)]);
    assert_eq!(status, 200);
    let label = format!("station=\"{station}\"");
    text.lines()
        .find(|l| l.starts_with(&format!("{name}{{")) && l.contains(&label))
        .and_then(|l| l.rsplit(' ').next()?.parse().ok())
        .unwrap_or_else(|| panic!("no {name} for {station} in:\n{text}"))
}

/// Waits until the slave's mailbox took `more` messages beyond `from`: a transfer to it is
/// under way.
fn wait_writes(ecatd: &Ecatd, station: u16, from: f64, more: f64) {
    let deadline = Instant::now() + Duration::from_secs(30);
    while station_counter(ecatd, "ecat_mailbox_writes_total", station) < from + more {
        assert!(Instant::now() < deadline, "no transfer under way");
        // Poll interval of the counter check; the loop ends on the count or the deadline.
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn a_two_second_cut_ends_transfers_cleanly_and_the_segment_recovers() {
    let scratch = Scratch::new();
    let topology = topology(&scratch);
    let slaves = Topology::default_segment().slaves.len();
    let ecatd = Ecatd::start_with(&["--simulate", &topology], &[]);
    wait_all_op(&ecatd, slaves);
    let drive = 1001;

    // FoE write of 4 MiB, cut once a few hundred packets went through.
    let file = scratch.0.join("big.bin");
    std::fs::write(&file, pattern(4 << 20, 1)).unwrap();
    let url = format!("{}/api/v1/slaves/0/foe/cut.bin", ecatd.http);
    let before = station_counter(&ecatd, "ecat_mailbox_writes_total", drive);
    let upload = background_curl(&[
        "-X",
        "PUT",
        "-H",
        "content-type: application/octet-stream",
        "--data-binary",
        &format!("@{}", file.display()),
        &url,
    ]);
    wait_writes(&ecatd, drive, before, 300.0);
    cut(&ecatd);
    let (status, body) = finished(upload);
    assert_eq!(status, 503, "{body}");
    let error: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(error["reason"], "BUS", "{body}");
    wait_all_op(&ecatd, slaves);
    // The next write is whole: read back equal.
    let small = pattern(200 << 10, 2);
    std::fs::write(&file, &small).unwrap();
    let next = format!("{}/api/v1/slaves/0/foe/next.bin", ecatd.http);
    let (status, body) = curl(&[
        "-s",
        "-X",
        "PUT",
        "-H",
        "content-type: application/octet-stream",
        "--data-binary",
        &format!("@{}", file.display()),
        &next,
    ]);
    assert_eq!(status, 200, "{body}");
    let back = scratch.0.join("back.bin");
    let (status, _) = curl(&["-s", "-o", back.to_str().unwrap(), &next]);
    assert_eq!(status, 200);
    assert_eq!(std::fs::read(&back).unwrap(), small);

    // Segmented SDO download of the large object, cut once a few hundred segments went.
    let sdo = format!("{}/api/v1/slaves/{STORE}/coe/sdo/0x2000/0", ecatd.http);
    let body = format!(r#"{{"data": "{}"}}"#, hex(&pattern(LARGE, 3)));
    let body_file = scratch.0.join("sdo.json");
    std::fs::write(&body_file, &body).unwrap();
    let before = station_counter(&ecatd, "ecat_mailbox_writes_total", STORE_STATION);
    let download = background_curl(&[
        "-X",
        "PUT",
        "-H",
        "content-type: application/json",
        "--data-binary",
        &format!("@{}", body_file.display()),
        &sdo,
    ]);
    wait_writes(&ecatd, STORE_STATION, before, 300.0);
    cut(&ecatd);
    let (status, body) = finished(download);
    assert_eq!(status, 503, "{body}");
    let error: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(error["reason"], "BUS", "{body}");
    wait_all_op(&ecatd, slaves);
    // The next download is whole: read back equal.
    let value = pattern(LARGE, 4);
    std::fs::write(&body_file, format!(r#"{{"data": "{}"}}"#, hex(&value))).unwrap();
    let (status, body) = curl(&[
        "-s",
        "-X",
        "PUT",
        "-H",
        "content-type: application/json",
        "--data-binary",
        &format!("@{}", body_file.display()),
        &sdo,
    ]);
    assert_eq!(status, 200, "{body}");
    let (status, body) = curl(&["-s", &sdo]);
    assert_eq!(status, 200, "{body}");
    let read: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(read["data"], hex(&value));
}

fn hex(data: &[u8]) -> String {
    data.iter().map(|b| format!("{b:02x}")).collect()
}

/// Waits until every slave is listed absent (`present` false) over REST; the listing.
fn wait_all_absent(ecatd: &Ecatd) -> Vec<serde_json::Value> {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let (status, body) = curl(&["-s", &format!("{}/api/v1/slaves", ecatd.http)]);
        assert_eq!(status, 200, "{body}");
        let listed: Vec<serde_json::Value> = serde_json::from_str(&body).unwrap();
        if !listed.is_empty() && listed.iter().all(|s| s["present"] == false) {
            return listed;
        }
        assert!(
            Instant::now() < deadline,
            "the slaves were not lost after the cut: {body}"
        );
        // Poll interval of the listing; the loop ends on the loss or the deadline.
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Issue 35: a slave lost with the cable is absent in every API (never its last state as
/// if live) and a request to it fails at once saying so, until it is found again.
#[test]
fn a_lost_slave_is_absent_in_every_api_until_it_is_found_again() {
    let ecatd = Ecatd::start(&[]);
    let slaves = Topology::default_segment().slaves.len();
    wait_all_op(&ecatd, slaves);
    let gateway = ecatd.gateway_addr();
    let drive = 1001u16;

    ecatd.set_sim_link(false);
    let listed = wait_all_absent(&ecatd);
    for slave in &listed {
        assert_eq!(slave["state"], "ABSENT", "{slave}");
    }
    // At the default level (info) the loss is in the log, one line per slave.
    let lost = ecatd.log_until("slave lost");
    let line = lost.last().expect("the line waited for");
    assert_eq!(line["level"], "WARN", "{line}");
    assert!(line["fields"]["station"].as_u64().is_some(), "{line}");

    // REST: 404 with the reason, at once.
    let (status, body) = curl(&[
        "-s",
        &format!("{}/api/v1/slaves/0/coe/sdo/0x1018/1", ecatd.http),
    ]);
    assert_eq!(status, 404, "{body}");
    let error: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(error["reason"], "SLAVE_ABSENT", "{body}");
    assert!(
        error["detail"]
            .as_str()
            .unwrap_or_default()
            .contains("absent"),
        "{body}"
    );

    // gRPC: UNAVAILABLE (14), and the listing says not present, state unspecified.
    let (code, message) = server_support::call(
        &ecatd.grpc,
        &[],
        "ecat.v1.CoeService/Upload",
        r#"{"slave": "0", "index": 4120, "subindex": 1}"#,
    )
    .unwrap_err();
    assert_eq!(code, "14", "{message}");
    assert!(message.contains("absent"), "{message}");
    let list = server_support::call(&ecatd.grpc, &[], "ecat.v1.BusService/ListSlaves", "{}")
        .expect("ListSlaves");
    for slave in list["slaves"].as_array().expect("slaves") {
        // proto3 JSON leaves out false and the zero enum value.
        assert!(slave.get("present").is_none(), "{slave}");
        assert!(slave.get("state").is_none(), "{slave}");
    }

    // The gateway: the SDO abort "protocol timed out" at once, not after a timeout.
    let mut client = server_support::gateway_client::GatewayClient::new(gateway);
    let asked = Instant::now();
    assert_eq!(client.sdo_upload(drive, 0x1018, 1), Err(0x0504_0000));
    assert!(
        asked.elapsed() < Duration::from_secs(1),
        "{:?}",
        asked.elapsed()
    );

    // The CLI's listing and the metrics.
    let output = Command::new(server_support::bin_dir().join("ecat"))
        .args(["--address", &format!("http://{}", ecatd.grpc), "slaves"])
        .output()
        .expect("ecat runs");
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{text}");
    assert_eq!(text.lines().count(), slaves, "{text}");
    assert!(
        text.lines()
            .all(|l| l.contains("ABSENT") || l.contains("absent")),
        "{text}"
    );
    let (status, metrics) = curl(&["-s", &format!("{}/metrics", ecatd.http)]);
    assert_eq!(status, 200);
    assert!(
        metrics.lines().any(|l| l == "ecat_slaves{state=\"OP\"} 0"),
        "{metrics}"
    );

    ecatd.set_sim_link(true);
    wait_all_op(&ecatd, slaves);
    // ... and so is the return: a "slave found" line after the last "slave lost".
    let deadline = Instant::now() + Duration::from_secs(10);
    let found_again = loop {
        let messages: Vec<serde_json::Value> = ecatd
            .log()
            .lines()
            .filter_map(|l| serde_json::from_str(l).ok())
            .collect();
        let last_lost = messages
            .iter()
            .rposition(|v| v["fields"]["message"] == "slave lost")
            .expect("slave lost logged");
        if let Some(found) = messages[last_lost..]
            .iter()
            .find(|v| v["fields"]["message"] == "slave found")
        {
            break found.clone();
        }
        assert!(
            Instant::now() < deadline,
            "no slave found after the loss:\n{}",
            ecatd.log()
        );
        // Poll interval of the log reader; the loop ends on the line or the deadline.
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(found_again["level"], "INFO", "{found_again}");
    let (status, body) = curl(&[
        "-s",
        &format!("{}/api/v1/slaves/0/coe/sdo/0x1018/1", ecatd.http),
    ]);
    assert_eq!(status, 200, "{body}");
}
