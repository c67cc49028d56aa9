//! ecatd's `/metrics`: `promtool check metrics` reports nothing, and the counters and gauges
//! equal what the test did (uploads good and bad, a state change).

mod server_support;

use std::io::Write;
use std::process::{Command, Stdio};

use server_support::{Ecatd, curl};
use sim::topology::Topology;

fn scrape(ecatd: &Ecatd) -> String {
    let (status, body) = curl(&["-s", &format!("{}/metrics", ecatd.http)]);
    assert_eq!(status, 200);
    body
}

/// The value of the sample `series` (name with labels, exactly as exposed).
fn sample(text: &str, series: &str) -> f64 {
    text.lines()
        .find_map(|line| line.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
        .unwrap_or_else(|| panic!("no sample {series} in:\n{text}"))
}

#[test]
fn promtool_finds_nothing() {
    let ecatd = Ecatd::start(&[]);
    // Some traffic first, so that every family has samples.
    curl(&[
        "-s",
        &format!("{}/api/v1/slaves/0/coe/sdo/0x1018/1", ecatd.http),
    ]);
    let text = scrape(&ecatd);
    let mut promtool = Command::new("promtool")
        .args(["check", "metrics"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("promtool (Debian package prometheus; scripts/test installs it)");
    promtool
        .stdin
        .take()
        .unwrap()
        .write_all(text.as_bytes())
        .unwrap();
    let output = promtool.wait_with_output().unwrap();
    let report = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(
        output.status.success() && report.trim().is_empty(),
        "promtool:\n{report}"
    );
}

#[test]
fn counters_equal_what_was_done() {
    let ecatd = Ecatd::start(&[]);
    let topology = Topology::default_segment();
    let before = scrape(&ecatd);
    let requests = r#"ecat_mailbox_requests_total{station="1004"}"#;
    let failed = r#"ecat_mailbox_failed_requests_total{station="1004"}"#;
    let (r0, f0) = (sample(&before, requests), sample(&before, failed));
    for _ in 0..5 {
        let (status, _) = curl(&[
            "-s",
            &format!("{}/api/v1/slaves/3/coe/sdo/0x2001/0", ecatd.http),
        ]);
        assert_eq!(status, 200);
    }
    for _ in 0..3 {
        let (status, _) = curl(&[
            "-s",
            &format!("{}/api/v1/slaves/3/coe/sdo/0x6000/0", ecatd.http),
        ]);
        assert_eq!(status, 409);
    }
    let after = scrape(&ecatd);
    assert_eq!(sample(&after, requests) - r0, 8.0);
    assert_eq!(sample(&after, failed) - f0, 3.0);
    assert_eq!(
        sample(&after, r#"ecat_slaves{state="OP"}"#),
        topology.slaves.len() as f64
    );
    let url = format!("{}/api/v1/slaves/1/state", ecatd.http);
    let (status, _) = curl(&[
        "-s",
        "-X",
        "PUT",
        "-H",
        "content-type: application/json",
        "-d",
        r#"{"state":"PREOP"}"#,
        &url,
    ]);
    assert_eq!(status, 200);
    let states = scrape(&ecatd);
    assert_eq!(sample(&states, r#"ecat_slaves{state="PREOP"}"#), 1.0);
    assert_eq!(
        sample(&states, r#"ecat_slaves{state="OP"}"#),
        topology.slaves.len() as f64 - 1.0
    );
    assert!(sample(&states, "ecat_bus_frames_sent_total") > 0.0);
    assert_eq!(
        sample(&states, "ecat_bus_frames_lost_total"),
        0.0,
        "the in-process link loses nothing"
    );
    let name = &topology.slaves[0].name;
    assert_eq!(
        sample(
            &states,
            &format!(r#"ecat_slave_al_status_code{{position="0",station="1001",name="{name}"}}"#)
        ),
        0.0
    );
}
