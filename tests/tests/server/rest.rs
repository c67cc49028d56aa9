//! ecatd's REST API driven by curl: every route answers with the simulator's values,
//! errors are JSON with the protocol's code, events arrive as server-sent events, and the
//! OpenAPI document validates (openapi-spec-validator from the venv) and lists every route.

use crate::server_support;

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use serde_json::Value;
use server_support::gateway_client::GatewayClient;
use server_support::{Ecatd, curl, curl_as_browser};
use sim::topology::{SIM_VENDOR_ID, Topology};

/// Every REST route the tests call, as the OpenAPI document must list it.
const ROUTES: [(&str, &str); 43] = [
    ("get", "/api/v1/master"),
    ("get", "/api/v1/process-data"),
    ("get", "/api/v1/process-data/layout"),
    ("get", "/api/v1/process-data/forced"),
    ("get", "/api/v1/process-data/stream"),
    ("get", "/api/v1/slaves/{slave}/process-data"),
    (
        "put",
        "/api/v1/slaves/{slave}/process-data/{index}/{subindex}",
    ),
    (
        "delete",
        "/api/v1/slaves/{slave}/process-data/{index}/{subindex}",
    ),
    ("get", "/api/v1/capture"),
    ("get", "/api/v1/domains"),
    ("get", "/api/v1/log-filter"),
    ("put", "/api/v1/log-filter"),
    ("post", "/api/v1/slaves/{slave}/registers/{address}/rdwr"),
    ("get", "/api/v1/slaves"),
    ("get", "/api/v1/slaves/{slave}"),
    ("put", "/api/v1/slaves/{slave}/state"),
    ("post", "/api/v1/rescan"),
    ("get", "/api/v1/events"),
    ("get", "/api/v1/config"),
    ("get", "/api/v1/slaves/{slave}/registers/{address}"),
    ("put", "/api/v1/slaves/{slave}/registers/{address}"),
    ("get", "/api/v1/slaves/{slave}/sii"),
    ("put", "/api/v1/slaves/{slave}/sii/{word}"),
    ("put", "/api/v1/slaves/{slave}/alias"),
    ("get", "/api/v1/slaves/{slave}/coe/sdo/{index}/{subindex}"),
    ("put", "/api/v1/slaves/{slave}/coe/sdo/{index}/{subindex}"),
    ("get", "/api/v1/slaves/{slave}/coe/od"),
    ("get", "/api/v1/slaves/{slave}/coe/od/{index}"),
    ("get", "/api/v1/slaves/{slave}/coe/od/{index}/{subindex}"),
    ("get", "/api/v1/slaves/{slave}/soe/{drive}/{idn}"),
    ("put", "/api/v1/slaves/{slave}/soe/{drive}/{idn}"),
    ("get", "/api/v1/slaves/{slave}/foe/{name}"),
    ("put", "/api/v1/slaves/{slave}/foe/{name}"),
    ("post", "/api/v1/slaves/{slave}/voe"),
    ("get", "/api/v1/slaves/{slave}/eoe/ip"),
    ("put", "/api/v1/slaves/{slave}/eoe/ip"),
    ("put", "/api/v1/slaves/{slave}/eoe/filter"),
    ("get", "/api/v1/eoe/interfaces"),
    ("get", "/api/v1/gateway"),
    ("post", "/api/v1/gateway/start"),
    ("post", "/api/v1/gateway/stop"),
    ("get", "/api/v1/bus"),
    ("get", "/api/v1/session"),
];

fn get(ecatd: &Ecatd, path: &str) -> (u16, Value) {
    let (status, body) = curl(&["-s", &format!("{}{path}", ecatd.http)]);
    (
        status,
        serde_json::from_str(&body).unwrap_or(Value::String(body)),
    )
}

fn send(ecatd: &Ecatd, method: &str, path: &str, body: &str) -> (u16, Value) {
    let url = format!("{}{path}", ecatd.http);
    let (status, body) = curl(&[
        "-s",
        "-X",
        method,
        "-H",
        "content-type: application/json",
        "-d",
        body,
        &url,
    ]);
    (
        status,
        serde_json::from_str(&body).unwrap_or(Value::String(body)),
    )
}

fn pattern(size: usize) -> Vec<u8> {
    (0..size).map(|i| (i % 251) as u8).collect()
}

#[test]
fn every_route_answers_with_the_simulators_values() {
    let ecatd = Ecatd::start(&[]);
    let topology = Topology::default_segment();

    let (status, slaves) = get(&ecatd, "/api/v1/slaves");
    assert_eq!(status, 200);
    let names: Vec<&str> = slaves
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    let expected: Vec<&str> = topology.slaves.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, expected);
    let (_, slave) = get(&ecatd, "/api/v1/slaves/%231004");
    assert_eq!(slave["position"], 3);
    let (status, missing) = get(&ecatd, "/api/v1/slaves/9");
    assert_eq!(
        (status, missing["reason"].as_str()),
        (404, Some("UNKNOWN_SLAVE"))
    );

    let (status, state) = send(
        &ecatd,
        "PUT",
        "/api/v1/slaves/2/state",
        r#"{"state":"SAFEOP"}"#,
    );
    assert_eq!((status, state["state"].as_str()), (200, Some("SAFEOP")));
    let (status, bad) = send(
        &ecatd,
        "PUT",
        "/api/v1/slaves/2/state",
        r#"{"state":"FLYING"}"#,
    );
    assert_eq!((status, bad["grpc_code"].as_i64()), (400, Some(3)));
    let (status, rescan) = send(&ecatd, "POST", "/api/v1/rescan", "");
    assert_eq!(status, 200);
    assert_eq!(
        rescan["slaves"].as_array().unwrap().len(),
        topology.slaves.len()
    );

    let (_, reg) = get(&ecatd, "/api/v1/slaves/1/registers/0x10?length=2");
    assert_eq!(reg["data"], hex(&1002u16.to_le_bytes()));
    let (status, _) = send(
        &ecatd,
        "PUT",
        "/api/v1/slaves/1/registers/0xa00",
        r#"{"data":"a55a"}"#,
    );
    assert_eq!(status, 200);
    let (_, sii) = get(&ecatd, "/api/v1/slaves/0/sii");
    assert_eq!(
        &sii["data"].as_str().unwrap()[32..40],
        hex(&SIM_VENDOR_ID.to_le_bytes())
    );
    // SII word 0x20 is reserved (no meaning to the slave): write it and read it back.
    let (status, _) = send(
        &ecatd,
        "PUT",
        "/api/v1/slaves/2/sii/0x20",
        r#"{"data":"3412"}"#,
    );
    assert_eq!(status, 200, "SII write");
    let (_, sii2) = get(&ecatd, "/api/v1/slaves/2/sii");
    assert_eq!(
        &sii2["data"].as_str().unwrap()[0x40 * 2..0x40 * 2 + 4],
        "3412"
    );
    let (status, alias) = send(&ecatd, "PUT", "/api/v1/slaves/4/alias", r#"{"alias":1911}"#);
    assert_eq!((status, alias["alias"].as_u64()), (200, Some(1911)));
    let (_, by_alias) = get(&ecatd, "/api/v1/slaves/@0x777");
    assert_eq!(by_alias["position"], 4);

    let (_, upload) = get(&ecatd, "/api/v1/slaves/0/coe/sdo/0x1018/1");
    assert_eq!(upload["data"], hex(&SIM_VENDOR_ID.to_le_bytes()));
    let (_, typed) = get(&ecatd, "/api/v1/slaves/0/coe/sdo/0x1018/1?type=auto");
    assert_eq!(typed["value"], SIM_VENDOR_ID.to_string());
    let (status, _) = send(
        &ecatd,
        "PUT",
        "/api/v1/slaves/3/coe/sdo/0x2001/0",
        r#"{"value":"4660","type":"auto"}"#,
    );
    assert_eq!(status, 200);
    let (_, typed) = get(&ecatd, "/api/v1/slaves/3/coe/sdo/0x2001/0?type=u32");
    assert_eq!(typed["value"], "4660");
    let (status, bad) = send(
        &ecatd,
        "PUT",
        "/api/v1/slaves/3/coe/sdo/0x2001/0",
        r#"{"value":"-1","type":"auto"}"#,
    );
    assert_eq!(
        (status, bad["reason"].as_str()),
        (400, Some("INVALID_ARGUMENT"))
    );
    let (status, abort) = get(&ecatd, "/api/v1/slaves/0/coe/sdo/0x6000/1");
    assert_eq!(status, 404, "an unknown object is NOT_FOUND");
    assert_eq!(abort["reason"], "SDO_ABORT");
    assert_eq!(abort["protocol_code"], 0x0602_0000);
    let (status, _) = send(
        &ecatd,
        "PUT",
        "/api/v1/slaves/3/coe/sdo/0x2001/0",
        r#"{"data":"efbeadde"}"#,
    );
    assert_eq!(status, 200);
    let (_, back) = get(&ecatd, "/api/v1/slaves/3/coe/sdo/0x2001/0");
    assert_eq!(back["data"], "efbeadde");
    let (_, list) = get(&ecatd, "/api/v1/slaves/0/coe/od");
    assert!(
        list["indices"]
            .as_array()
            .unwrap()
            .contains(&Value::from(0x6041))
    );
    let (_, object) = get(&ecatd, "/api/v1/slaves/0/coe/od/0x6041");
    assert_eq!(object["name"], "Statusword");
    let (_, entry) = get(&ecatd, "/api/v1/slaves/0/coe/od/0x6041/0");
    assert_eq!(entry["bit_length"], 16);

    let (_, soe) = get(&ecatd, "/api/v1/slaves/0/soe/0/0x8064");
    assert_eq!(soe["data"], hex(&253u16.to_le_bytes()));
    let (status, soe_err) = send(
        &ecatd,
        "PUT",
        "/api/v1/slaves/0/soe/0/0x8064",
        r#"{"data":"0100"}"#,
    );
    assert_eq!(
        (status, soe_err["reason"].as_str()),
        (409, Some("SOE_ERROR"))
    );

    let url = format!("{}/api/v1/slaves/0/foe/firmware.bin", ecatd.http);
    let file = Command::new("curl").args(["-sf", &url]).output().unwrap();
    assert!(file.status.success());
    assert_eq!(file.stdout, pattern(topology.slaves[0].foe_files[0].size));
    let upload_file = std::env::temp_dir().join(format!("ecatd-foe-{}.bin", std::process::id()));
    let content: Vec<u8> = (0..3000u32).map(|i| (i * 7) as u8).collect();
    std::fs::write(&upload_file, &content).unwrap();
    let put_url = format!("{}/api/v1/slaves/0/foe/upload.bin", ecatd.http);
    let (status, _) = curl(&[
        "-s",
        "-X",
        "PUT",
        "--data-binary",
        &format!("@{}", upload_file.display()),
        "-H",
        "content-type: application/octet-stream",
        &put_url,
    ]);
    std::fs::remove_file(&upload_file).unwrap();
    assert_eq!(status, 200, "FoE write");

    let (_, voe) = send(
        &ecatd,
        "POST",
        "/api/v1/slaves/0/voe",
        r#"{"vendor_id":4452,"vendor_type":1,"data":"000ff0"}"#,
    );
    assert_eq!(voe["data"], "fff00f");
    let (status, _) = send(
        &ecatd,
        "PUT",
        "/api/v1/slaves/4/eoe/ip",
        r#"{"ip":"192.168.100.45","subnet_mask":"255.255.255.0"}"#,
    );
    assert_eq!(status, 200);
    let (_, ip) = get(&ecatd, "/api/v1/slaves/4/eoe/ip");
    assert_eq!(ip["ip"], "192.168.100.45");
    let (status, bad_ip) = send(
        &ecatd,
        "PUT",
        "/api/v1/slaves/4/eoe/ip",
        r#"{"ip":"300.1.1.1"}"#,
    );
    assert_eq!(
        (status, bad_ip["reason"].as_str()),
        (400, Some("INVALID_ARGUMENT"))
    );
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[test]
fn state_changes_arrive_as_server_sent_events() {
    let ecatd = Ecatd::start(&[]);
    let mut stream = Command::new("curl")
        .args([
            "-sN",
            "--max-time",
            "30",
            "-H",
            "accept: text/event-stream",
            &format!("{}/api/v1/events", ecatd.http),
        ])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let stdout = stream.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if let Some(data) = line.strip_prefix("data: ") {
                let _ = tx.send(serde_json::from_str::<Value>(data).unwrap());
            }
        }
    });
    // curl may subscribe after a change, so change the state until an event for the slave
    // arrives (bounded attempts, each waiting up to a second for the event).
    let mut found = None;
    'attempts: for attempt in 0..20 {
        let state = if attempt % 2 == 0 { "SAFEOP" } else { "OP" };
        let (status, _) = send(
            &ecatd,
            "PUT",
            "/api/v1/slaves/1/state",
            &format!(r#"{{"state":"{state}"}}"#),
        );
        assert_eq!(status, 200);
        while let Ok(event) = rx.recv_timeout(Duration::from_secs(1)) {
            if event["kind"] == "state_changed" && event["position"] == 1 {
                found = Some(event);
                break 'attempts;
            }
        }
    }
    let _ = stream.kill();
    let _ = stream.wait();
    let event = found.expect("a state_changed event for slave 1");
    assert_eq!(event["station"], 1002);
    assert!(event["to"] == "SAFEOP" || event["to"] == "OP", "{event}");
}

#[test]
fn gateway_routes_report_stop_and_start_the_gateway() {
    let ecatd = Ecatd::start(&[]);
    let bound = ecatd.gateway_addr();
    let (status, gateway) = get(&ecatd, "/api/v1/gateway");
    assert_eq!(status, 200);
    assert_eq!(gateway["enabled"], true);
    assert_eq!(gateway["running"], true);
    assert_eq!(gateway["bound_address"], bound.to_string());
    assert_eq!(gateway["port"], bound.port());
    assert_eq!(gateway["configured_address"], "127.0.0.1:0");
    assert_eq!(gateway["master_number"], 1);
    assert_eq!(gateway["strict"], false);
    assert_eq!(gateway["stats"]["total_requests"], 0);

    // Two SDO uploads (one of a missing object) and one malformed datagram.
    let mut client = GatewayClient::new(bound);
    let device_type = Topology::default_segment().slaves[0].device_type;
    assert_eq!(
        client.sdo_upload(1001, 0x1000, 0),
        Ok(device_type.to_le_bytes().to_vec())
    );
    assert_eq!(
        client.sdo_upload(1001, 0x5FFF, 0),
        Err(server_support::gateway_client::object_missing()),
        "the slave's own abort, forwarded"
    );
    client.send_raw(&[0x01]);
    // The malformed datagram gets no answer: wait for its count instead.
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    let stats = loop {
        let (_, gateway) = get(&ecatd, "/api/v1/gateway");
        if gateway["stats"]["total_requests"] == 3 || std::time::Instant::now() > deadline {
            break gateway["stats"].clone();
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(stats["total_requests"], 3, "{stats}");
    assert_eq!(stats["forwarded_requests"], 2);
    assert_eq!(stats["failed_requests"], 1);
    assert_eq!(stats["coe_count"], 2);
    assert_eq!(stats["failures"]["malformed"], 1);
    assert_eq!(stats["latency"]["count"], 2);
    assert_eq!(stats["port"], bound.port());

    let (status, stopped) = send(&ecatd, "POST", "/api/v1/gateway/stop", "");
    assert_eq!(status, 200, "{stopped}");
    assert_eq!(stopped["running"], false);
    assert_eq!(stopped["bound_address"], "");
    assert_eq!(stopped["stats"]["started_at_ms"], 0);
    let (status, started) = send(&ecatd, "POST", "/api/v1/gateway/start", "");
    assert_eq!(status, 200, "{started}");
    assert_eq!(started["running"], true);
    assert_eq!(started["stats"]["total_requests"], 0);
    let port = started["port"].as_u64().unwrap() as u16;
    assert_eq!(started["stats"]["port"], port);
    let mut client = GatewayClient::new(std::net::SocketAddr::from(([127, 0, 0, 1], port)));
    assert_eq!(
        client.sdo_upload(1001, 0x1000, 0),
        Ok(device_type.to_le_bytes().to_vec())
    );
}

/// The dashboard's two reads: the bus counters move with the cycle, the session names the
/// caller (no tokens: `anonymous` with the write role).
#[test]
fn bus_counters_and_session() {
    let ecatd = Ecatd::start(&[]);
    let (status, first) = get(&ecatd, "/api/v1/bus");
    assert_eq!(status, 200, "{first}");
    assert!(first["period_us"].as_u64().unwrap() > 0, "{first}");
    assert!(first["expected_wkc"].as_u64().unwrap() > 0, "{first}");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    loop {
        let (_, now) = get(&ecatd, "/api/v1/bus");
        if now["cycles_completed"].as_u64() > first["cycles_completed"].as_u64()
            && now["frames_sent"].as_u64() > first["frames_sent"].as_u64()
        {
            assert!(now["cycle_time"]["count"].as_u64().unwrap() > 0, "{now}");
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "the cycle counters do not move: {now}"
        );
        // Poll interval; the loop ends on the condition or the deadline.
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let (status, session) = get(&ecatd, "/api/v1/session");
    assert_eq!(status, 200);
    assert_eq!(
        session,
        serde_json::json!({"caller": "anonymous", "role": "write"})
    );
}

#[test]
fn openapi_document_validates_and_lists_every_route() {
    let ecatd = Ecatd::start(&[]);
    let (status, body) = curl(&["-s", &format!("{}/api/v1/openapi.json", ecatd.http)]);
    assert_eq!(status, 200);
    let doc: Value = serde_json::from_str(&body).unwrap();
    for (method, path) in ROUTES {
        assert!(
            doc["paths"][path][method].is_object(),
            "{method} {path} missing from the document"
        );
    }
    let documented: usize = doc["paths"]
        .as_object()
        .unwrap()
        .values()
        .map(|p| p.as_object().unwrap().len())
        .sum();
    assert_eq!(
        documented,
        ROUTES.len(),
        "the document has routes the tests do not know"
    );
    let file = std::env::temp_dir().join(format!("ecatd-openapi-{}.json", std::process::id()));
    std::fs::write(&file, &body).unwrap();
    let validator = server_support::venv_bin().join("openapi-spec-validator");
    let output = Command::new(&validator)
        .arg(&file)
        .output()
        .unwrap_or_else(|e| panic!("{}: {e}", validator.display()));
    std::fs::remove_file(&file).unwrap();
    assert!(
        output.status.success(),
        "openapi-spec-validator refused the document:\n{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
}

#[test]
fn browser_forms_and_foreign_hosts_are_refused() {
    let ecatd = Ecatd::start(&[]);
    let stop = format!("{}/api/v1/gateway/stop", ecatd.http);
    let slaves = format!("{}/api/v1/slaves", ecatd.http);
    // A cross-origin web form: urlencoded body, a foreign Origin, no custom header.
    let (status, body) = curl_as_browser(&[
        "-s",
        "-X",
        "POST",
        "-H",
        "Content-Type: application/x-www-form-urlencoded",
        "-H",
        "Origin: http://evil.example",
        "-d",
        "a=b",
        &stop,
    ]);
    assert_eq!(status, 403, "{body}");
    assert!(body.contains("cross-origin"), "{body}");
    // The same form from the page's own origin is still a form: refused.
    let own_origin = format!("Origin: {}", ecatd.http);
    let (status, body) = curl_as_browser(&[
        "-s",
        "-X",
        "POST",
        "-H",
        "Content-Type: application/x-www-form-urlencoded",
        "-H",
        &own_origin,
        "-d",
        "a=b",
        &stop,
    ]);
    assert_eq!(status, 403, "{body}");
    assert!(body.contains("X-Ecat-Client"), "{body}");
    // DNS rebinding: a foreign Host, on a write and on a read.
    for method in ["POST", "GET"] {
        let (status, body) = curl_as_browser(&[
            "-s",
            "-X",
            method,
            "-H",
            "Host: evil.example",
            "-H",
            "Content-Type: application/json",
            &slaves,
        ]);
        assert_eq!(status, 421, "{method}: {body}");
        assert!(body.contains("evil.example"), "{body}");
    }
    // Nothing was stopped: the gateway still runs.
    let (_, gateway) = get(&ecatd, "/api/v1/gateway");
    assert_eq!(gateway["running"], true, "{gateway}");
    // A same-origin JSON request works without the custom header.
    let (status, body) = curl_as_browser(&[
        "-s",
        "-X",
        "POST",
        "-H",
        "Content-Type: application/json",
        "-H",
        &own_origin,
        &stop,
    ]);
    assert_eq!(status, 200, "{body}");
    let (_, gateway) = get(&ecatd, "/api/v1/gateway");
    assert_eq!(gateway["running"], false, "{gateway}");
}

#[test]
fn sii_writes_keep_the_checksum_valid_unless_forced() {
    use master_core::wire::sii::checksum::{checksum_ok, crc8};
    let ecatd = Ecatd::start(&[]);
    let image = |ecatd: &Ecatd| {
        let (status, sii) = get(ecatd, "/api/v1/slaves/2/sii");
        assert_eq!(status, 200, "{sii}");
        hex_decode(sii["data"].as_str().unwrap())
    };
    let before = image(&ecatd);
    assert!(checksum_ok(&before).unwrap());
    // Word 5 (reserved) without word 7: the checksum is recomputed and written.
    let (status, body) = send(
        &ecatd,
        "PUT",
        "/api/v1/slaves/2/sii/5",
        r#"{"data":"3412"}"#,
    );
    assert_eq!(status, 200, "{body}");
    let after = image(&ecatd);
    assert_eq!(&after[10..12], &[0x34, 0x12]);
    let mut expected = before.clone();
    expected[10..12].copy_from_slice(&[0x34, 0x12]);
    expected[14] = crc8(&expected[..14]);
    assert_eq!(&after[..16], &expected[..16]);
    assert!(checksum_ok(&after).unwrap());
    // Words 5-7 with a wrong checksum: refused, nothing written.
    let wrong = (after[14] ^ 0xFF, after[15]);
    let body = format!(r#"{{"data":"78560000{:02x}{:02x}"}}"#, wrong.0, wrong.1);
    let (status, refused) = send(&ecatd, "PUT", "/api/v1/slaves/2/sii/5", &body);
    assert_eq!(status, 400, "{refused}");
    assert!(refused.to_string().contains("checksum"), "{refused}");
    assert_eq!(&image(&ecatd)[..16], &after[..16]);
    // The same with force: written as given.
    let (status, forced) = send(&ecatd, "PUT", "/api/v1/slaves/2/sii/5?force=true", &body);
    assert_eq!(status, 200, "{forced}");
    let raw = image(&ecatd);
    assert_eq!(&raw[10..16], &[0x78, 0x56, 0x00, 0x00, wrong.0, wrong.1]);
    assert!(!checksum_ok(&raw).unwrap());
}

fn hex_decode(text: &str) -> Vec<u8> {
    (0..text.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&text[i..i + 2], 16).unwrap())
        .collect()
}

/// curl with `extra` arguments: the status, the content type and the body as JSON.
fn answer(ecatd: &Ecatd, method: &str, path: &str, extra: &[&str]) -> (u16, String, Value) {
    let url = format!("{}{path}", ecatd.http);
    let output = Command::new("curl")
        .args(["-s", "-X", method, "-H", "X-Ecat-Client: tests"])
        .args(extra)
        .arg(&url)
        .args(["-w", "\n%{content_type}\n%{http_code}"])
        .output()
        .expect("curl runs");
    let text = String::from_utf8_lossy(&output.stdout).into_owned();
    let mut lines = text.rsplitn(3, '\n');
    let status = lines.next().unwrap_or("0").trim().parse().unwrap_or(0);
    let content_type = lines.next().unwrap_or("").to_owned();
    let body = lines.next().unwrap_or("");
    let json = serde_json::from_str(body).unwrap_or(Value::String(body.to_owned()));
    (status, content_type, json)
}

#[test]
fn every_malformed_request_is_answered_with_problem_json_and_changes_nothing() {
    let ecatd = Ecatd::start(&[]);
    let json = ["-H", "Content-Type: application/json", "-d"];
    let with = |body: &'static str| -> Vec<&'static str> {
        let mut args = json.to_vec();
        args.push(body);
        args
    };
    let state = "/api/v1/slaves/0/state";
    let cases: Vec<(&str, &str, Vec<&str>, u16, &str)> = vec![
        // A number where a string is expected.
        ("PUT", state, with(r#"{"state": 6}"#), 422, "invalid_body"),
        // Not JSON at all.
        ("PUT", state, with(r#"{"state": "#), 400, "invalid_json"),
        // A field the body does not have.
        (
            "PUT",
            state,
            with(r#"{"state": "INIT", "force": true}"#),
            422,
            "invalid_body",
        ),
        // A required field missing.
        ("PUT", state, with("{}"), 422, "invalid_body"),
        // No content type (curl's -d says urlencoded unless told; remove the header).
        (
            "PUT",
            state,
            vec!["-H", "Content-Type:", "-d", r#"{"state":"INIT"}"#],
            415,
            "unsupported_media_type",
        ),
        // A query parameter the route does not have, on a read and on a write.
        (
            "GET",
            "/api/v1/slaves?verbose=1",
            vec![],
            400,
            "unknown_query_parameter",
        ),
        (
            "PUT",
            "/api/v1/slaves/0/state?force=1",
            with(r#"{"state":"INIT"}"#),
            400,
            "unknown_query_parameter",
        ),
        // A declared query parameter of the wrong form.
        (
            "GET",
            "/api/v1/slaves/0/coe/sdo/0x1018/1?complete_access=maybe",
            vec![],
            400,
            "invalid_query",
        ),
        // A route that does not exist, inside the API and outside it.
        ("GET", "/api/v1/nothing-here", vec![], 404, "unknown_route"),
        ("GET", "/nothing-here", vec![], 404, "unknown_route"),
        // A route that exists, with a method it does not take.
        (
            "DELETE",
            "/api/v1/slaves",
            vec![],
            405,
            "method_not_allowed",
        ),
    ];
    for (method, path, extra, want_status, want_type) in &cases {
        let (status, content_type, body) = answer(&ecatd, method, path, extra);
        let case = format!("{method} {path} {extra:?}: {status} {content_type} {body}");
        assert_eq!(status, *want_status, "{case}");
        assert_eq!(content_type, "application/problem+json", "{case}");
        assert_eq!(
            body["type"],
            format!("urn:ecat:error:{want_type}"),
            "{case}"
        );
        assert_eq!(body["status"], *want_status, "{case}");
        assert!(
            body["detail"].as_str().is_some_and(|d| !d.is_empty()),
            "{case}"
        );
    }
    // A typed value: an unknown type, and complete access (which writes bytes) with a type,
    // each refused naming its field; the entry keeps its value.
    let sdo = "/api/v1/slaves/3/coe/sdo/0x2001/0";
    let (_, _, kept) = answer(&ecatd, "GET", sdo, &[]);
    for (body, field) in [
        (r#"{"value":"5","type":"u7"}"#, "value_type"),
        (
            r#"{"value":"5","type":"u8","complete_access":true}"#,
            "complete_access",
        ),
    ] {
        let (status, content_type, answer) = answer(&ecatd, "PUT", sdo, &with(body));
        let case = format!("PUT {sdo} {body}: {status} {content_type} {answer}");
        assert_eq!(status, 400, "{case}");
        assert_eq!(content_type, "application/problem+json", "{case}");
        assert_eq!(answer["field"], field, "{case}");
    }
    let (_, _, after) = answer(&ecatd, "GET", sdo, &[]);
    assert_eq!(
        after["data"], kept["data"],
        "a refused write changed the entry"
    );
    // A register length out of range and SII data of an odd length name their field too.
    let (_, _, sii_before) = answer(&ecatd, "GET", "/api/v1/slaves/1/sii", &[]);
    for (method, path, extra, field) in [
        (
            "GET",
            "/api/v1/slaves/0/registers/0x0130?length=0",
            vec![],
            "length",
        ),
        (
            "PUT",
            "/api/v1/slaves/1/sii/8",
            with(r#"{"data":"aabbcc"}"#),
            "data",
        ),
    ] {
        let (status, _, answer) = answer(&ecatd, method, path, &extra);
        let case = format!("{method} {path}: {status} {answer}");
        assert_eq!(
            (status, answer["field"].as_str()),
            (400, Some(field)),
            "{case}"
        );
    }
    let (_, _, sii_after) = answer(&ecatd, "GET", "/api/v1/slaves/1/sii", &[]);
    assert_eq!(
        sii_after["data"], sii_before["data"],
        "a refused SII write changed it"
    );
    // Every refused state change changed nothing: the slave is still in OP.
    let (_, slave) = get(&ecatd, "/api/v1/slaves/0");
    assert_eq!(slave["state"], "OP", "{slave}");
    // Declared parameters still pass.
    let (status, _, body) = answer(
        &ecatd,
        "GET",
        "/api/v1/slaves/0/coe/sdo/0x1018/1?complete_access=false",
        &[],
    );
    assert_eq!(status, 200, "{body}");
}
