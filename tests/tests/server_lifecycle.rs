//! ecatd's configuration precedence (file, then `ECATD_*` environment, then flags) as
//! `--print-config` shows it, and a clean stop on SIGTERM.

mod server_support;

use std::process::Command;

use server_support::{Ecatd, bin_dir};

#[test]
fn flags_win_over_environment_over_file() {
    let file = std::env::temp_dir().join(format!("ecatd-lifecycle-{}.toml", std::process::id()));
    std::fs::write(
        &file,
        "grpc_listen = \"127.0.0.1:1111\"\nhttp_listen = \"127.0.0.1:2222\"\nlog = \"debug\"\n",
    )
    .unwrap();
    let output = Command::new(bin_dir().join("ecatd"))
        .args([
            "--config",
            file.to_str().unwrap(),
            "--http-listen",
            "127.0.0.1:4444",
            "--simulate",
            "--print-config",
        ])
        .env("ECATD_GRPC_LISTEN", "127.0.0.1:3333")
        .env("ECATD_HTTP_LISTEN", "127.0.0.1:5555")
        .output()
        .unwrap();
    std::fs::remove_file(&file).unwrap();
    assert!(output.status.success());
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(
        text.contains("grpc_listen = \"127.0.0.1:3333\""),
        "environment over file:\n{text}"
    );
    assert!(
        text.contains("http_listen = \"127.0.0.1:4444\""),
        "flag over environment:\n{text}"
    );
    assert!(
        text.contains("log = \"debug\""),
        "file over default:\n{text}"
    );
    assert!(text.contains("[segment.simulate]"), "{text}");
}

#[test]
fn bad_configuration_is_refused() {
    let output = Command::new(bin_dir().join("ecatd"))
        .args(["--config", "/nonexistent/ecatd.toml", "--print-config"])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&output.stderr).contains("/nonexistent/ecatd.toml"));
}

#[test]
fn sigterm_stops_cleanly() {
    let mut ecatd = Ecatd::start(&[]);
    assert!(ecatd.stop(), "ecatd exited with failure:\n{}", ecatd.log());
    let log = ecatd.log();
    let shutting = log.find("shutting down").expect("a shutdown line");
    let stopped = log.find("\"stopped\"").expect("a stopped line");
    assert!(shutting < stopped, "{log}");
    assert!(log.contains("SIGTERM"), "{log}");
}
