//! Watched values: ecatd with a configuration file listing `[[watch]]` entries exports each
//! as `ecat_watch_value`; when the test changes the watched CoE object through the REST
//! download API the gauge follows, an IDN watch shows the simulator's value, and a watch of
//! a missing object counts read errors without a value.

mod server_support;

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
