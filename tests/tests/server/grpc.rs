//! ecatd's gRPC API driven by grpcurl (the real client, from the venv): reflection lists
//! and describes the services, and every RPC answers with the simulator's values.

use crate::server_support;

use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

use serde_json::Value;
use server_support::gateway_client::GatewayClient;
use server_support::streaming::Streaming;
use server_support::{Ecatd, b64, call, call_status, grpcurl, grpcurl_path};
use sim::topology::{SIM_VENDOR_ID, Topology};

/// The simulator's test pattern for sized objects and files (byte i = i mod 251; the
/// topology model documents it, but does not export the function).
fn pattern(size: usize) -> Vec<u8> {
    (0..size).map(|i| (i % 251) as u8).collect()
}

fn bytes(v: &Value) -> Vec<u8> {
    b64::decode(v.as_str().unwrap_or(""))
}

#[test]
fn reflection_lists_and_describes_every_service() {
    let ecatd = Ecatd::start(&[]);
    let list = grpcurl(&[&ecatd.grpc, "list"]);
    for service in [
        "ecat.v1.BusService",
        "ecat.v1.CoeService",
        "ecat.v1.SoeService",
        "ecat.v1.FoeService",
        "ecat.v1.VoeService",
        "ecat.v1.EoeService",
        "ecat.v1.GatewayService",
        "ecat.v1.ProcessDataService",
        "grpc.health.v1.Health",
        "grpc.reflection.v1alpha.ServerReflection",
    ] {
        assert!(
            list.lines().any(|l| l == service),
            "{service} missing from:\n{list}"
        );
    }
    let described = grpcurl(&[&ecatd.grpc, "describe", "ecat.v1.CoeService"]);
    for rpc in [
        "Upload",
        "Download",
        "ObjectList",
        "ObjectDescription",
        "EntryDescription",
    ] {
        assert!(
            described.contains(&format!("rpc {rpc} (")),
            "{rpc} not described:\n{described}"
        );
    }
    let message = grpcurl(&[&ecatd.grpc, "describe", "ecat.v1.Slave"]);
    assert!(message.contains("al_status_code"), "{message}");
    let health = call(&ecatd.grpc, &[], "grpc.health.v1.Health/Check", "{}").unwrap();
    assert_eq!(health["status"], "SERVING");
}

#[test]
fn bus_calls_match_the_topology() {
    let ecatd = Ecatd::start(&[]);
    let topology = Topology::default_segment();
    let list = call(&ecatd.grpc, &[], "ecat.v1.BusService/ListSlaves", "{}").unwrap();
    let slaves = list["slaves"].as_array().unwrap();
    assert_eq!(slaves.len(), topology.slaves.len());
    for (slave, spec) in slaves.iter().zip(&topology.slaves) {
        assert_eq!(slave["name"], spec.name.as_str());
        assert_eq!(slave["identity"]["vendorId"], spec.vendor_id);
        assert_eq!(slave["identity"]["productCode"], spec.product_code);
        assert_eq!(slave["state"], "AL_STATE_OP");
    }
    // One name syntax: position, station, and station in hex name the same slave.
    for name in ["3", "#1004", "#0x3ec"] {
        let slave = call(
            &ecatd.grpc,
            &[],
            "ecat.v1.BusService/GetSlave",
            &format!(r#"{{"slave":"{name}"}}"#),
        )
        .unwrap();
        assert_eq!(slave["name"], topology.slaves[3].name.as_str(), "{name}");
    }
    let missing = call(
        &ecatd.grpc,
        &[],
        "ecat.v1.BusService/GetSlave",
        r#"{"slave":"@0x777"}"#,
    )
    .unwrap_err();
    assert_eq!(missing.0, "5", "NOT_FOUND: {missing:?}");
    let bad = call(
        &ecatd.grpc,
        &[],
        "ecat.v1.BusService/GetSlave",
        r#"{"slave":"x"}"#,
    )
    .unwrap_err();
    assert_eq!(bad.0, "3", "INVALID_ARGUMENT: {bad:?}");

    let state = call(
        &ecatd.grpc,
        &[],
        "ecat.v1.BusService/RequestState",
        r#"{"slave":"1","state":"AL_STATE_PREOP"}"#,
    )
    .unwrap();
    assert_eq!(state["slave"]["state"], "AL_STATE_PREOP");
    let status = call(
        &ecatd.grpc,
        &[],
        "ecat.v1.BusService/ReadRegister",
        r#"{"slave":"1","address":304,"length":2}"#,
    )
    .unwrap();
    assert_eq!(
        bytes(&status["data"])[0] & 0x0f,
        0x2,
        "AL status register says PREOP"
    );

    // Registers: the station address register 0x0010 holds 1001 + position.
    let reg = call(
        &ecatd.grpc,
        &[],
        "ecat.v1.BusService/ReadRegister",
        r#"{"slave":"2","address":16,"length":2}"#,
    )
    .unwrap();
    assert_eq!(bytes(&reg["data"]), 1003u16.to_le_bytes());
    call(
        &ecatd.grpc,
        &[],
        "ecat.v1.BusService/WriteRegister",
        &format!(
            r#"{{"slave":"2","address":2560,"data":"{}"}}"#,
            b64::encode(&[0xa5, 0x5a])
        ),
    )
    .unwrap();

    // SII: word 8-9 is the vendor id.
    let sii = bytes(
        &call(
            &ecatd.grpc,
            &[],
            "ecat.v1.BusService/ReadSii",
            r#"{"slave":"0"}"#,
        )
        .unwrap()["data"],
    );
    assert_eq!(sii[16..20], SIM_VENDOR_ID.to_le_bytes());
    let alias = call(
        &ecatd.grpc,
        &[],
        "ecat.v1.BusService/SetAlias",
        r#"{"slave":"4","alias":1911}"#,
    )
    .unwrap();
    assert_eq!(alias["alias"], 1911);
    let by_alias = call(
        &ecatd.grpc,
        &[],
        "ecat.v1.BusService/GetSlave",
        r#"{"slave":"@0x777"}"#,
    )
    .unwrap();
    assert_eq!(by_alias["name"], topology.slaves[4].name.as_str());
    let rescan = call(&ecatd.grpc, &[], "ecat.v1.BusService/Rescan", "{}").unwrap();
    assert_eq!(
        rescan["slaves"].as_array().unwrap().len(),
        topology.slaves.len()
    );
}

#[test]
fn mailbox_calls_match_the_simulator() {
    let ecatd = Ecatd::start(&[]);
    let g = ecatd.grpc.as_str();
    let upload = call(
        g,
        &[],
        "ecat.v1.CoeService/Upload",
        r#"{"slave":"0","index":4120,"subindex":1}"#,
    )
    .unwrap();
    assert_eq!(bytes(&upload["data"]), SIM_VENDOR_ID.to_le_bytes());
    let typed = call(
        g,
        &[],
        "ecat.v1.CoeService/Upload",
        r#"{"slave":"0","index":4120,"subindex":1,"valueType":"auto"}"#,
    )
    .unwrap();
    assert_eq!(typed["value"], SIM_VENDOR_ID.to_string());
    let topology = Topology::default_segment();
    let store = topology.slaves[3]
        .objects
        .iter()
        .find(|o| o.index == 0x2000)
        .unwrap();
    let large = call(
        g,
        &[],
        "ecat.v1.CoeService/Upload",
        r#"{"slave":"3","index":8192,"subindex":0}"#,
    )
    .unwrap();
    assert_eq!(bytes(&large["data"]), pattern(store.size.unwrap()));
    // 0x2001 "Parameter" on the CoE store is a plain read-write u32 (not process data).
    let value = b64::encode(&0xcafe_babeu32.to_le_bytes());
    call(
        g,
        &[],
        "ecat.v1.CoeService/Download",
        &format!(r#"{{"slave":"3","index":8193,"subindex":0,"data":"{value}"}}"#),
    )
    .unwrap();
    let back = call(
        g,
        &[],
        "ecat.v1.CoeService/Upload",
        r#"{"slave":"3","index":8193,"subindex":0}"#,
    )
    .unwrap();
    assert_eq!(bytes(&back["data"]), 0xcafe_babeu32.to_le_bytes());
    let abort = call(
        g,
        &[],
        "ecat.v1.CoeService/Upload",
        r#"{"slave":"0","index":24576,"subindex":1}"#,
    )
    .unwrap_err();
    assert_eq!(abort.0, "5", "NOT_FOUND: {abort:?}");
    assert!(
        abort.1.contains("0x06020000"),
        "the abort code is in the message: {abort:?}"
    );
    // The details: a google.rpc.ErrorInfo grpcurl decodes through reflection.
    let status = call_status(
        g,
        &[],
        "ecat.v1.CoeService/Upload",
        r#"{"slave":"0","index":24576,"subindex":1}"#,
    )
    .unwrap_err();
    let info = &status["details"][0];
    assert_eq!(
        info["@type"], "type.googleapis.com/google.rpc.ErrorInfo",
        "{status}"
    );
    assert_eq!(info["reason"], "SDO_ABORT");
    assert_eq!(info["domain"], "ecat.v1");
    assert_eq!(
        info["metadata"]["code"], "0x06020000",
        "0x%08X, as IgH prints it"
    );
    assert_eq!(
        info["metadata"]["code_text"],
        "Object does not exist in the object dictionary"
    );

    let list = call(g, &[], "ecat.v1.CoeService/ObjectList", r#"{"slave":"0"}"#).unwrap();
    let indices: Vec<u64> = list["indices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    for index in [0x1018, 0x6040, 0x6041, 0x607a, 0x6064] {
        assert!(
            indices.contains(&index),
            "{index:#x} missing from {indices:x?}"
        );
    }
    let object = call(
        g,
        &[],
        "ecat.v1.CoeService/ObjectDescription",
        r#"{"slave":"0","index":24640}"#,
    )
    .unwrap();
    assert_eq!(object["name"], "Controlword");
    let entry = call(
        g,
        &[],
        "ecat.v1.CoeService/EntryDescription",
        r#"{"slave":"0","index":24640,"subindex":0}"#,
    )
    .unwrap();
    assert_eq!(entry["bitLength"], 16);

    // SoE: P-0-0100 motor temperature is 253 (0.1 degC steps).
    let soe = call(
        g,
        &[],
        "ecat.v1.SoeService/Read",
        r#"{"slave":"0","idn":32868}"#,
    )
    .unwrap();
    assert_eq!(bytes(&soe["data"]), 253u16.to_le_bytes());
    let refused = call(
        g,
        &[],
        "ecat.v1.SoeService/Write",
        &format!(
            r#"{{"slave":"0","idn":32868,"data":"{}"}}"#,
            b64::encode(&[1, 0])
        ),
    )
    .unwrap_err();
    assert_eq!(
        refused.0, "9",
        "a read-only IDN is FAILED_PRECONDITION: {refused:?}"
    );

    // FoE: the drive's firmware.bin is the test pattern of 1024 bytes.
    let chunks = grpcurl(&[
        "-d",
        r#"{"slave":"0","name":"firmware.bin"}"#,
        g,
        "ecat.v1.FoeService/Read",
    ]);
    let mut file = Vec::new();
    let decoder = serde_json::Deserializer::from_str(&chunks).into_iter::<Value>();
    for chunk in decoder {
        file.extend(bytes(&chunk.unwrap()["data"]));
    }
    assert_eq!(file, pattern(topology.slaves[0].foe_files[0].size));
    let missing = call(
        g,
        &[],
        "ecat.v1.FoeService/Read",
        r#"{"slave":"0","name":"nope.bin"}"#,
    )
    .unwrap_err();
    assert_eq!(missing.0, "5", "a missing file is NOT_FOUND: {missing:?}");

    // VoE echo inverts every byte.
    let voe = call(
        g,
        &[],
        "ecat.v1.VoeService/Transfer",
        &format!(
            r#"{{"slave":"0","vendorId":4452,"vendorType":1,"data":"{}"}}"#,
            b64::encode(&[0x00, 0x0f, 0xf0])
        ),
    )
    .unwrap();
    assert_eq!(bytes(&voe["data"]), [0xff, 0xf0, 0x0f]);

    // EoE: set an IP and read it back.
    call(
        g,
        &[],
        "ecat.v1.EoeService/SetIp",
        r#"{"slave":"4","settings":{"ip":"192.168.100.44","subnetMask":"255.255.255.0"}}"#,
    )
    .unwrap();
    let ip = call(g, &[], "ecat.v1.EoeService/GetIp", r#"{"slave":"4"}"#).unwrap();
    assert_eq!(ip["ip"], "192.168.100.44");
    let unsupported = call(g, &[], "ecat.v1.EoeService/GetIp", r#"{"slave":"3"}"#).unwrap_err();
    assert_eq!(
        unsupported.0, "9",
        "FAILED_PRECONDITION for a slave without EoE: {unsupported:?}"
    );
}

/// A uint64 field as grpcurl prints it (a string; absent when 0).
fn u64_field(v: &Value) -> u64 {
    match v {
        Value::Null => 0,
        Value::String(s) => s.parse().expect("a uint64 string"),
        other => other.as_u64().expect("a number"),
    }
}

#[test]
fn gateway_service_reports_stops_and_starts_the_gateway() {
    let ecatd = Ecatd::start(&[]);
    let g = &ecatd.grpc;
    let bound = ecatd.gateway_addr();
    let status = call(g, &[], "ecat.v1.GatewayService/GetGateway", "{}").unwrap();
    assert_eq!(status["enabled"], true);
    assert_eq!(status["running"], true);
    assert_eq!(status["boundAddress"], bound.to_string());
    assert_eq!(status["port"], bound.port());
    assert_eq!(status["configuredAddress"], "127.0.0.1:0");
    assert_eq!(status["masterNumber"], 1);
    assert_eq!(
        status["allow"],
        serde_json::json!(["127.0.0.0/8 write", "::1/128 write"])
    );
    assert!(status["strict"].is_null(), "not strict: {status}");
    assert_eq!(status["stats"]["port"], bound.port());

    // Three uploads of the CoE store's vendor ID through the gateway, then the counters.
    let vendor = Topology::default_segment().slaves[3].vendor_id;
    let mut client = GatewayClient::new(bound);
    for _ in 0..3 {
        assert_eq!(
            client.sdo_upload(1004, 0x1018, 1),
            Ok(vendor.to_le_bytes().to_vec())
        );
    }
    let stats = &call(g, &[], "ecat.v1.GatewayService/GetGateway", "{}").unwrap()["stats"];
    assert_eq!(u64_field(&stats["totalRequests"]), 3, "{stats}");
    assert_eq!(u64_field(&stats["forwardedRequests"]), 3);
    assert_eq!(u64_field(&stats["failedRequests"]), 0);
    assert_eq!(u64_field(&stats["coeCount"]), 3);
    assert_eq!(u64_field(&stats["soeCount"]), 0);
    assert_eq!(u64_field(&stats["latency"]["count"]), 3);
    assert!(u64_field(&stats["latency"]["p50Us"]) > 0, "{stats}");
    assert!(u64_field(&stats["startedAtMs"]) > 0);

    let stopped = call(g, &[], "ecat.v1.GatewayService/StopGateway", "{}").unwrap();
    assert!(stopped["running"].is_null(), "stopped: {stopped}");
    assert!(stopped["boundAddress"].is_null(), "{stopped}");
    assert_eq!(u64_field(&stopped["stats"]["startedAtMs"]), 0);
    assert_eq!(
        u64_field(&stopped["stats"]["totalRequests"]),
        3,
        "counters stay readable"
    );

    let started = call(g, &[], "ecat.v1.GatewayService/StartGateway", "{}").unwrap();
    assert_eq!(started["running"], true);
    let port = started["port"].as_u64().expect("a port") as u16;
    assert_eq!(
        started["boundAddress"],
        format!("127.0.0.1:{port}"),
        "{started}"
    );
    assert_eq!(
        u64_field(&started["stats"]["totalRequests"]),
        0,
        "counters restart"
    );
    let mut client = GatewayClient::new(std::net::SocketAddr::from(([127, 0, 0, 1], port)));
    assert_eq!(
        client.sdo_upload(1004, 0x1018, 1),
        Ok(vendor.to_le_bytes().to_vec())
    );
}

#[test]
fn domains_register_read_write_and_the_log_filter_agree_across_both_apis() {
    let ecatd = Ecatd::start(&[]);
    let g = &ecatd.grpc;
    let rest = |args: &[&str]| server_support::curl(args);

    // ListDomains and GET /domains: the same layout.
    let grpc = call(g, &[], "ecat.v1.BusService/ListDomains", "{}").unwrap();
    let (status, body) = rest(&["-s", &format!("{}/api/v1/domains", ecatd.http)]);
    assert_eq!(status, 200, "{body}");
    let http: Value = serde_json::from_str(&body).unwrap();
    let domain = &grpc["domains"][0];
    assert_eq!(domain["size"], http[0]["size"]);
    assert_eq!(domain["expectedWkc"], http[0]["expected_wkc"]);
    assert_eq!(
        domain["entries"].as_array().unwrap().len(),
        http[0]["entries"].as_array().unwrap().len()
    );
    assert_eq!(
        bytes(&domain["data"]).len() as u64,
        http[0]["size"].as_u64().unwrap()
    );

    // ReadWriteRegister (gRPC) then POST .../rdwr: each returns the other's write.
    let first = call(
        g,
        &[],
        "ecat.v1.BusService/ReadWriteRegister",
        &format!(
            r#"{{"slave":"2","address":3856,"data":"{}"}}"#,
            b64::encode(&[0xAB, 0xCD])
        ),
    )
    .unwrap();
    assert_eq!(bytes(&first["data"]), [0, 0]);
    let (status, body) = rest(&[
        "-s",
        "-X",
        "POST",
        "-H",
        "Content-Type: application/json",
        "-d",
        r#"{"data":"0102"}"#,
        &format!("{}/api/v1/slaves/2/registers/0x0f10/rdwr", ecatd.http),
    ]);
    assert_eq!(status, 200, "{body}");
    assert_eq!(
        serde_json::from_str::<Value>(&body).unwrap()["data"],
        "abcd"
    );
    // Empty data is a bad request and writes nothing.
    let status = call_status(
        g,
        &[],
        "ecat.v1.BusService/ReadWriteRegister",
        r#"{"slave":"2","address":3856}"#,
    )
    .unwrap_err();
    assert_eq!(status["code"], 3, "{status}");
    let read = call(
        g,
        &[],
        "ecat.v1.BusService/ReadRegister",
        r#"{"slave":"2","address":3856,"length":2}"#,
    )
    .unwrap();
    assert_eq!(bytes(&read["data"]), [1, 2]);

    // The log filter: set through one API, read through the other; a bad one refused.
    let set = call(
        g,
        &[],
        "ecat.v1.BusService/SetLogFilter",
        r#"{"filter":"warn,server=debug"}"#,
    )
    .unwrap();
    assert_eq!(set["filter"], "warn,server=debug");
    let (status, body) = rest(&["-s", &format!("{}/api/v1/log-filter", ecatd.http)]);
    assert_eq!(
        (status, body.contains("warn,server=debug")),
        (200, true),
        "{body}"
    );
    let (status, body) = rest(&[
        "-s",
        "-X",
        "PUT",
        "-H",
        "Content-Type: application/json",
        "-d",
        r#"{"filter":"info,[[bad"}"#,
        &format!("{}/api/v1/log-filter", ecatd.http),
    ]);
    assert_eq!(status, 400, "{body}");
    let get = call(g, &[], "ecat.v1.BusService/GetLogFilter", "{}").unwrap();
    assert_eq!(get["filter"], "warn,server=debug", "unchanged");
}

/// How long a process-data value may take to show what a test waits for.
const PD_PATIENCE: Duration = Duration::from_secs(30);

/// ecatd with the application interface (a force needs it) on a socket of the test's own,
/// so that tests running side by side do not share the default one, and the configuration
/// `config` (TOML). Returns ecatd and the socket.
fn ecatd_with_app(name: &str, config: &str) -> (Ecatd, PathBuf) {
    let dir = std::env::temp_dir().join(format!("ecatd-grpc-pd-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("the test's directory");
    let socket = dir.join("app.sock");
    let file = dir.join("ecatd.toml");
    std::fs::write(&file, config).expect("the configuration");
    let ecatd = Ecatd::start(&[
        "--app-socket",
        socket.to_str().expect("UTF-8 path"),
        "--config",
        file.to_str().expect("UTF-8 path"),
    ]);
    (ecatd, socket)
}

/// Calls `ProcessDataService/<method>`.
fn pd_call(ecatd: &Ecatd, method: &str, body: &str) -> Result<Value, Value> {
    call_status(
        &ecatd.grpc,
        &[],
        &format!("ecat.v1.ProcessDataService/{method}"),
        body,
    )
}

/// A number of grpcurl's JSON: 64-bit integers come as strings, and proto3 leaves out
/// zeros.
fn n(v: &Value) -> u64 {
    v.as_u64()
        .or_else(|| v.as_str().and_then(|s| s.parse().ok()))
        .unwrap_or(0)
}

/// Whether a `PdEntry` is `index:subindex` of `slave`.
fn is_entry(e: &Value, slave: u64, index: u64, subindex: u64) -> bool {
    n(&e["slave"]) == slave && n(&e["index"]) == index && n(&e["subindex"]) == subindex
}

/// The entry and value of `index:subindex` of `slave` in the last cycle, through `Read`.
fn pd_value(ecatd: &Ecatd, slave: u64, index: u64, subindex: u64) -> Value {
    let read = pd_call(ecatd, "Read", &format!(r#"{{"slave":"{slave}"}}"#)).expect("Read");
    read["entries"]
        .as_array()
        .expect("entries")
        .iter()
        .find(|v| is_entry(&v["entry"], slave, index, subindex))
        .unwrap_or_else(|| panic!("no {index:#x}:{subindex} of slave {slave} in {read}"))
        .clone()
}

/// Polls `index:subindex` of `slave` until `wanted` holds for its value (a `PdValue`).
fn wait_pd(
    ecatd: &Ecatd,
    slave: u64,
    index: u64,
    subindex: u64,
    wanted: impl Fn(&Value) -> bool,
) -> Value {
    let deadline = Instant::now() + PD_PATIENCE;
    loop {
        let shown = pd_value(ecatd, slave, index, subindex);
        if wanted(&shown["value"]) {
            return shown;
        }
        assert!(
            Instant::now() < deadline,
            "{index:#x}:{subindex} of slave {slave} stays {shown}"
        );
        // Poll interval of the value check; the loop ends on the value or the deadline.
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Forces `index:subindex` of `slave` to `value` (a `ForceRequest` value field).
fn force(ecatd: &Ecatd, slave: u64, index: u64, subindex: u64, value: &str) -> Value {
    pd_call(
        ecatd,
        "Force",
        &format!(r#"{{"slave":"{slave}","index":{index},"subindex":{subindex},{value}}}"#),
    )
    .unwrap_or_else(|status| panic!("force {index:#x}:{subindex} of slave {slave}: {status}"))
}

/// The messages a streaming grpcurl printed so far (pretty JSON, one value per message).
fn messages(text: &str) -> Vec<Value> {
    serde_json::Deserializer::from_str(text)
        .into_iter::<Value>()
        .map_while(Result::ok)
        .collect()
}

#[test]
fn process_data_drives_the_drive_mirrors_the_do8_and_streams_the_change_over_grpc() {
    let (ecatd, _socket) = ecatd_with_app("drive", "[app]\nwatchdog = 1000\n");

    // The layout: the entries a control program attaches to, and each slave's PDOs.
    let layout = pd_call(&ecatd, "GetLayout", "{}").unwrap();
    assert_eq!(layout["generation"], 1, "{layout}");
    assert_eq!(n(&layout["periodNs"]), 1_000_000);
    let entries = layout["entries"].as_array().unwrap();
    let control = entries
        .iter()
        .find(|e| is_entry(e, 0, 0x6040, 0))
        .unwrap_or_else(|| panic!("no controlword in {layout}"));
    assert_eq!(control["name"], "Controlword");
    assert_eq!(control["dataType"], "UNSIGNED16");
    assert_eq!(control["bitLength"], 16);
    assert_eq!(control["direction"], "PD_DIRECTION_OUT");
    let status = entries.iter().find(|e| is_entry(e, 0, 0x6041, 0)).unwrap();
    assert_eq!(status["direction"], "PD_DIRECTION_IN");
    let drive = &layout["slaves"][0];
    assert_eq!(n(&drive["slave"]), 0);
    let sm2 = drive["syncManagers"]
        .as_array()
        .unwrap()
        .iter()
        .find(|sm| n(&sm["index"]) == 2)
        .unwrap_or_else(|| panic!("no SM2 in {drive}"));
    assert_eq!(n(&sm2["controlRegister"]), 0x64, "{sm2}");
    assert_eq!(n(&sm2["pdos"][0]["index"]), 0x1600);
    assert_eq!(sm2["pdos"][0]["name"], "Outputs");
    assert_eq!(sm2["pdos"][0]["entries"][0]["name"], "Controlword");
    assert_eq!(n(&sm2["pdos"][0]["entries"][0]["bitLength"]), 16);
    let di8 = pd_call(&ecatd, "GetLayout", r#"{"slave":"2"}"#).unwrap();
    assert_eq!(di8["entries"].as_array().unwrap().len(), 8, "{di8}");
    assert!(
        di8["entries"]
            .as_array()
            .unwrap()
            .iter()
            .all(|e| n(&e["slave"]) == 2 && e["direction"] == "PD_DIRECTION_IN"),
        "{di8}"
    );
    assert_eq!(di8["slaves"].as_array().unwrap().len(), 1);

    // The drive through its state machine by the controlword alone (CiA 402: shutdown,
    // switch on, enable operation), the statusword read back each time.
    for (command, state) in [(6u64, 0x21u64), (7, 0x23), (15, 0x27)] {
        let forced = force(&ecatd, 0, 0x6040, 0, &format!(r#""int_value":{command}"#));
        assert_eq!(
            n(&forced["force"]["value"]["uintValue"]),
            command,
            "{forced}"
        );
        assert_eq!(forced["force"]["forcedBy"], "anonymous");
        wait_pd(&ecatd, 0, 0x6041, 0, |v| n(&v["uintValue"]) & 0x6F == state);
    }
    let shown = pd_value(&ecatd, 0, 0x6040, 0);
    assert_eq!(n(&shown["value"]["uintValue"]), 15, "{shown}");
    assert_eq!(shown["forcedBy"], "anonymous");
    assert_eq!(b64::decode(shown["raw"].as_str().unwrap()), [15, 0]);

    // The DO8's first channel, read back on the DI8 the simulator wires it to.
    let forced = force(&ecatd, 1, 0x7000, 1, r#""bool_value":true"#);
    assert_eq!(forced["force"]["value"]["boolValue"], true, "{forced}");
    wait_pd(&ecatd, 2, 0x6000, 1, |v| v["boolValue"] == true);
    let listed = pd_call(&ecatd, "ListForced", "{}").unwrap();
    let forced = listed["forced"].as_array().unwrap();
    assert_eq!(forced.len(), 2, "{listed}");
    assert!(forced.iter().any(|f| is_entry(&f["entry"], 1, 0x7000, 1)));

    // Watch: every entry of the DI8 first; then, once an output changes, the input it is
    // wired to, alone, in the next message: the first interval that saw the change.
    let mut watch = Command::new(grpcurl_path());
    watch.args([
        "-plaintext",
        "-d",
        r#"{"slave":"2","interval_ms":50}"#,
        &ecatd.grpc,
        "ecat.v1.ProcessDataService/Watch",
    ]);
    let stream = Streaming::start(&mut watch);
    let first = stream.wait_for("the first message", |text| messages(text).first().cloned());
    let all = first["entries"].as_array().unwrap();
    assert_eq!(all.len(), 8, "every entry first: {first}");
    assert!(
        all.iter()
            .any(|v| is_entry(&v["entry"], 2, 0x6000, 1) && v["value"]["boolValue"] == true)
    );
    force(&ecatd, 1, 0x7000, 2, r#""int_value":1"#);
    let changed = stream.wait_for("the changed input", |text| messages(text).get(1).cloned());
    let only = changed["entries"].as_array().unwrap();
    assert_eq!(only.len(), 1, "only the change: {changed}");
    assert!(is_entry(&only[0]["entry"], 2, 0x6000, 2), "{changed}");
    assert_eq!(only[0]["value"]["boolValue"], true);
    assert!(n(&changed["cycle"]) > n(&first["cycle"]));
    drop(stream);

    // Release: once, then it is not forced any more.
    pd_call(
        &ecatd,
        "ReleaseForce",
        r#"{"slave":"1","index":28672,"subindex":1}"#,
    )
    .unwrap();
    let again = pd_call(
        &ecatd,
        "ReleaseForce",
        r#"{"slave":"1","index":28672,"subindex":1}"#,
    )
    .unwrap_err();
    assert_eq!(again["code"], 5, "NOT_FOUND: {again}");
    assert!(
        again["message"].as_str().unwrap().contains("is not forced"),
        "{again}"
    );
    let listed = pd_call(&ecatd, "ListForced", "{}").unwrap();
    assert!(
        !listed["forced"]
            .as_array()
            .unwrap()
            .iter()
            .any(|f| is_entry(&f["entry"], 1, 0x7000, 1)),
        "{listed}"
    );
    assert_eq!(pd_value(&ecatd, 1, 0x7000, 1)["forcedBy"], Value::Null);
    let audit = ecatd.log();
    assert!(
        audit.contains("force_output") && audit.contains("release_output"),
        "the audit trail names each force:\n{audit}"
    );
}

/// The field a failed call's `google.rpc.BadRequest` names.
fn bad_field(status: &Value) -> String {
    status["details"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|d| d["fieldViolations"][0]["field"].as_str())
        .next()
        .unwrap_or_default()
        .to_owned()
}

#[test]
fn process_data_refuses_bad_requests_and_forces_over_an_owner_only_with_override_over_grpc() {
    // A 20 ms cycle, so that an interval above the 10 ms floor can still be below the cycle.
    let (mut ecatd, socket) = ecatd_with_app(
        "refused",
        "[app]\nwatchdog = 1000\n[bus]\ncycle = \"20ms\"\n",
    );
    let cases: [(&str, &str, u64, &str, &str); 8] = [
        (
            "Force",
            r#"{"slave":"1","index":28672,"subindex":9,"int_value":1}"#,
            5,
            "",
            "0x7000:09",
        ),
        (
            "Force",
            r#"{"slave":"2","index":24576,"subindex":1,"int_value":1}"#,
            3,
            "index",
            "is an input",
        ),
        (
            "Force",
            r#"{"slave":"0","index":24640,"subindex":0,"int_value":70000}"#,
            3,
            "value",
            "does not fit",
        ),
        (
            "Force",
            r#"{"slave":"1","index":28672,"subindex":1}"#,
            3,
            "value",
            "a value is needed",
        ),
        (
            "Force",
            r#"{"slave":"1","index":70000,"subindex":1,"int_value":1}"#,
            3,
            "index",
            "out of range",
        ),
        ("Read", r#"{"slave":"9"}"#, 5, "", ""),
        (
            "Watch",
            r#"{"interval_ms":15}"#,
            3,
            "interval",
            "interval 15ms is below the cycle (20ms) or 10ms",
        ),
        (
            "Watch",
            r#"{"interval_ms":5}"#,
            3,
            "interval",
            "below the cycle",
        ),
    ];
    for (method, body, code, field, text) in cases {
        let status = pd_call(&ecatd, method, body).unwrap_err();
        assert_eq!(n(&status["code"]), code, "{method} {body}: {status}");
        assert_eq!(bad_field(&status), field, "{method} {body}: {status}");
        assert!(
            status["message"].as_str().unwrap().contains(text),
            "{method} {body}: {status}"
        );
    }
    assert_eq!(
        pd_call(&ecatd, "ListForced", "{}").unwrap(),
        serde_json::json!({}),
        "nothing was forced"
    );

    // A control program owns the outputs (the DO8 at 0x01): a force is refused...
    let mut hold = Command::new(env!("CARGO_BIN_EXE_app_program"));
    hold.arg(&socket).arg("hold");
    let owner = Streaming::start(&mut hold);
    owner.wait_for_line(r#"{"claimed": true}"#);
    ecatd.wait_sim_outputs(1, &[0x01], PD_PATIENCE);
    let refused = pd_call(
        &ecatd,
        "Force",
        r#"{"slave":"1","index":28672,"subindex":2,"int_value":1}"#,
    )
    .unwrap_err();
    assert_eq!(refused["code"], 9, "FAILED_PRECONDITION: {refused}");
    assert_eq!(
        refused["details"][0]["reason"], "OUTPUTS_OWNED",
        "{refused}"
    );
    assert!(
        refused["message"]
            .as_str()
            .unwrap()
            .contains("owns the outputs"),
        "{refused}"
    );
    assert_eq!(
        pd_call(&ecatd, "ListForced", "{}").unwrap(),
        serde_json::json!({})
    );
    // ...unless it says override: the owner's channel 1 and the forced channel 2 together.
    let forced = force(&ecatd, 1, 0x7000, 2, r#""int_value":1,"override":true"#);
    assert_eq!(forced["force"]["override"], true, "{forced}");
    ecatd.wait_sim_outputs(1, &[0x03], PD_PATIENCE);
    // The audit line says the force went over the owner.
    ecatd.wait_log(r#""target":"slave 1 0x7000:02 over_owner","outcome":"done""#);
    drop(owner);
}

/// Issue 35: a request body that does not parse as the method's message is the caller's
/// fault, INVALID_ARGUMENT (prost's codec alone says INTERNAL), and changes nothing.
#[test]
fn a_request_that_does_not_parse_is_an_invalid_argument() {
    let ecatd = Ecatd::start(&[]);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let status = runtime.block_on(async {
        let channel = tonic::transport::Channel::from_shared(format!("http://{}", ecatd.grpc))
            .unwrap()
            .connect()
            .await
            .expect("connects");
        let mut grpc = tonic::client::Grpc::new(channel);
        grpc.ready().await.expect("ready");
        // `Domain` has a varint at field 1 where `GetSlaveRequest` has a string: the bytes
        // are valid protobuf of the wrong shape.
        let wrong = proto::v1::Domain {
            index: 7,
            ..Default::default()
        };
        let codec = tonic_prost::ProstCodec::<proto::v1::Domain, proto::v1::Slave>::default();
        grpc.unary(
            tonic::Request::new(wrong),
            tonic::codegen::http::uri::PathAndQuery::from_static("/ecat.v1.BusService/GetSlave"),
            codec,
        )
        .await
        .expect_err("a malformed request is refused")
    });
    assert_eq!(status.code(), tonic::Code::InvalidArgument, "{status:?}");
    assert!(
        status.message().contains("GetSlaveRequest"),
        "{}",
        status.message()
    );
    // The server goes on answering.
    let list = call(&ecatd.grpc, &[], "ecat.v1.BusService/ListSlaves", "{}").unwrap();
    assert!(!list["slaves"].as_array().unwrap().is_empty());
}

/// proto3's JSON leaves zero values out (the first slave has no `position`); grpcurl's
/// `-emit-defaults`, as docs/call-it.md says, prints them.
#[test]
fn grpcurl_shows_position_zero_with_emit_defaults() {
    let ecatd = Ecatd::start(&[]);
    let first = |text: &str| -> Value {
        let v: Value = serde_json::from_str(text).unwrap();
        v["slaves"][0].clone()
    };
    let plain = first(&grpcurl(&[&ecatd.grpc, "ecat.v1.BusService/ListSlaves"]));
    assert_eq!(plain.get("position"), None, "proto3 JSON omits 0: {plain}");
    let full = first(&grpcurl(&[
        "-emit-defaults",
        &ecatd.grpc,
        "ecat.v1.BusService/ListSlaves",
    ]));
    assert_eq!(full["position"], 0, "{full}");
    assert_eq!(full["station"], plain["station"]);
}
