//! Issue 19, item 5, the audit trail: at `--log warn` every kind of write (REST PUT and
//! POST, gRPC unary writes, the gRPC FoE write stream, the mailbox gateway) still leaves
//! one JSON audit line with the caller, the operation, the target, the value's size and
//! SHA-256 prefix and the outcome (`done` or the error); `--audit-log FILE` sends them to a
//! file instead.
//!
//! Issue 35, item 4: a failed FoE transfer leaves a line at `info` naming who started it
//! (the token over REST and gRPC, the client's address through the gateway), and every
//! failed REST call, gRPC call and gateway request one at `debug`.

use crate::server_support;

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use master_core::wire::Emit;
use master_core::wire::foe::FoeRepr;
use master_core::wire::mailbox::MailboxType;
use serde_json::Value;
use server_support::gateway_client::GatewayClient;
use server_support::{b64, bin_dir, call, curl};
use sha2::{Digest, Sha256};

const WRITER: &str = "write-secret-for-the-audit-test";
const DEADLINE: Duration = Duration::from_secs(30);

/// ecatd at `--log warn`: the shared helper waits for an info line, so this one finds its
/// ports itself and waits on `/readyz`.
struct Quiet {
    child: Child,
    http: String,
    grpc: String,
    gateway: std::net::SocketAddr,
    stderr: Arc<Mutex<Vec<String>>>,
}

fn free_tcp() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn free_udp() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

impl Quiet {
    fn start(extra: &[&str]) -> Quiet {
        Quiet::start_at("warn", extra)
    }

    /// ecatd with `--log level`.
    fn start_at(level: &str, extra: &[&str]) -> Quiet {
        let config = std::env::temp_dir().join(format!(
            "ecatd-audit-{}-{:?}.toml",
            std::process::id(),
            std::thread::current().id()
        ));
        std::fs::write(
            &config,
            format!("[[tokens]]\nname = \"engineer\"\ntoken = \"{WRITER}\"\nrole = \"write\"\n"),
        )
        .unwrap();
        let (http, grpc, gateway) = (free_tcp(), free_tcp(), free_udp());
        let mut child = Command::new(bin_dir().join("ecatd"))
            .args(["--simulate", "--log", level, "--log-format", "json"])
            .args(["--config", config.to_str().unwrap()])
            .args(["--http-listen", &format!("127.0.0.1:{http}")])
            .args(["--grpc-listen", &format!("127.0.0.1:{grpc}")])
            .args(["--gateway-listen", &format!("127.0.0.1:{gateway}")])
            .args(extra)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("ecatd starts");
        let stderr = Arc::new(Mutex::new(Vec::new()));
        let keep = Arc::clone(&stderr);
        let pipe = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            for line in BufReader::new(pipe).lines().map_while(Result::ok) {
                keep.lock().unwrap().push(line);
            }
        });
        let quiet = Quiet {
            child,
            http: format!("http://127.0.0.1:{http}"),
            grpc: format!("127.0.0.1:{grpc}"),
            gateway: format!("127.0.0.1:{gateway}").parse().unwrap(),
            stderr,
        };
        let deadline = Instant::now() + DEADLINE;
        while curl(&["-s", &format!("{}/readyz", quiet.http)]).0 != 200 {
            assert!(
                Instant::now() < deadline,
                "ecatd not ready:\n{}",
                quiet.stderr.lock().unwrap().join("\n")
            );
            // Poll interval of the readiness check; the loop ends on it or the deadline.
            std::thread::sleep(Duration::from_millis(50));
        }
        std::fs::remove_file(config).unwrap();
        quiet
    }

    fn stderr(&self) -> Vec<Value> {
        parse(&self.stderr.lock().unwrap().join("\n"))
    }
}

impl Drop for Quiet {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn parse(text: &str) -> Vec<Value> {
    text.lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .collect()
}

/// Polls `lines` until one satisfies `found` or the deadline passes.
fn wait_for(lines: impl Fn() -> Vec<Value>, found: impl Fn(&Value) -> bool) -> Option<Value> {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        if let Some(v) = lines().into_iter().find(&found) {
            return Some(v);
        }
        if Instant::now() > deadline {
            return None;
        }
        // Poll interval of the log check; the loop ends on the condition or the deadline.
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn finished(v: &Value, operation: &str) -> bool {
    v["target"] == "audit"
        && v["fields"]["message"] == "write finished"
        && v["fields"]["operation"] == operation
}

/// A finished write's line made by the call `call` (`PUT /slaves/3/...`,
/// `/ecat.v1.CoeService/Download`).
fn finished_call(v: &Value, operation: &str, call: &str) -> bool {
    finished(v, operation) && v["fields"]["call"] == call
}

fn sha_prefix(data: &[u8]) -> String {
    Sha256::digest(data)[..8]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

const AUTH: &str = "authorization: Bearer write-secret-for-the-audit-test";

#[test]
fn every_write_kind_is_audited_with_its_outcome_at_log_warn() {
    let ecatd = Quiet::start(&[]);
    let lines = || ecatd.stderr();
    let rest_put = |path: &str, body: &str| {
        let url = format!("{}/api/v1{path}", ecatd.http);
        let args = [
            "-s",
            "-X",
            "PUT",
            "-H",
            AUTH,
            "-H",
            "content-type: application/json",
        ];
        let mut args = args.to_vec();
        args.extend(["-d", body, &url]);
        curl(&args)
    };
    // REST PUT, done: the core's line, named as gRPC's is, with the REST call beside it and
    // the size and digest of the bytes written.
    let body = r#"{"data":"01020304"}"#;
    assert_eq!(rest_put("/slaves/3/coe/sdo/0x2001/0", body).0, 200);
    let line = wait_for(lines, |v| {
        finished_call(v, "coe_download", "PUT /slaves/3/coe/sdo/0x2001/0")
            && v["fields"]["outcome"] == "done"
    })
    .unwrap_or_else(|| panic!("no REST audit line:\n{:#?}", lines()));
    assert_eq!(line["fields"]["caller"], "engineer");
    // The slave the path names, as gRPC's lines carry the request's slave.
    assert_eq!(line["fields"]["target"], "3");
    assert_eq!(line["fields"]["size"], 4);
    assert_eq!(line["fields"]["sha256"], sha_prefix(&[1, 2, 3, 4]));
    // REST PUT, failed: the error, by its stable tag.
    let (status, answer) = rest_put("/slaves/3/coe/sdo/0x7777/0", body);
    assert_eq!(status, 404, "{answer}");
    let line = wait_for(lines, |v| {
        finished_call(v, "coe_download", "PUT /slaves/3/coe/sdo/0x7777/0")
    })
    .unwrap_or_else(|| panic!("no audit line of the failed write:\n{:#?}", lines()));
    let outcome = line["fields"]["outcome"].as_str().unwrap();
    assert!(outcome.starts_with("error: sdo_abort: "), "{outcome}");

    // gRPC unary, done and failed.
    call(
        &ecatd.grpc,
        &[AUTH],
        "ecat.v1.CoeService/Download",
        r#"{"slave":"3","index":8193,"subindex":0,"data":"BQYHCA=="}"#,
    )
    .unwrap();
    let grpc = "/ecat.v1.CoeService/Download";
    let line = wait_for(lines, |v| {
        finished_call(v, "coe_download", grpc) && v["fields"]["outcome"] == "done"
    })
    .unwrap_or_else(|| panic!("no gRPC audit line:\n{:#?}", lines()));
    assert_eq!(line["fields"]["target"], "3");
    assert_eq!(line["fields"]["caller"], "engineer");
    // BQYHCA== is 05 06 07 08.
    assert_eq!(line["fields"]["size"], 4);
    assert_eq!(line["fields"]["sha256"], sha_prefix(&[5, 6, 7, 8]));
    let failed = call(
        &ecatd.grpc,
        &[AUTH],
        "ecat.v1.CoeService/Download",
        r#"{"slave":"3","index":30583,"subindex":0,"data":"BQYHCA=="}"#,
    )
    .unwrap_err();
    let line = wait_for(lines, |v| {
        finished_call(v, "coe_download", grpc)
            && v["fields"]["outcome"]
                .as_str()
                .is_some_and(|o| o.starts_with("error: "))
    })
    .unwrap_or_else(|| {
        panic!(
            "no audit line of the failed gRPC write ({failed:?}):\n{:#?}",
            lines()
        )
    });
    assert_eq!(line["fields"]["target"], "3");

    // gRPC FoE write: the real file name, the data's size and digest.
    let file = b"audited firmware".to_vec();
    call(
        &ecatd.grpc,
        &[AUTH],
        "ecat.v1.FoeService/Write",
        &format!(
            r#"{{"slave":"0","name":"audit.bin","password":0,"data":"{}"}}"#,
            b64::encode(&file)
        ),
    )
    .unwrap();
    let line = wait_for(lines, |v| {
        finished_call(v, "foe_write", "/ecat.v1.FoeService/Write")
    })
    .unwrap_or_else(|| panic!("no FoE audit line:\n{:#?}", lines()));
    assert_eq!(line["fields"]["target"], "0 audit.bin");
    assert_eq!(line["fields"]["outcome"], "done");
    assert_eq!(line["fields"]["size"], file.len());
    assert_eq!(line["fields"]["sha256"], sha_prefix(&file));

    // The mailbox gateway's own audit line reaches the same sink.
    let mut client = GatewayClient::new(ecatd.gateway);
    client
        .sdo_download(1001, 0x6040, 0, &[6, 0], 128)
        .expect("download through the gateway");
    let line = wait_for(lines, |v| {
        v["target"] == "audit" && v["fields"]["message"] == "gateway write"
    })
    .unwrap_or_else(|| panic!("no gateway audit line:\n{:#?}", lines()));
    assert_eq!(line["fields"]["object"], "0x6040:00");
    assert_eq!(line["fields"]["outcome"], "done");

    // REST POST (no body): done, without size or digest.
    let stop = format!("{}/api/v1/gateway/stop", ecatd.http);
    assert_eq!(curl(&["-s", "-X", "POST", "-H", AUTH, &stop]).0, 200);
    let line = wait_for(lines, |v| {
        finished_call(v, "stop_gateway", "POST /gateway/stop")
    })
    .unwrap_or_else(|| panic!("no POST audit line:\n{:#?}", lines()));
    assert_eq!(line["fields"]["outcome"], "done");
    assert!(line["fields"].get("sha256").is_none(), "{line}");

    // And the log level did hold the rest back.
    assert!(
        !lines()
            .iter()
            .any(|v| v["level"] == "INFO" && v["target"] != "audit"),
        "info lines at --log warn:\n{:#?}",
        lines()
    );
}

#[test]
fn audit_log_file_takes_the_lines() {
    let file = std::env::temp_dir().join(format!("ecatd-audit-{}.jsonl", std::process::id()));
    let _ = std::fs::remove_file(&file);
    let ecatd = Quiet::start(&["--audit-log", file.to_str().unwrap()]);
    let url = format!("{}/api/v1/slaves/3/coe/sdo/0x2001/0", ecatd.http);
    let (status, _) = curl(&[
        "-s",
        "-X",
        "PUT",
        "-H",
        AUTH,
        "-H",
        "content-type: application/json",
        "-d",
        r#"{"data":"0a0b0c0d"}"#,
        &url,
    ]);
    assert_eq!(status, 200);
    let in_file = || parse(&std::fs::read_to_string(&file).unwrap_or_default());
    let line = wait_for(in_file, |v| finished(v, "coe_download"))
        .unwrap_or_else(|| panic!("no audit line in the file"));
    assert_eq!(line["fields"]["outcome"], "done");
    assert!(
        !ecatd.stderr().iter().any(|v| v["target"] == "audit"),
        "audit lines on stderr too"
    );
    drop(ecatd);
    std::fs::remove_file(file).unwrap();
}

#[test]
fn a_failed_transfer_names_who_started_it_at_info_and_every_failed_call_is_at_debug() {
    // `debug` is ecatd's own crates' (the logging scope), so the level of each line shows.
    let ecatd = Quiet::start_at("debug", &[]);
    let lines = || ecatd.stderr();

    // REST: a read of a file the slave does not have.
    let url = format!("{}/api/v1/slaves/0/foe/missing-rest.bin", ecatd.http);
    let (status, _) = curl(&["-s", "-o", "/dev/null", "-H", AUTH, &url]);
    assert!(status >= 400, "{status}");
    // The path within the API, as the audit lines write it.
    let rest = "GET /slaves/0/foe/missing-rest.bin";
    let transfer = wait_for(lines, |v| {
        v["fields"]["message"] == "transfer failed" && v["fields"]["file"] == "missing-rest.bin"
    })
    .unwrap_or_else(|| panic!("no transfer line:\n{:#?}", lines()));
    assert_eq!(transfer["level"], "INFO");
    assert_eq!(transfer["fields"]["caller"], "engineer");
    assert_eq!(transfer["fields"]["operation"], rest);
    assert_eq!(transfer["fields"]["direction"], "read");
    assert_eq!(transfer["fields"]["slave"], "0");
    let failed = wait_for(lines, |v| {
        v["fields"]["message"] == "REST call failed" && v["fields"]["operation"] == rest
    })
    .unwrap_or_else(|| panic!("no REST failure line:\n{:#?}", lines()));
    assert_eq!(failed["level"], "DEBUG");
    assert_eq!(failed["fields"]["caller"], "engineer");
    assert_eq!(failed["fields"]["status"], status);
    assert!(
        failed["fields"]["error"]
            .as_str()
            .unwrap()
            .contains("\"reason\""),
        "the problem document: {failed}"
    );

    // gRPC: the same through the read stream (its transfer runs in a task of its own).
    let grpc = call(
        &ecatd.grpc,
        &[AUTH],
        "ecat.v1.FoeService/Read",
        r#"{"slave":"0","name":"missing-grpc.bin"}"#,
    );
    assert!(grpc.is_err(), "{grpc:?}");
    let transfer = wait_for(lines, |v| {
        v["fields"]["message"] == "transfer failed" && v["fields"]["file"] == "missing-grpc.bin"
    })
    .unwrap_or_else(|| panic!("no gRPC transfer line:\n{:#?}", lines()));
    assert_eq!(transfer["level"], "INFO");
    assert_eq!(transfer["fields"]["caller"], "engineer");
    assert_eq!(transfer["fields"]["operation"], "/ecat.v1.FoeService/Read");
    // A unary call that fails: its line at debug, with the caller.
    let upload = call(
        &ecatd.grpc,
        &[AUTH],
        "ecat.v1.CoeService/Upload",
        r#"{"slave":"3","index":30583,"subindex":0}"#,
    );
    assert!(upload.is_err(), "{upload:?}");
    let failed = wait_for(lines, |v| {
        v["fields"]["message"] == "gRPC call failed"
            && v["fields"]["operation"] == "/ecat.v1.CoeService/Upload"
    })
    .unwrap_or_else(|| panic!("no gRPC failure line:\n{:#?}", lines()));
    assert_eq!(failed["level"], "DEBUG");
    assert_eq!(failed["fields"]["caller"], "engineer");

    // The gateway: a file read that fails names the client at info; a failed SDO upload is
    // at debug.
    let mut client = GatewayClient::new(ecatd.gateway);
    let request = FoeRepr::ReadRequest {
        password: 0,
        file_name: b"missing-gateway.bin",
    }
    .to_vec()
    .unwrap();
    client.exchange(1001, MailboxType::Foe, &request);
    let client_address = client.socket.local_addr().unwrap().to_string();
    let transfer = wait_for(lines, |v| {
        v["fields"]["message"] == "gateway transfer failed"
            && v["fields"]["client"] == client_address.as_str()
    })
    .unwrap_or_else(|| panic!("no gateway transfer line:\n{:#?}", lines()));
    assert_eq!(transfer["level"], "INFO");
    assert!(
        transfer["fields"]["error"]
            .as_str()
            .unwrap()
            .starts_with("FoE error"),
        "{transfer}"
    );
    assert!(client.sdo_upload(1004, 0x7777, 0).is_err());
    let failed = wait_for(lines, |v| {
        v["fields"]["message"] == "gateway request failed" && v["fields"]["object"] == "0x7777:00"
    })
    .unwrap_or_else(|| panic!("no gateway failure line:\n{:#?}", lines()));
    assert_eq!(failed["level"], "DEBUG");
    assert_eq!(failed["fields"]["client"], client_address.as_str());
    // Nothing that succeeded is logged as failed.
    let all = lines();
    assert!(
        !all.iter()
            .any(|v| v["fields"]["message"] == "REST call failed"
                && v["fields"]["status"].as_u64().is_some_and(|s| s < 400)),
        "{all:#?}"
    );
}
