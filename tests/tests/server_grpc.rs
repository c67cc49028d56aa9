//! ecatd's gRPC API driven by grpcurl (the real client, from the venv): reflection lists
//! and describes the services, and every RPC answers with the simulator's values.

mod server_support;

use serde_json::Value;
use server_support::gateway_client::GatewayClient;
use server_support::{Ecatd, b64, call, call_status, grpcurl};
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
    assert_eq!(info["metadata"]["code"], "0x6020000");
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
