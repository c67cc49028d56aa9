//! The dashboard in a real browser: headless Chromium driven over WebDriver
//! (`tests/py/web_dashboard.py`, Python selenium with Debian's `chromium-driver`) against
//! `ecatd --simulate` with a read and a write token. The script acts and reports what the
//! page showed; every expected value here comes from the simulator's topology or from
//! ecatd's REST API. Screenshots of each view go to `target/web-dashboard/`.
//!
//! Needs `chromium`, `chromium-driver` and the venv of `scripts/test` (tests/README.md).

mod server_support;

use std::process::Command;

use server_support::{Ecatd, curl, root, venv_bin};
use sha2::{Digest, Sha256};
use sim::topology::{SIM_VENDOR_ID, Topology};

const READ_TOKEN: &str = "read-secret-1-dashboard";
const WRITE_TOKEN: &str = "write-secret-2-dashboard";
/// Written to 0x2001:00 (UNSIGNED32 "Parameter" of slave 3, 0x12345678 at start).
const COE_VALUE: u32 = 4660;
/// The CoE emergency the simulated drive sends (CiA 301 0x8110, CAN overrun).
const EMERGENCY_CODE: u16 = 0x8110;
/// Malformed datagrams sent to the gateway.
const BAD_REQUESTS: usize = 40;

fn config() -> std::path::PathBuf {
    let file = std::env::temp_dir().join(format!("ecatd-web-{}.toml", std::process::id()));
    std::fs::write(
        &file,
        format!(
            "[[tokens]]\nname = \"viewer\"\ntoken = \"{READ_TOKEN}\"\nrole = \"read\"\n\n\
             [[tokens]]\nname = \"engineer\"\ntoken = \"{WRITE_TOKEN}\"\nrole = \"write\"\n"
        ),
    )
    .unwrap();
    file
}

/// 1 MiB that no two runs share (the FoE store must not already hold it).
fn foe_content() -> Vec<u8> {
    let mut state = u64::from(std::process::id()) | 1;
    (0..1 << 20)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state as u8
        })
        .collect()
}

fn rest(ecatd: &Ecatd, token: &str, args: &[&str], path: &str) -> (u16, String) {
    let auth = format!("authorization: Bearer {token}");
    let url = format!("{}{path}", ecatd.http);
    let mut all = vec!["-s", "-H", auth.as_str()];
    all.extend_from_slice(args);
    all.push(&url);
    curl(&all)
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[test]
fn the_dashboard_shows_the_segment_and_drives_the_mailboxes() {
    let file = config();
    let ecatd = Ecatd::start(&["--config", file.to_str().unwrap()]);
    std::fs::remove_file(&file).unwrap();
    let topology = Topology::default_segment();
    let shots = root().join("target/web-dashboard");
    std::fs::create_dir_all(&shots).unwrap();
    let foe = foe_content();
    let foe_file = std::env::temp_dir().join(format!("ecatd-web-{}.bin", std::process::id()));
    std::fs::write(&foe_file, &foe).unwrap();

    // The page itself: embedded, with a policy that allows nothing off-origin.
    let (status, page) = curl(&["-s", "-i", &format!("{}/", ecatd.http)]);
    assert_eq!(status, 200);
    assert!(
        page.contains("content-security-policy: default-src 'none'"),
        "{page}"
    );
    assert!(page.contains("<script type=\"module\" src=\"/static/app.js\">"));

    let args = serde_json::json!({
        "http": ecatd.http,
        "grpc": ecatd.grpc,
        "gateway": ecatd.gateway_addr().to_string(),
        "ecat": server_support::bin_dir().join("ecat"),
        "read_token": READ_TOKEN,
        "write_token": WRITE_TOKEN,
        "slave_count": topology.slaves.len(),
        "coe_write_value": COE_VALUE,
        // The drive's store holds 1 MiB in all: the new file replaces firmware.bin.
        "foe_name": "firmware.bin",
        "foe_file": foe_file,
        "bad_requests": BAD_REQUESTS,
        "emergency_code": EMERGENCY_CODE,
        "screenshots": shots,
    });
    let output = Command::new(venv_bin().join("python"))
        .arg(root().join("tests/py/web_dashboard.py"))
        .arg(args.to_string())
        .output()
        .expect("python runs");
    std::fs::remove_file(&foe_file).unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "web_dashboard.py failed:\n{stderr}\n{stdout}"
    );
    let r: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(r["steps"], serde_json::json!([]), "every wait ended: {r:#}");

    // The token prompt, then the segment: every slave, named, in the state ecatd reports.
    assert_eq!(r["token_prompt"], true);
    assert!(r["role_label"].as_str().unwrap().starts_with("engineer"));
    let (_, slaves) = rest(&ecatd, READ_TOKEN, &[], "/api/v1/slaves");
    let slaves: serde_json::Value = serde_json::from_str(&slaves).unwrap();
    let shown = r["slaves"].as_array().unwrap();
    assert_eq!(shown.len(), topology.slaves.len());
    for (p, spec) in topology.slaves.iter().enumerate() {
        assert_eq!(shown[p]["position"], p);
        assert_eq!(shown[p]["name"], format!("{p}: {}", spec.name));
        assert_eq!(shown[p]["state"], slaves[p]["state"], "slave {p}");
    }

    // A state change from the CLI reached the open page without a reload.
    assert_eq!(r["cli_safeop"]["status"], 0, "{}", r["cli_safeop"]);
    assert_eq!(r["state_after_cli"], "SAFEOP");
    assert_eq!(r["not_reloaded"], true);
    assert_eq!(r["keyboard_view"], "#/events");

    // An emergency: in the log (filtered to emergencies only) and on the slave's page.
    assert_eq!(r["emergency_raised"], 200);
    let rows = r["events_filtered"].as_array().unwrap();
    assert_eq!(rows.len(), 1, "{rows:?}");
    let code = format!("0x{EMERGENCY_CODE:04x}");
    assert!(rows[0].as_str().unwrap().contains(&code), "{rows:?}");
    let shown = r["slave_emergencies"].as_str().unwrap();
    assert!(
        shown.contains(&format!("0x{EMERGENCY_CODE:04X}")),
        "{shown}"
    );

    // CoE: 0x1018:01 is the vendor id; the write reached the slave.
    assert_eq!(r["coe_1018_01"], SIM_VENDOR_ID.to_string());
    assert_eq!(r["coe_write_status"], "written");
    let (status, value) = rest(
        &ecatd,
        READ_TOKEN,
        &[],
        "/api/v1/slaves/3/coe/sdo/0x2001/0?type=u32",
    );
    assert_eq!(status, 200);
    let value: serde_json::Value = serde_json::from_str(&value).unwrap();
    assert_eq!(value["value"], COE_VALUE.to_string());

    // FoE: 1 MiB written with the bar at 100 %, and the same bytes read back.
    let digest = sha256_hex(&foe);
    assert_eq!(
        r["foe_write"]["progress"],
        100,
        "{}\n{}",
        r["foe_write"],
        ecatd.log()
    );
    assert_eq!(r["foe_write"]["sha256"], digest.as_str());
    assert_eq!(r["foe_read"]["progress"], 100, "{}", r["foe_read"]);
    assert_eq!(r["foe_read"]["sha256"], digest.as_str());
    assert_eq!(r["foe_read"]["size"], (1 << 20).to_string());
    let back = Command::new("curl")
        .args(["-sf", "-H", &format!("authorization: Bearer {READ_TOKEN}")])
        .arg(format!("{}/api/v1/slaves/0/foe/firmware.bin", ecatd.http))
        .output()
        .unwrap();
    assert_eq!(sha256_hex(&back.stdout), digest);

    // Gateway: no failures before, the failure rate above the 5 % line after.
    assert_eq!(r["gateway_before"], 0.0);
    assert!(
        r["gateway_after"].as_f64().unwrap() > 5.0,
        "{}",
        r["gateway_after"]
    );
    assert!(r["gateway_chart_last"].as_f64().unwrap() > 5.0);
    let (_, gateway) = rest(&ecatd, READ_TOKEN, &[], "/api/v1/gateway");
    let gateway: serde_json::Value = serde_json::from_str(&gateway).unwrap();
    let malformed = gateway["stats"]["failures"]["malformed"].as_u64().unwrap();
    assert_eq!(malformed, BAD_REQUESTS as u64);
    assert!(
        r["gateway_malformed"]
            .as_str()
            .unwrap()
            .contains(&format!("malformed\n{malformed}")),
        "{}",
        r["gateway_malformed"]
    );
    assert!(r["bus_period"].as_str().unwrap().ends_with("µs"));

    // Dark theme, and no sideways scrolling at a tablet's width.
    assert_eq!(r["dark_background"], "rgb(13, 17, 23)");
    assert_eq!(r["tablet_overflow"], false);

    // Read only: no write control, the value shown, and ecatd refuses the write.
    assert!(r["read_role_label"].as_str().unwrap().starts_with("viewer"));
    for view in ["segment", "slave", "gateway"] {
        assert_eq!(r[format!("read_only_{view}_controls")], 0, "{view}");
    }
    assert_eq!(r["read_only_value"], COE_VALUE.to_string());
    let (status, _) = rest(
        &ecatd,
        READ_TOKEN,
        &[
            "-X",
            "PUT",
            "-H",
            "content-type: application/json",
            "-d",
            r#"{"value":"1","type":"auto"}"#,
        ],
        "/api/v1/slaves/3/coe/sdo/0x2001/0",
    );
    assert_eq!(status, 403);

    // The console: no error, except the refusals before the token was given.
    let console = r["console"].as_array().cloned().unwrap_or_default();
    let errors: Vec<_> = console
        .iter()
        .filter(|e| e["level"] == "SEVERE")
        .filter(|e| {
            !(e["phase"] == "token"
                && e["message"]
                    .as_str()
                    .unwrap_or("")
                    .contains("status of 401"))
        })
        .collect();
    assert!(errors.is_empty(), "console errors: {errors:#?}");

    // Every request the page made went to ecatd on 127.0.0.1.
    let requests = r["requests"].as_array().unwrap();
    assert!(requests.len() > 20, "{requests:?}");
    let origin = format!("{}/", ecatd.http);
    let foreign: Vec<_> = requests
        .iter()
        .filter_map(|u| u.as_str())
        .filter(|u| !u.starts_with(&origin) && !u.starts_with("blob:") && !u.starts_with("data:"))
        .collect();
    assert!(foreign.is_empty(), "requests off 127.0.0.1: {foreign:?}");
    assert!(origin.starts_with("http://127.0.0.1:"));

    for shot in r["screenshots"].as_array().unwrap() {
        let len = std::fs::metadata(shot.as_str().unwrap()).unwrap().len();
        assert!(len > 10_000, "{shot} is {len} bytes");
    }
}
