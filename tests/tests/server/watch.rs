//! Watched values: ecatd with a configuration file listing `[[watch]]` entries exports each
//! as `ecat_watch_value`; when the test changes the watched CoE object through the REST
//! download API the gauge follows, an IDN watch shows the simulator's value, and a watch of
//! a missing object counts read errors without a value. A process-data watch (`pdo`) shows
//! the value in the process image, follows a DO8 output forced onto the DI8's input, and
//! moves no mailbox counter.

use crate::server_support;

use std::time::{Duration, Instant};

use server_support::{Ecatd, curl};
use sim::topology::Topology;

const DEADLINE: Duration = Duration::from_secs(20);

fn scrape(ecatd: &Ecatd) -> String {
    let (status, body) = curl(&["-s", &format!("{}/metrics", ecatd.http)]);
    assert_eq!(status, 200);
    body
}

/// The value of the sample `series` (name with labels, exactly as exposed), if present.
fn sample(text: &str, series: &str) -> Option<f64> {
    text.lines()
        .find_map(|line| line.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
}

/// Scrapes until `series` satisfies `want`, or panics at the deadline.
fn wait_for(ecatd: &Ecatd, series: &str, want: impl Fn(f64) -> bool) -> f64 {
    let deadline = Instant::now() + DEADLINE;
    loop {
        let text = scrape(ecatd);
        if let Some(value) = sample(&text, series).filter(|v| want(*v)) {
            return value;
        }
        assert!(
            Instant::now() < deadline,
            "{series} not as wanted in time:\n{text}"
        );
        // Poll interval of the scrape; the loop ends on the condition or the deadline.
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn watched_values_follow_the_slave() {
    let topology = Topology::default_segment();
    // The CoE store's UNSIGNED32 "Parameter" 0x2001 and the drive's motor temperature IDN.
    let parameter = topology.slaves[3]
        .objects
        .iter()
        .find(|o| o.index == 0x2001)
        .and_then(|o| o.value.as_ref()?.as_integer())
        .expect("0x2001 has a value");
    let temperature = topology.slaves[0]
        .idns
        .iter()
        .find(|i| i.name == "Motor temperature")
        .expect("the drive has P-0-0100");
    let idn = format!("P-0-{:04}", temperature.idn & 0x0fff);
    let dir = std::env::temp_dir().join(format!("ecatd-watch-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("ecatd.toml");
    std::fs::write(
        &config,
        format!(
            r#"
[[watch]]
slave = "3"
sdo = "0x2001:00"
period_ms = 50
name = "parameter"

[[watch]]
slave = "0"
idn = "{idn}"
type = "u16"
period_ms = 100
name = "motor_temperature"

[[watch]]
slave = "3"
sdo = "0x5fff:00"
type = "u32"
period_ms = 50
"#
        ),
    )
    .unwrap();
    let ecatd = Ecatd::start(&["--config", config.to_str().unwrap()]);
    std::fs::remove_dir_all(&dir).unwrap();

    let series = r#"ecat_watch_value{slave="3",object="0x2001:00",name="parameter"}"#;
    let first = wait_for(&ecatd, series, |_| true);
    assert_eq!(first, parameter as f64);

    let new_value = 0xdead_beefu32;
    let (status, body) = curl(&[
        "-s",
        "-X",
        "PUT",
        "-H",
        "content-type: application/json",
        "-d",
        &format!(r#"{{"value":"{new_value}","type":"u32"}}"#),
        &format!("{}/api/v1/slaves/3/coe/sdo/0x2001/0", ecatd.http),
    ]);
    assert_eq!(status, 200, "{body}");
    wait_for(&ecatd, series, |v| v == f64::from(new_value));

    let idn_series =
        format!(r#"ecat_watch_value{{slave="0",object="{idn}",name="motor_temperature"}}"#);
    let read = wait_for(&ecatd, &idn_series, |_| true);
    let value = temperature.value.as_deref().expect("the IDN has a value");
    let expected = u16::from_le_bytes(value.try_into().expect("a u16 value"));
    assert_eq!(read, f64::from(expected));

    let missing = r#"{slave="3",object="0x5fff:00",name=""}"#;
    wait_for(
        &ecatd,
        &format!("ecat_watch_read_errors_total{missing}"),
        |v| v >= 2.0,
    );
    let text = scrape(&ecatd);
    assert_eq!(sample(&text, &format!("ecat_watch_value{missing}")), None);
    assert_eq!(
        sample(
            &text,
            r#"ecat_watch_read_errors_total{slave="3",object="0x2001:00",name="parameter"}"#
        ),
        Some(0.0)
    );
}

#[test]
fn a_bad_watch_refuses_the_start() {
    let dir = std::env::temp_dir().join(format!("ecatd-badwatch-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("ecatd.toml");
    std::fs::write(&config, "[[watch]]\nslave = \"3\"\nsdo = \"0x2001\"\n").unwrap();
    let (status, stderr) = server_support::run_to_exit(&[
        "--simulate",
        "--config",
        config.to_str().unwrap(),
        "--grpc-listen",
        "127.0.0.1:0",
        "--http-listen",
        "127.0.0.1:0",
        "--no-gateway",
    ]);
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(!status.success());
    assert!(stderr.contains("watch sdo"), "{stderr}");
}

/// The value of `index:subindex` of the slave at `position` in the last completed cycle,
/// over REST (the process image ecatd serves).
fn image_value(ecatd: &Ecatd, position: u16, index: u16, subindex: u8) -> serde_json::Value {
    let (status, body) = curl(&[
        "-s",
        &format!("{}/api/v1/slaves/{position}/process-data", ecatd.http),
    ]);
    assert_eq!(status, 200, "{body}");
    let view: serde_json::Value = serde_json::from_str(&body).expect("JSON");
    view["entries"]
        .as_array()
        .expect("entries")
        .iter()
        .find(|e| e["index"] == index && e["subindex"] == subindex)
        .map(|e| e["value"].clone())
        .unwrap_or_else(|| panic!("{index:#06x}:{subindex} not mapped on {position}: {view}"))
}

/// The mailbox counters a read through a mailbox would move: every station's requests
/// (CoE, SoE, FoE, VoE and EoE calls, whoever made them) and ecatd's own requests by slave
/// and protocol (where its watch tasks count). The messages written are left out: the EoE
/// side traffic of the drive and the EoE port carries the host's own frames (router
/// solicitations on their interfaces) whenever the kernel sends them.
fn mailbox_requests(text: &str) -> Vec<String> {
    text.lines()
        .filter(|l| {
            l.starts_with("ecat_mailbox_requests_total{")
                || l.starts_with("ecat_mailbox_protocol_requests_total{")
        })
        .map(str::to_owned)
        .collect()
}

#[test]
fn a_process_data_watch_shows_the_image_and_reads_no_mailbox() {
    // The DI8's input 3, wired to the DO8's output 3, and the drive's statusword: the
    // drive has a mailbox, so a watch read through it would show in its counters.
    let dir = std::env::temp_dir().join(format!("ecatd-pdowatch-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("ecatd.toml");
    std::fs::write(
        &config,
        r#"
[[watch]]
slave = "2"
pdo = "0x6000:03"
name = "input_3"

[[watch]]
slave = "0"
pdo = "0x6041:0"
name = "statusword"
"#,
    )
    .unwrap();
    let ecatd = Ecatd::start(&["--config", config.to_str().unwrap()]);
    std::fs::remove_dir_all(&dir).unwrap();
    let input = r#"ecat_watch_value{slave="2",object="0x6000:03",name="input_3"}"#;
    let statusword = r#"ecat_watch_value{slave="0",object="0x6041:00",name="statusword"}"#;

    let before = scrape(&ecatd);
    let requests = mailbox_requests(&before);
    assert!(
        requests.iter().any(|l| l.contains(r#"station="1001""#)),
        "no mailbox counters of the drive:\n{before}"
    );

    // Nothing drives the DI8 yet: input 3 is off in the image and on the gauge.
    assert_eq!(image_value(&ecatd, 2, 0x6000, 3), false);
    assert_eq!(wait_for(&ecatd, input, |_| true), 0.0);
    // The statusword stands still until a controlword moves the drive's state machine.
    let image = image_value(&ecatd, 0, 0x6041, 0);
    let shown = wait_for(&ecatd, statusword, |_| true);
    assert_eq!(Some(shown), image.as_f64(), "{image}");

    let (status, body) = curl(&[
        "-s",
        "-X",
        "PUT",
        "-H",
        "content-type: application/json",
        "-d",
        r#"{"value": true}"#,
        &format!("{}/api/v1/slaves/1/process-data/0x7000/3", ecatd.http),
    ]);
    assert_eq!(status, 200, "{body}");
    // The wire carries output 3 to input 3 from the next frame on.
    assert_eq!(wait_for(&ecatd, input, |v| v == 1.0), 1.0);
    assert_eq!(image_value(&ecatd, 2, 0x6000, 3), true);

    // A few scrapes more, each reading both watches from the image.
    for _ in 0..5 {
        let text = scrape(&ecatd);
        assert_eq!(sample(&text, input), Some(1.0));
        assert_eq!(sample(&text, statusword), Some(shown));
    }
    let after = scrape(&ecatd);
    assert_eq!(mailbox_requests(&after), requests);
    for series in [
        r#"ecat_watch_read_errors_total{slave="2",object="0x6000:03",name="input_3"}"#,
        r#"ecat_watch_read_errors_total{slave="0",object="0x6041:00",name="statusword"}"#,
    ] {
        assert_eq!(sample(&after, series), Some(0.0), "{after}");
    }
}
