//! Mailbox failures as a user of ecatd meets them, against a simulated slave whose firmware
//! answers like SOES (`sim::topology::EscSpec` switches): SDO aborts in CoE service 2 with
//! the request's low command bits left set, one code for every wrong length, no complete
//! access, SDO Information errors without their abort code, a slow mailbox. Every refusal
//! must reach the user as the slave's abort code, through REST, `ecat` and the gateway,
//! and leave a debug line in ecatd's JSON log.

use crate::server_support;

use std::path::PathBuf;
use std::process::Command;

use master_core::wire::coe::SdoRequest;
use master_core::wire::coe::sdo::SdoFrame;
use master_core::wire::coe::{CoeRepr, SdoPayload};
use master_core::wire::mailbox::MailboxType;
use serde_json::Value;
use server_support::gateway_client::{GatewayClient, coe_bytes};
use server_support::{Ecatd, bin_dir, curl};
use sim::topology::{CoeObject, EscSpec, Topology};

/// Ring position of the default segment's CoE store, and its station address.
const STORE: usize = 3;
const STORE_STATION: u16 = 1004;
const WRITE_ONLY: u16 = 0x2F00;
const READ_ONLY: u16 = 0x2F01;
const PARAMETER: u16 = 0x2001;
const MISSING: u16 = 0x5555;

const MISSING_CODE: u32 = 0x0602_0000;
const WRITE_ONLY_CODE: u32 = 0x0601_0001;
const READ_ONLY_CODE: u32 = 0x0601_0002;
const LENGTH_CODE: u32 = 0x0607_0010;
const GENERAL_CODE: u32 = 0x0800_0000;

/// A SOES-like CoE store answering after `delay_us`.
fn soes_like(delay_us: u32) -> EscSpec {
    EscSpec {
        sdo_abort_in_request: true,
        sdo_abort_keeps_command_bits: true,
        sdo_abort_length_mismatch: true,
        refuse_complete_access: true,
        sdo_info_short_errors: true,
        response_delay_us: delay_us,
        ..EscSpec::default()
    }
}

/// The default segment with the CoE store's firmware as `esc` says, written to a file for
/// `--simulate` (`name` keeps the files of the tests apart).
fn topology_file(name: &str, esc: EscSpec) -> PathBuf {
    let mut topology = Topology::default_segment();
    let store = &mut topology.slaves[STORE];
    store.esc = esc;
    store
        .objects
        .push(CoeObject::unsigned32(WRITE_ONLY, "wo", "Write only"));
    store
        .objects
        .push(CoeObject::unsigned32(READ_ONLY, "ro", "Read only"));
    let path = std::env::temp_dir().join(format!(
        "ecatd-mailbox-errors-{name}-{}.toml",
        std::process::id()
    ));
    std::fs::write(&path, topology.to_toml().expect("the topology serialises"))
        .expect("the topology file is written");
    path
}

fn start_with(name: &str, esc: EscSpec) -> Ecatd {
    let file = topology_file(name, esc);
    let file = file.to_str().expect("a UTF-8 temp path");
    Ecatd::start_with(&["--simulate", file], &["--log", "info,master_core=debug"])
}

fn start(name: &str) -> Ecatd {
    start_with(name, soes_like(2_000))
}

fn rest(ecatd: &Ecatd, method: &str, path: &str, body: &str) -> (u16, Value) {
    let url = format!("{}{path}", ecatd.http);
    let mut args = vec!["-s", "-X", method, &url];
    if !body.is_empty() {
        args.extend(["-H", "content-type: application/json", "-d", body]);
    }
    let (status, text) = curl(&args);
    (
        status,
        serde_json::from_str(&text).unwrap_or(Value::String(text)),
    )
}

fn ecat(ecatd: &Ecatd, args: &[&str]) -> (bool, String) {
    let output = Command::new(bin_dir().join("ecat"))
        .args(["--address", &format!("http://{}", ecatd.grpc)])
        .args(args)
        .output()
        .expect("ecat runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    (output.status.success(), text)
}

#[test]
fn every_refusal_reaches_rest_ecat_and_the_gateway_as_the_slave_abort() {
    let ecatd = start("refusals");
    let base = format!("/api/v1/slaves/{STORE}/coe/sdo");

    // REST.
    // Each abort with the status of its class (docs/call-it.md, "Errors").
    let cases = [
        (
            "GET",
            format!("{base}/{MISSING:#x}/0"),
            "",
            MISSING_CODE,
            404,
        ),
        (
            "GET",
            format!("{base}/{WRITE_ONLY:#x}/0"),
            "",
            WRITE_ONLY_CODE,
            409,
        ),
        (
            "PUT",
            format!("{base}/{READ_ONLY:#x}/0"),
            r#"{"data":"01020304"}"#,
            READ_ONLY_CODE,
            409,
        ),
        (
            "PUT",
            format!("{base}/{PARAMETER:#x}/0"),
            r#"{"data":"0102"}"#,
            LENGTH_CODE,
            400,
        ),
        (
            "GET",
            format!("{base}/0x1018/0?complete_access=true"),
            "",
            GENERAL_CODE,
            409,
        ),
    ];
    for (method, path, body, code, http) in &cases {
        let (status, answer) = rest(&ecatd, method, path, body);
        assert_eq!(status, *http, "{method} {path}: {answer}");
        assert_eq!(answer["reason"], "SDO_ABORT", "{method} {path}");
        assert_eq!(answer["protocol_code"], *code, "{method} {path}");
    }

    // `ecat` (the upload of the missing object with the default `--type auto`).
    let store = STORE.to_string();
    let cli: [(Vec<&str>, u32); 5] = [
        (vec!["upload", "-p", &store, "0x5555", "0"], MISSING_CODE),
        (
            vec!["upload", "-p", &store, "0x2f00", "0", "--type", "u32"],
            WRITE_ONLY_CODE,
        ),
        (
            vec![
                "download", "-p", &store, "0x2f01", "0", "5", "--type", "u32",
            ],
            READ_ONLY_CODE,
        ),
        (
            vec![
                "download", "-p", &store, "0x2001", "0", "5", "--type", "u16",
            ],
            LENGTH_CODE,
        ),
        (
            vec![
                "upload",
                "-p",
                &store,
                "0x1018",
                "0",
                "--complete",
                "--type",
                "hex",
            ],
            GENERAL_CODE,
        ),
    ];
    for (args, code) in &cli {
        let (ok, text) = ecat(&ecatd, args);
        assert!(!ok, "ecat {args:?} refused: {text}");
        assert!(
            text.contains(&format!("{code:#010x}")),
            "ecat {args:?} names the abort {code:#010x}: {text}"
        );
        assert!(!text.contains("nternal"), "ecat {args:?}: {text}");
    }

    // The gateway forwards the slave's abort unchanged: CoE service 2, low bits kept.
    let mut client = GatewayClient::new(ecatd.gateway_addr());
    let upload = |index, complete_access| {
        coe_bytes(&CoeRepr::SdoRequest(SdoRequest::InitiateUpload {
            index,
            subindex: 0,
            complete_access,
        }))
    };
    let download = |index, data: &'static [u8]| {
        coe_bytes(&CoeRepr::SdoRequest(SdoRequest::InitiateDownload {
            index,
            subindex: 0,
            complete_access: false,
            payload: SdoPayload::Expedited(data),
        }))
    };
    let requests = [
        (upload(MISSING, false), MISSING, MISSING_CODE),
        (upload(WRITE_ONLY, false), WRITE_ONLY, WRITE_ONLY_CODE),
        (
            download(READ_ONLY, &[1, 2, 3, 4]),
            READ_ONLY,
            READ_ONLY_CODE,
        ),
        (download(PARAMETER, &[1, 2]), PARAMETER, LENGTH_CODE),
        (upload(0x1018, true), 0x1018, GENERAL_CODE),
    ];
    for (request, index, code) in &requests {
        let reply = client.exchange(STORE_STATION, MailboxType::Coe, request);
        assert_eq!(reply.header.mailbox_type, MailboxType::Coe);
        let frame = SdoFrame::new_checked(&reply.data[..]).expect("an SDO frame");
        let (answered, _, abort) = frame.any_abort().expect("an abort");
        assert_eq!(
            (answered, u32::from(abort)),
            (*index, *code),
            "{index:#06x}"
        );
        assert_eq!(reply.data[1] >> 4, 2, "{index:#06x}: service 2, unchanged");
        assert_eq!(
            reply.data[2],
            0x80 | (request[2] & 0x1f),
            "{index:#06x}: the request's low bits, unchanged"
        );
    }

    // Every refusal of the API and `ecat` left its debug line (the gateway's raw messages
    // are the client's to judge).
    let lines = failure_lines(&ecatd);
    for (object, code) in [
        ("0x5555:00", MISSING_CODE),
        ("0x2f00:00", WRITE_ONLY_CODE),
        ("0x2f01:00", READ_ONLY_CODE),
        ("0x2001:00", LENGTH_CODE),
        ("0x1018:00", GENERAL_CODE),
    ] {
        let code = format!("{code:#010x}");
        let found = lines
            .iter()
            .filter(|fields| fields["object"] == object && fields["code"] == code.as_str());
        assert!(
            found.count() >= 2,
            "REST and ecat each left a line for {object} {code}:\n{lines:#?}"
        );
    }
}

#[test]
fn an_auto_typed_upload_of_a_missing_object_prints_the_slave_abort_not_internal() {
    let ecatd = start("auto");
    let store = STORE.to_string();
    let (ok, text) = ecat(&ecatd, &["upload", "-p", &store, "0x5555", "0"]);
    assert!(!ok, "{text}");
    assert!(text.contains("0x06020000"), "{text}");
    assert!(!text.contains("nternal"), "{text}");
    // The entry description itself is a typed error, not a protocol violation.
    let (status, answer) = rest(
        &ecatd,
        "GET",
        &format!("/api/v1/slaves/{store}/coe/od/0x5555/0"),
        "",
    );
    assert_eq!(status, 409, "{answer}");
    assert_eq!(answer["reason"], "SDO_INFO_ERROR");
    assert!(
        answer["detail"]
            .as_str()
            .unwrap_or_default()
            .contains("SDO Information error (abort code missing)"),
        "{answer}"
    );
    // An object that exists still reads with its type from SDO Information.
    let (ok, text) = ecat(&ecatd, &["upload", "-p", &store, "0x2001", "0"]);
    assert!(ok, "{text}");
    assert_eq!(text.trim(), format!("0x12345678 {}", 0x1234_5678u32));
    // The failed entry description left its line, with the slave and the object.
    let lines = failure_lines(&ecatd);
    assert!(
        lines.iter().any(|f| f["object"] == "0x5555:00"
            && f["station"] == "0x03ec"
            && f["protocol"] == "CoE"
            && f["error"]
                .as_str()
                .unwrap_or_default()
                .contains("abort code missing")),
        "{lines:#?}"
    );
}

#[test]
fn a_timeout_leaves_a_warn_line_and_its_late_reply_a_debug_line() {
    // The store answers 4 s after each request; the engine waits 3 s.
    let ecatd = start_with("slow", soes_like(4_000_000));
    let (status, answer) = rest(
        &ecatd,
        "GET",
        &format!("/api/v1/slaves/{STORE}/coe/sdo/{PARAMETER:#x}/0"),
        "",
    );
    assert_eq!(status, 504, "{answer}");
    assert_eq!(answer["reason"], "TIMEOUT");
    let (at, warned) = wait_for_line(&ecatd, 0, |v| {
        v["level"] == "WARN"
            && v["fields"]["message"] == "mailbox request failed"
            && v["fields"]["object"] == "0x2001:00"
    });
    assert_eq!(warned["fields"]["station"], "0x03ec");
    assert_eq!(warned["fields"]["protocol"], "CoE");
    assert!(
        warned["fields"]["error"]
            .as_str()
            .unwrap_or_default()
            .contains("no answer in time"),
        "{warned}"
    );
    // The answer comes a second later, to nobody: dropped, with its line (after the
    // warning: the scan's upload of 0x1000 timed out as well, and its answer came late too).
    let (_, dropped) = wait_for_line(&ecatd, at + 1, |v| {
        v["level"] == "DEBUG"
            && v["fields"]["station"] == "0x03ec"
            && v["fields"]["message"]
                .as_str()
                .is_some_and(|m| m.starts_with("unexpected mailbox reply dropped"))
    });
    assert_eq!(dropped["fields"]["protocol"], "CoE");
}

/// The first line of ecatd's JSON log from line `from` on that `matches`, and its line
/// number, polled with a deadline.
fn wait_for_line(ecatd: &Ecatd, from: usize, matches: impl Fn(&Value) -> bool) -> (usize, Value) {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(20);
    loop {
        let found = ecatd
            .log()
            .lines()
            .enumerate()
            .skip(from)
            .filter_map(|(n, line)| Some((n, serde_json::from_str::<Value>(line).ok()?)))
            .find(|(_, v)| matches(v));
        if let Some(line) = found {
            return line;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "no such line in ecatd's log:\n{}",
            ecatd.log()
        );
        // Poll interval of the log check; the loop ends on the condition or the deadline.
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// The fields of every "mailbox request failed" line in ecatd's JSON log, polled with a
/// deadline (the log reader runs behind the process).
fn failure_lines(ecatd: &Ecatd) -> Vec<Value> {
    let collect = || -> Vec<Value> {
        ecatd
            .log()
            .lines()
            .filter_map(|line| serde_json::from_str::<Value>(line).ok())
            .filter(|v| v["fields"]["message"] == "mailbox request failed")
            .map(|v| {
                assert_eq!(v["level"], "DEBUG", "an abort is a debug line: {v}");
                v["fields"].clone()
            })
            .collect()
    };
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    let mut lines = collect();
    while lines.len() < 5 && std::time::Instant::now() < deadline {
        // Poll interval of the log check; the loop ends on the condition or the deadline.
        std::thread::sleep(std::time::Duration::from_millis(20));
        lines = collect();
    }
    lines
}
