//! Issue 15, items 2 and 3, through the ecatd process: the gateway's enable flag, roles and
//! allowlist come from ecatd's configuration file; a `read` client reads and is refused a
//! write (counted `denied`); a `write` client's writes leave audit lines (target `audit`,
//! as the APIs': client, slave, object/IDN/file, outcome); ecatd refuses a non-loopback
//! network with the write role unless `--insecure`, saying what to change; a repeated
//! datagram is answered once and counted in `ecat_mailbox_gateway_retries_answered_total`.

use crate::server_support;

use crate::compat_client;

use std::time::{Duration, Instant};

use compat_client::CompatClient;
use master_core::wire::coe::{CoeRepr, SdoPayload, SdoRequest};
use master_core::wire::mailbox::MailboxType;
use serde_json::Value;
use server_support::gateway_client::{GatewayClient, coe_bytes, datagram};
use server_support::{Ecatd, call, curl, run_to_exit};

const DRIVE: u16 = 1001;

fn config_file(name: &str, toml: &str) -> std::path::PathBuf {
    let file = std::env::temp_dir().join(format!(
        "ecatd-gateway-roles-{name}-{}.toml",
        std::process::id()
    ));
    std::fs::write(&file, toml).unwrap();
    file
}

fn start_with_config(name: &str, toml: &str) -> Ecatd {
    let file = config_file(name, toml);
    let ecatd = Ecatd::start(&["--config", file.to_str().unwrap()]);
    std::fs::remove_file(&file).unwrap();
    ecatd
}

fn gateway_view(ecatd: &Ecatd) -> Value {
    let (status, body) = curl(&["-s", &format!("{}/api/v1/gateway", ecatd.http)]);
    assert_eq!(status, 200, "{body}");
    serde_json::from_str(&body).expect("JSON")
}

fn download(index: u16, subindex: u8, value: &[u8]) -> Vec<u8> {
    coe_bytes(&CoeRepr::SdoRequest(SdoRequest::InitiateDownload {
        index,
        subindex,
        complete_access: false,
        payload: SdoPayload::Expedited(value),
    }))
}

/// Polls ecatd's log until a line satisfies `found` (the log reader runs on its own
/// thread) or a deadline passes.
fn wait_for_log(ecatd: &Ecatd, found: impl Fn(&Value) -> bool) -> bool {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let log = ecatd.log();
        if log
            .lines()
            .filter_map(|l| serde_json::from_str::<Value>(l).ok())
            .any(|v| found(&v))
        {
            return true;
        }
        if Instant::now() > deadline {
            return false;
        }
        // Poll interval of the log check; the loop ends on the condition or the deadline.
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn audit_line(v: &Value, client: &str, slave: &str, object: &str, outcome: &str) -> bool {
    v["target"] == "audit"
        && v["fields"]["client"] == client
        && v["fields"]["slave"] == slave
        && v["fields"]["object"] == object
        && v["fields"]["outcome"] == outcome
}

#[test]
fn a_read_client_reads_and_is_refused_writes() {
    let ecatd = start_with_config(
        "read",
        "[gateway]\nallow = [{ net = \"127.0.0.0/8\", role = \"read\" }]\n",
    );
    let view = gateway_view(&ecatd);
    assert_eq!(view["allow"], serde_json::json!(["127.0.0.0/8 read"]));
    let mut client = GatewayClient::new(ecatd.gateway_addr());
    assert_eq!(
        client.sdo_upload(DRIVE, 0x6040, 0).expect("upload").len(),
        2
    );
    let reply = client.exchange(DRIVE, MailboxType::Coe, &download(0x6040, 0, &[6, 0]));
    assert_eq!(reply.data[2], 0x80, "an abort: {reply:?}");
    assert_eq!(reply.data[6..10], 0x0601_0002u32.to_le_bytes());
    // In the manual's layout: its code for "write protected" too.
    let compat = CompatClient::new(ecatd.gateway_addr(), Duration::from_secs(8));
    let r = compat
        .coe_sdo_write(DRIVE, 0x6040, 0, &[6, 0])
        .expect("answer");
    assert_eq!(r.data[6..10], 0x0601_0002u32.to_le_bytes());
    let view = gateway_view(&ecatd);
    assert_eq!(view["stats"]["failures"]["denied"], 2, "{view}");
    let me = client.socket.local_addr().unwrap().to_string();
    assert!(
        wait_for_log(&ecatd, |v| audit_line(
            v,
            &me,
            "0x03E9",
            "0x6040:00",
            "refused: read role"
        )),
        "no audit line for the refused write:\n{}",
        ecatd.log()
    );
}

#[test]
fn a_write_clients_writes_leave_audit_lines() {
    let ecatd = Ecatd::start(&[]);
    let gateway = ecatd.gateway_addr();
    let mut client = GatewayClient::new(gateway);
    let me = client.socket.local_addr().unwrap().to_string();
    client
        .sdo_download(DRIVE, 0x6040, 0, &[6, 0], 128)
        .expect("download");
    let compat = CompatClient::new(gateway, Duration::from_secs(8));
    let you = compat.socket.local_addr().unwrap().to_string();
    let r = compat
        .soe_write(DRIVE, 32, &1000u32.to_le_bytes(), 0, 5)
        .expect("SoE write");
    assert_eq!(r.data[0], 0x02, "no error: {r:02X?}");
    let r = compat.voe_send(DRIVE, 0x1164, 1, &[1, 2]).expect("VoE");
    assert_eq!(r.code, 0x0F);
    // An AL state request through the master's dictionary (0xA000:02 = OP, where the
    // slave already is) is a write too.
    let reply = client.exchange(0, MailboxType::Coe, &download(0xA000, 2, &[8, 0]));
    assert_eq!(reply.data[2], 0x60, "download response: {reply:?}");
    for (client, slave, object, outcome) in [
        (&me, "0x03E9", "0x6040:00", "done"),
        (&you, "0x03E9", "S-0-0032 drive 0", "done"),
        (&you, "0x03E9", "VoE vendor 0x00001164", "done"),
        (&me, "master", "0xA000:02", "done"),
    ] {
        assert!(
            wait_for_log(&ecatd, |v| audit_line(v, client, slave, object, outcome)),
            "no audit line {client} {slave} {object} {outcome}:\n{}",
            ecatd.log()
        );
    }
    // Reads leave none.
    client.sdo_upload(DRIVE, 0x6040, 0).expect("upload");
    let reads = ecatd
        .log()
        .lines()
        .filter(|l| l.contains("\"target\":\"audit\"") && l.contains("gateway write"))
        .count();
    assert_eq!(reads, 4, "{}", ecatd.log());
}

#[test]
fn a_repeated_download_runs_once_and_is_counted() {
    let ecatd = Ecatd::start(&[]);
    let client = GatewayClient::new(ecatd.gateway_addr());
    let message = datagram(DRIVE, MailboxType::Coe, 5, &download(0x6040, 0, &[6, 0]));
    client.send_raw(&message);
    let first = client.recv();
    client.send_raw(&message);
    let second = client.recv();
    assert_eq!(first.data, second.data);
    let view = gateway_view(&ecatd);
    assert_eq!(view["stats"]["retries_answered"], 1, "{view}");
    assert_eq!(view["stats"]["forwarded_requests"], 1, "{view}");
    // The gRPC message carries the same counter (a uint64: a JSON string in grpcurl).
    let status = call(&ecatd.grpc, &[], "ecat.v1.GatewayService/GetGateway", "{}").unwrap();
    assert_eq!(status["stats"]["retriesAnswered"], "1", "{status}");
    let (status, metrics) = curl(&["-s", &format!("{}/metrics", ecatd.http)]);
    assert_eq!(status, 200);
    assert!(
        metrics
            .lines()
            .any(|l| l == "ecat_mailbox_gateway_retries_answered_total 1"),
        "{metrics}"
    );
    // Audited once: the repeat was not executed.
    let audits = ecatd
        .log()
        .lines()
        .filter(|l| l.contains("\"target\":\"audit\"") && l.contains("0x6040:00"))
        .count();
    assert_eq!(audits, 1, "{}", ecatd.log());
}

#[test]
fn open_writers_need_insecure_and_the_message_says_what_to_change() {
    let file = config_file("open", "[gateway]\nallow = [\"192.168.10.0/24\"]\n");
    let path = file.to_str().unwrap();
    let (status, stderr) = run_to_exit(&["--simulate", "--config", path]);
    assert!(!status.success());
    assert!(
        stderr.contains("192.168.10.0/24")
            && stderr.contains("role =")
            && stderr.contains("read")
            && stderr.contains("--insecure"),
        "{stderr}"
    );
    std::fs::remove_file(&file).unwrap();
    // The same network as a read network starts.
    let ecatd = start_with_config(
        "readnet",
        "[gateway]\nallow = [\"127.0.0.0/8\", { net = \"192.168.10.0/24\", role = \"read\" }]\n",
    );
    assert_eq!(
        gateway_view(&ecatd)["allow"],
        serde_json::json!(["127.0.0.0/8 write", "192.168.10.0/24 read"])
    );
}

#[test]
fn the_enable_flag_is_in_the_file() {
    let ecatd = start_with_config("off", "[gateway]\nenabled = false\n");
    let view = gateway_view(&ecatd);
    assert_eq!(view["enabled"], false, "{view}");
    assert_eq!(view["running"], false, "{view}");
}
