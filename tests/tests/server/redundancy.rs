//! Cable redundancy end to end (docs/redundancy.md): `ecatd --simulate --ring` runs the
//! built-in five slaves as a ring into two in-process ports; `POST /api/v1/sim/ring` cuts a
//! cable, kills a slave or heals the ring, and every API shows it: `GET /api/v1/master`,
//! gRPC `GetMaster`, `ecat master`, `/metrics`, the `ring_broken` / `ring_closed` events.
//! Waits are bounded polls of the API for the state asked for, never sleeps.

use crate::server_support;

use std::time::{Duration, Instant};

use serde_json::Value;
use server_support::gateway_client::GatewayClient;
use server_support::{Ecatd, call, curl, ecat_ok, post_json, run_to_exit};
use sim::topology::SIM_VENDOR_ID;

/// How long a change may take to show (it shows at the next frame; the bound is for a
/// loaded machine).
const PATIENCE: Duration = Duration::from_secs(20);

fn get(ecatd: &Ecatd, path: &str) -> (u16, Value) {
    let (status, body) = curl(&["-s", &format!("{}{path}", ecatd.http)]);
    (
        status,
        serde_json::from_str(&body).unwrap_or(Value::String(body)),
    )
}

/// `POST /api/v1/sim/ring` with `body`: the status and the JSON answer.
fn cut(ecatd: &Ecatd, body: &str) -> (u16, Value) {
    let (status, text) = post_json(&format!("{}/api/v1/sim/ring", ecatd.http), body);
    (
        status,
        serde_json::from_str(&text).unwrap_or(Value::String(text)),
    )
}

/// Polls `GET /api/v1/master` until its `redundancy` satisfies `wanted`; panics with the
/// last answer at the deadline.
fn wait_ring(ecatd: &Ecatd, what: &str, wanted: impl Fn(&Value) -> bool) -> Value {
    let deadline = Instant::now() + PATIENCE;
    loop {
        let (status, master) = get(ecatd, "/api/v1/master");
        assert_eq!(status, 200, "{master}");
        let ring = master["redundancy"].clone();
        if wanted(&ring) {
            return ring;
        }
        assert!(
            Instant::now() < deadline,
            "the ring never showed {what}: {ring}"
        );
        // Poll interval (the loop ends on the condition or the deadline).
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Polls the kept events of `kind` until one satisfies `wanted`.
fn wait_event(ecatd: &Ecatd, kind: &str, wanted: impl Fn(&Value) -> bool) -> Value {
    let deadline = Instant::now() + PATIENCE;
    loop {
        let (status, events) = get(ecatd, &format!("/api/v1/events?kind={kind}"));
        assert_eq!(status, 200, "{events}");
        if let Some(event) = events
            .as_array()
            .expect("a list of events")
            .iter()
            .find(|e| wanted(e))
        {
            return event.clone();
        }
        assert!(Instant::now() < deadline, "no {kind} event: {events}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The slaves' AL states, by position.
fn states(ecatd: &Ecatd) -> Vec<String> {
    let (status, slaves) = get(ecatd, "/api/v1/slaves");
    assert_eq!(status, 200, "{slaves}");
    slaves
        .as_array()
        .expect("a list of slaves")
        .iter()
        .map(|s| s["state"].as_str().unwrap_or_default().to_owned())
        .collect()
}

/// The value of the unlabelled metric `name` in `/metrics`.
fn metric(ecatd: &Ecatd, name: &str) -> f64 {
    let (status, text) = curl(&["-s", &format!("{}/metrics", ecatd.http)]);
    assert_eq!(status, 200);
    text.lines()
        .find_map(|line| line.strip_prefix(name)?.strip_prefix(' '))
        .and_then(|value| value.trim().parse().ok())
        .unwrap_or_else(|| panic!("no {name} in /metrics"))
}

fn ecat(ecatd: &Ecatd, args: &[&str]) -> String {
    ecat_ok(&ecatd.grpc, args)
}

fn vendor_hex() -> String {
    SIM_VENDOR_ID
        .to_le_bytes()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[test]
fn a_cut_ring_keeps_every_slave_in_op_and_every_api_says_where_it_broke() {
    let ecatd = Ecatd::start(&["--ring"]);
    let closed = wait_ring(&ecatd, "closed", |r| r["state"] == "closed");
    assert_eq!(closed["break_after"], Value::Null);
    assert_eq!(
        (closed["ring_slaves"].as_u64(), closed["breaks"].as_u64()),
        (Some(5), Some(0))
    );
    assert_eq!(metric(&ecatd, "ecat_bus_redundancy_state"), 1.0);
    assert_eq!(metric(&ecatd, "ecat_bus_redundancy_break_after"), -1.0);

    let (status, done) = cut(&ecatd, r#"{"action":"break","cable":3}"#);
    assert_eq!((status, &done["ok"]), (200, &Value::Bool(true)), "{done}");
    let broken = wait_ring(&ecatd, "broken after 3", |r| r["state"] == "broken");
    assert_eq!(broken["break_after"], 3);
    assert_eq!(
        (
            broken["primary_side"].as_u64(),
            broken["backup_side"].as_u64(),
            broken["unreachable"].as_u64(),
            broken["breaks"].as_u64()
        ),
        (Some(3), Some(2), Some(0), Some(1)),
        "{broken}"
    );

    // Every slave is served from one port or the other: all stay in OP, and the mailbox of
    // a slave behind the break (the CoE store at 3, on the backup side) still answers, as
    // does one before it.
    assert_eq!(states(&ecatd), vec!["OP"; 5]);
    for slave in [3, 0] {
        let (status, upload) = get(&ecatd, &format!("/api/v1/slaves/{slave}/coe/sdo/0x1018/1"));
        assert_eq!(
            (status, upload["data"].as_str()),
            (200, Some(vendor_hex().as_str())),
            "slave {slave}: {upload}"
        );
    }
    // The ETG.8200 gateway too: an SDO upload from the CoE store behind the break.
    let mut gateway = GatewayClient::new(ecatd.gateway_addr());
    assert_eq!(
        gateway.sdo_upload(1001 + 3, 0x1018, 1),
        Ok(SIM_VENDOR_ID.to_le_bytes().to_vec()),
        "the gateway through the backup port"
    );
    assert_eq!(states(&ecatd), vec!["OP"; 5], "still OP after the uploads");

    let event = wait_event(&ecatd, "ring_broken", |e| e["ring"]["break_after"] == 3);
    assert_eq!(
        event["text"],
        "ring broken after 3 slaves (positions 0-2 on the primary port, 3-4 on the backup port)"
    );
    assert_eq!(
        (
            event["ring"]["backup_side"].as_u64(),
            event["ring"]["unreachable"].as_u64()
        ),
        (Some(2), Some(0))
    );

    assert_eq!(metric(&ecatd, "ecat_bus_redundancy_state"), 2.0);
    assert_eq!(metric(&ecatd, "ecat_bus_redundancy_break_after"), 3.0);
    assert_eq!(metric(&ecatd, "ecat_bus_redundancy_breaks_total"), 1.0);
    assert_eq!(
        metric(&ecatd, "ecat_bus_redundancy_unreachable_slaves"),
        0.0
    );

    let grpc = call(&ecatd.grpc, &[], "ecat.v1.BusService/GetMaster", "{}").unwrap();
    let ring = &grpc["redundancy"];
    assert_eq!(
        (ring["state"].as_str(), ring["breakAfter"].as_u64()),
        (Some("broken"), Some(3)),
        "{grpc}"
    );
    assert_eq!(
        (ring["primarySide"].as_u64(), ring["backupSide"].as_u64()),
        (Some(3), Some(2))
    );
    assert_eq!(ring["breaks"], "1", "uint64 is a string in proto JSON");

    let human = ecat(&ecatd, &["master"]);
    assert!(
        human.contains("  Redundancy:\n    State: broken\n    Break after: 3 slaves (3 on the primary port, 2 on the backup port)\n    Unreachable: 0\n    Breaks: 1\n    Heals: 0"),
        "{human}"
    );
    let json: Value = serde_json::from_str(&ecat(&ecatd, &["--json", "master"])).unwrap();
    assert_eq!(
        (
            json["redundancy"]["state"].as_str(),
            json["redundancy"]["break_after"].as_u64()
        ),
        (Some("broken"), Some(3))
    );

    let (status, done) = cut(&ecatd, r#"{"action":"heal"}"#);
    assert_eq!(status, 200, "{done}");
    let healed = wait_ring(&ecatd, "closed again", |r| r["state"] == "closed");
    assert_eq!(
        (healed["break_after"].clone(), healed["heals"].as_u64()),
        (Value::Null, Some(1))
    );
    let closed = wait_event(&ecatd, "ring_closed", |_| true);
    assert_eq!(
        closed["text"],
        "ring closed again: all 5 slaves on both ports"
    );
    assert_eq!(
        (
            closed["ring"]["state"].as_str(),
            closed["ring"]["heals"].as_u64()
        ),
        (Some("closed"), Some(1))
    );
    assert!(
        closed["id"].as_u64() > event["id"].as_u64(),
        "after the break"
    );
    assert_eq!(metric(&ecatd, "ecat_bus_redundancy_state"), 1.0);
    assert_eq!(metric(&ecatd, "ecat_bus_redundancy_heals_total"), 1.0);
    assert_eq!(metric(&ecatd, "ecat_bus_redundancy_break_after"), -1.0);
    assert!(
        ecat(&ecatd, &["master"])
            .contains("    State: closed\n    Ring slaves: 5\n    Breaks: 1\n    Heals: 1")
    );
    assert_eq!(states(&ecatd), vec!["OP"; 5]);
}

#[test]
fn bad_cuts_are_refused_with_the_field_and_change_nothing_and_a_killed_slave_is_unreachable() {
    let ecatd = Ecatd::start(&["--ring"]);
    wait_ring(&ecatd, "closed", |r| r["state"] == "closed");
    for (body, field) in [
        (r#"{"action":"cut","cable":3}"#, "action"),
        (r#"{"action":"break","cable":6}"#, "cable"),
        (r#"{"action":"break"}"#, "cable"),
        (r#"{"action":"kill","position":5}"#, "position"),
        (r#"{"action":"heal","cable":1}"#, "cable"),
    ] {
        let (status, refused) = cut(&ecatd, body);
        assert_eq!(
            (
                status,
                refused["reason"].as_str(),
                refused["field"].as_str()
            ),
            (400, Some("INVALID_ARGUMENT"), Some(field)),
            "{body}: {refused}"
        );
    }
    let (status, refused) = cut(&ecatd, r#"{"action":"heal","extra":1}"#);
    assert_eq!(
        (status, refused["reason"].as_str()),
        (422, Some("INVALID_BODY")),
        "an unknown field, as every JSON body: {refused}"
    );
    // Nothing changed: the ring is closed, never broke, every slave in OP.
    let ring = wait_ring(&ecatd, "closed", |r| r["state"] == "closed");
    assert_eq!(
        (ring["breaks"].as_u64(), ring["break_after"].clone()),
        (Some(0), Value::Null)
    );
    assert_eq!(states(&ecatd), vec!["OP"; 5]);

    // A slave without power: reached from neither port, the ring broken at it.
    let (status, done) = cut(&ecatd, r#"{"action":"kill","position":2}"#);
    assert_eq!(status, 200, "{done}");
    let killed = wait_ring(&ecatd, "one unreachable", |r| r["unreachable"] == 1);
    assert_eq!(
        (
            killed["state"].as_str(),
            killed["break_after"].as_u64(),
            killed["primary_side"].as_u64(),
            killed["backup_side"].as_u64()
        ),
        (Some("broken"), Some(2), Some(2), Some(2)),
        "{killed}"
    );
    assert_eq!(
        metric(&ecatd, "ecat_bus_redundancy_unreachable_slaves"),
        1.0
    );
    let event = wait_event(&ecatd, "ring_broken", |e| e["ring"]["unreachable"] == 1);
    assert!(
        event["text"]
            .as_str()
            .unwrap_or_default()
            .ends_with("; 1 unreachable (position 2)"),
        "{event}"
    );
}

#[test]
fn a_line_refuses_ring_cuts_and_shows_redundancy_off() {
    let ecatd = Ecatd::start(&[]);
    let (status, master) = get(&ecatd, "/api/v1/master");
    assert_eq!(
        (status, master["redundancy"]["state"].as_str()),
        (200, Some("off"))
    );
    assert_eq!(master["redundancy"]["break_after"], Value::Null);
    let (status, refused) = cut(&ecatd, r#"{"action":"break","cable":1}"#);
    assert_eq!(refused["grpc_code"], 9, "FAILED_PRECONDITION");
    assert_eq!(
        (status, refused["type"].as_str(), refused["reason"].as_str()),
        (409, Some("urn:ecat:error:not_a_ring"), Some("NOT_A_RING")),
        "{refused}"
    );
    assert_eq!(states(&ecatd), vec!["OP"; 5], "nothing was cut");
    assert_eq!(metric(&ecatd, "ecat_bus_redundancy_state"), 0.0);
    assert!(ecat(&ecatd, &["master"]).contains("\n  Redundancy: off\n"));
}

#[test]
fn a_backup_interface_with_the_simulator_is_a_configuration_error() {
    let (status, stderr) = run_to_exit(&["--simulate", "--backup-iface", "eth1"]);
    assert_eq!(status.code(), Some(78), "{stderr}");
    assert!(
        stderr.contains("--backup-iface / [bus] backup_iface = \"eth1\" needs a segment on an interface (--iface)"),
        "{stderr}"
    );
    let (status, stderr) = run_to_exit(&["--iface", "lo", "--backup-iface", "lo"]);
    assert_eq!(status.code(), Some(78), "{stderr}");
    assert!(
        stderr.contains("is the primary interface itself"),
        "{stderr}"
    );
}
