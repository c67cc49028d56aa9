//! ecatd's event streams carry CoE emergencies: a gRPC `WatchEvents` stream (grpcurl) and the
//! REST server-sent events (curl) both deliver the emergency a simulated slave raised (through
//! the `--simulate`-only route `POST /api/v1/slaves/{slave}/sim/emergency`, or on veth through
//! `ecat-sim --control`), with the slave, the error code, the error register and the five
//! manufacturer bytes as raised.

use crate::server_support;

use std::process::Command;

use serde_json::Value;
use server_support::streaming::Streaming;
use server_support::{Ecatd, b64, curl, grpcurl_path};

/// The JSON messages grpcurl printed after "Response contents:" (one pretty object each).
fn grpc_messages(text: &str) -> Vec<Value> {
    text.split("Response contents:")
        .skip(1)
        .filter_map(|part| {
            serde_json::Deserializer::from_str(part)
                .into_iter::<Value>()
                .next()?
                .ok()
        })
        .collect()
}

/// The `data:` payloads of the server-sent events named `kind`.
fn sse_events(text: &str, kind: &str) -> Vec<Value> {
    let mut out = Vec::new();
    let mut current = String::new();
    for line in text.lines() {
        if let Some(name) = line.strip_prefix("event:") {
            current = name.trim().to_owned();
        } else if let Some(data) = line.strip_prefix("data:")
            && current == kind
            && let Ok(value) = serde_json::from_str(data.trim())
        {
            out.push(value);
        }
    }
    out
}

fn raise(ecatd: &Ecatd, slave: &str, body: &str) -> (u16, String) {
    server_support::post_json(
        &format!("{}/api/v1/slaves/{slave}/sim/emergency", ecatd.http),
        body,
    )
}

#[test]
fn emergencies_reach_the_grpc_and_sse_streams() {
    let mut ecatd = Ecatd::start(&[]);
    // The CoE store of the default segment, named by position.
    let (status, body) = curl(&["-s", &format!("{}/api/v1/slaves/3", ecatd.http)]);
    assert_eq!(status, 200, "{body}");
    let slave: Value = serde_json::from_str(&body).unwrap();
    let station = slave["station"].as_u64().unwrap();

    let grpc = Streaming::start(
        Command::new(grpcurl_path())
            .args(["-plaintext", "-v", "-d", "{}", &ecatd.grpc])
            .arg("ecat.v1.BusService/WatchEvents"),
    );
    let sse = Streaming::start(Command::new("curl").args([
        "-s",
        "-N",
        "-i",
        "-H",
        "accept: text/event-stream",
        &format!("{}/api/v1/events", ecatd.http),
    ]));
    // Both subscribed once their response headers arrived (the handlers subscribe before
    // answering).
    grpc.wait_for("gRPC response headers", |t| {
        t.contains("Response headers received").then_some(())
    });
    sse.wait_for("SSE response headers", |t| {
        t.lines()
            .next()
            .filter(|l| l.starts_with("HTTP/1.1 200"))
            .map(|_| ())
    });

    ecatd
        .raise_emergency(3, 0x8130, 0x11, [0xde, 0xad, 0xbe, 0xef, 0x01])
        .expect("the emergency is raised");

    let from_grpc = grpc.wait_for("emergency on the gRPC stream", |t| {
        grpc_messages(t)
            .into_iter()
            .find(|m| m["kind"] == "emergency")
    });
    assert_eq!(from_grpc["position"], 3);
    assert_eq!(from_grpc["station"].as_u64(), Some(station));
    assert_eq!(from_grpc["emergency"]["errorCode"], 0x8130);
    assert_eq!(from_grpc["emergency"]["errorRegister"], 0x11);
    let data = from_grpc["emergency"]["data"].as_str().unwrap();
    assert_eq!(b64::decode(data), [0xde, 0xad, 0xbe, 0xef, 0x01]);

    let from_sse = sse.wait_for("emergency on the SSE stream", |t| {
        sse_events(t, "emergency").into_iter().next()
    });
    assert_eq!(from_sse["kind"], "emergency");
    assert_eq!(from_sse["position"], 3);
    assert_eq!(from_sse["station"].as_u64(), Some(station));
    assert_eq!(from_sse["emergency"]["error_code"], 0x8130);
    assert_eq!(from_sse["emergency"]["error_register"], 0x11);
    assert_eq!(from_sse["emergency"]["data"], "deadbeef01");

    // Exactly one emergency each: nothing invented or duplicated.
    let grpc_count = grpc_messages(&grpc.text())
        .iter()
        .filter(|m| m["kind"] == "emergency")
        .count();
    assert_eq!(grpc_count, 1);
    assert_eq!(sse_events(&sse.text(), "emergency").len(), 1);
}

#[test]
fn the_sim_route_refuses_bad_requests() {
    let ecatd = Ecatd::start(&[]);
    let good = r#"{"error_code": 1, "error_register": 0, "data": "0000000000"}"#;
    if server_support::on_veth() {
        // ecatd on a real interface has no simulator to reach: the route is not there.
        let (status, body) = raise(&ecatd, "3", good);
        assert_eq!(status, 404, "{body}");
        return;
    }
    // Position 1 of the default segment is the DO8 terminal: no mailbox, no emergencies.
    let (status, body) = raise(&ecatd, "1", good);
    assert_eq!(status, 400, "{body}");
    let (status, body) = raise(&ecatd, "9", good);
    assert_eq!(status, 404, "{body}");
    let short = r#"{"error_code": 1, "error_register": 0, "data": "00"}"#;
    let (status, body) = raise(&ecatd, "3", short);
    assert_eq!(status, 400, "{body}");
}

/// The event history: kept from before the first scan, numbered and stamped, answered as
/// JSON (filtered by kind, slave, time and count) to a client that does not ask for a
/// stream; and the stream asked with `Last-Event-ID` sends the kept events after that number
/// first, each once, then the live ones.
#[test]
fn the_history_is_answered_as_json_and_the_stream_resumes_after_the_last_event_id() {
    let ecatd = Ecatd::start(&[]);
    let history = |query: &str| -> (u16, Value) {
        let (status, body) = curl(&["-s", &format!("{}/api/v1/events{query}", ecatd.http)]);
        (
            status,
            serde_json::from_str(&body).unwrap_or(Value::String(body)),
        )
    };
    // The scan's events, kept since start-up: the default segment's slaves reached OP.
    let (status, all) = history("");
    assert_eq!(status, 200, "{all}");
    let all = all.as_array().expect("a JSON list").clone();
    let ids: Vec<u64> = all.iter().map(|e| e["id"].as_u64().unwrap()).collect();
    assert!(
        ids.windows(2).all(|w| w[0] < w[1]),
        "numbered in order: {ids:?}"
    );
    for event in &all {
        let time = event["time"].as_str().unwrap();
        assert!(
            time.len() == 24 && time.ends_with('Z') && time.starts_with("20"),
            "UTC, RFC 3339 with milliseconds: {event}"
        );
    }
    let to_op = |e: &&Value| e["kind"] == "state_changed" && e["to"] == "OP";
    let slaves = sim::topology::Topology::default_segment().slaves.len();
    assert_eq!(all.iter().filter(to_op).count(), slaves, "{all:#?}");
    // Words, not Rust's debug form.
    let text = all.iter().find(to_op).unwrap()["text"].as_str().unwrap();
    assert!(text.ends_with("SAFEOP -> OP"), "{text}");

    // A state change is kept as it happens.
    let (status, body) = curl(&[
        "-s",
        "-X",
        "PUT",
        "-H",
        "content-type: application/json",
        "-d",
        r#"{"state":"SAFEOP"}"#,
        &format!("{}/api/v1/slaves/1/state", ecatd.http),
    ]);
    assert_eq!(status, 200, "{body}");
    let (_, newest) = history("?kind=state_changed&slave=1&limit=1");
    let newest = newest.as_array().unwrap();
    assert_eq!(newest.len(), 1, "{newest:?}");
    assert_eq!(newest[0]["position"], 1);
    assert_eq!(newest[0]["to"], "SAFEOP");
    assert!(newest[0]["id"].as_u64().unwrap() > *ids.last().unwrap());
    // Filters: by kind, by time (a span back, a time to come), and refusals naming the field.
    let (_, found) = history("?kind=slave_found");
    assert_eq!(found.as_array().unwrap().len(), slaves, "{found}");
    let (_, now) = history("");
    let (_, recent) = history("?since=10m");
    assert_eq!(recent, now, "everything is from the last ten minutes");
    let (_, none) = history("?since=2999-01-01T00:00:00Z");
    assert_eq!(none, serde_json::json!([]));
    let (status, refused) = history("?since=yesterday-ish");
    assert_eq!(
        (status, &refused["field"]),
        (400, &Value::from("since")),
        "{refused}"
    );
    let (status, refused) = history("?verbose=1");
    assert_eq!(status, 400, "{refused}");

    // The stream, resumed after the third kept event: the rest, each once, in order.
    let now: Vec<u64> = now
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["id"].as_u64().unwrap())
        .collect();
    let sent = resumed(&ecatd, now[2], *now.last().unwrap());
    assert_eq!(sent, now[3..].to_vec());
}

/// The ids the stream sends when resumed with `Last-Event-ID: after`, up to `last` (events
/// newer than `last`, which a live segment may raise meanwhile, are left out).
fn resumed(ecatd: &Ecatd, after: u64, last: u64) -> Vec<u64> {
    let sse = Streaming::start(Command::new("curl").args([
        "-s",
        "-N",
        "-H",
        "accept: text/event-stream",
        "-H",
        &format!("last-event-id: {after}"),
        &format!("{}/api/v1/events", ecatd.http),
    ]));
    sse.wait_for("the kept events after the resume point", |t| {
        t.contains(&format!("id: {last}\n")).then_some(())
    });
    sse.text()
        .lines()
        .filter_map(|l| l.strip_prefix("id:")?.trim().parse().ok())
        .filter(|&id| id <= last)
        .collect()
}

/// With `[events] journal`, the history and the numbering survive a restart: the events of
/// the first run are answered by the second with their numbers and times, the new ones are
/// numbered after them, and a stream resumed with a number from the first run misses nothing.
#[test]
fn the_journal_keeps_the_history_and_the_numbering_across_a_restart() {
    let dir = std::env::temp_dir().join(format!("ecatd-journal-e2e-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("ecatd.toml");
    let journal = dir.join("events.jsonl");
    std::fs::write(
        &config,
        format!(
            "[events]\nhistory = 500\njournal = \"{}\"\n",
            journal.display()
        ),
    )
    .unwrap();
    let history = |ecatd: &Ecatd| -> Vec<Value> {
        let (status, body) = curl(&["-s", &format!("{}/api/v1/events?limit=500", ecatd.http)]);
        assert_eq!(status, 200, "{body}");
        serde_json::from_str::<Value>(&body)
            .unwrap()
            .as_array()
            .unwrap()
            .clone()
    };
    let mut first = Ecatd::start(&["--config", config.to_str().unwrap()]);
    let before = history(&first);
    let slaves = sim::topology::Topology::default_segment().slaves.len();
    assert!(before.len() >= 2 * slaves, "the scan's events: {before:#?}");
    assert!(first.stop(), "ecatd stops cleanly");
    // Each kept event is one JSON line in the file.
    let lines = std::fs::read_to_string(&journal).unwrap();
    let written: Vec<Value> = lines
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(written[..before.len()], before[..], "{lines}");

    let second = Ecatd::start(&["--config", config.to_str().unwrap()]);
    let after = history(&second);
    assert_eq!(
        after[..before.len()],
        before[..],
        "the first run's events, as they were"
    );
    let last_before = before.last().unwrap()["id"].as_u64().unwrap();
    let new_ids: Vec<u64> = after[before.len()..]
        .iter()
        .map(|e| e["id"].as_u64().unwrap())
        .collect();
    assert!(!new_ids.is_empty(), "the second scan's events");
    assert_eq!(
        new_ids[0],
        last_before + 1,
        "numbering goes on: {new_ids:?}"
    );
    // A client of the first run resumes where it was.
    let resume = before[before.len() - 2]["id"].as_u64().unwrap();
    let last = after.last().unwrap()["id"].as_u64().unwrap();
    let want: Vec<u64> = after
        .iter()
        .map(|e| e["id"].as_u64().unwrap())
        .filter(|id| *id > resume)
        .collect();
    assert_eq!(resumed(&second, resume, last), want);
    drop(second);
    std::fs::remove_dir_all(&dir).unwrap();
}
