//! `ecat`'s exit status by class of failure (docs/operations.md, "Exit status") against
//! `ecatd --simulate`: one command that fails in each class, in human form (a line on
//! standard error) and with `--json` (one object on standard error, same status).

use crate::server_support;

use std::net::TcpListener;
use std::process::Stdio;

use serde_json::Value;
use server_support::Ecatd;
use sim::topology::{EscSpec, Topology};

use crate::cli_igh::{Run, ecat, ecat_with};

/// Runs `args` without and with `--json` and checks both end with `status` and class
/// `class`; returns the JSON failure.
fn fails_as(address: &str, args: &[&str], status: i32, class: &str) -> Value {
    let human = ecat(address, args);
    assert_eq!(human.code, status, "ecat {args:?}: {}", human.stderr);
    assert!(
        human.stdout.is_empty(),
        "nothing on stdout: {}",
        human.stdout
    );
    assert!(
        human.stderr.starts_with("ecat: ") || human.stderr.starts_with("error: "),
        "one message on stderr: {}",
        human.stderr
    );
    let mut with_json = vec!["--json"];
    with_json.extend_from_slice(args);
    let json = ecat(address, &with_json);
    assert_eq!(json.code, status, "ecat {with_json:?}: {}", json.stderr);
    let value = failure_json(&json);
    assert_eq!(value["class"], class, "{value}");
    assert_eq!(value["exit_code"], status, "{value}");
    assert!(
        value["message"].as_str().is_some_and(|m| !m.is_empty()),
        "{value}"
    );
    value
}

/// Standard error of a `--json` run as the one JSON object it must be.
fn failure_json(run: &Run) -> Value {
    let lines: Vec<&str> = run.stderr.lines().collect();
    assert_eq!(lines.len(), 1, "one line on stderr: {}", run.stderr);
    serde_json::from_str(lines[0]).expect("the failure is JSON")
}

/// A loopback port nothing listens on.
fn closed_port() -> u16 {
    let listener = TcpListener::bind("127.0.0.1:0").expect("a free port");
    listener.local_addr().expect("bound").port()
}

#[test]
fn each_class_of_failure_has_its_exit_status_and_json_form() {
    let ecatd = Ecatd::start(&[]);
    let address = ecatd.grpc.as_str();

    // Usage: clap's own errors, an IgH master index ecatd does not run, a bad number.
    fails_as(address, &["slaves", "--no-such-flag"], 2, "usage");
    let master = fails_as(address, &["-m", "1", "slaves"], 2, "usage");
    assert!(
        master["message"]
            .as_str()
            .unwrap()
            .contains("one master, index 0"),
        "{master}"
    );
    fails_as(address, &["upload", "-p", "0", "0x1018", "one"], 2, "usage");

    // Not found: a slave ecatd does not know.
    let unknown = fails_as(
        address,
        &["upload", "-p", "station:4242", "0x1018", "1"],
        3,
        "not_found",
    );
    assert_eq!(unknown["status"], "NOT_FOUND");
    assert_eq!(unknown["reason"], "UNKNOWN_SLAVE");
    assert!(unknown.get("abort_code").is_none(), "{unknown}");

    // Refused by the slave: an SDO abort, with its code.
    let refused = fails_as(address, &["upload", "-p", "0", "0x6000", "1"], 4, "refused");
    assert_eq!(refused["abort_code"], "0x06020000", "{refused}");
    assert_eq!(refused["reason"], "SDO_ABORT");
    assert_eq!(refused["grpc_code"], 5);
    let human = ecat(address, &["upload", "-p", "0", "0x6000", "1"]);
    assert!(human.stderr.contains("0x06020000"), "{}", human.stderr);
    // An SoE error from the slave is a refusal too (a read-only IDN).
    let soe = fails_as(
        address,
        &["soe_write", "-p", "0", "P-0-0100", "1", "--type", "u16"],
        4,
        "refused",
    );
    assert!(soe["abort_code"].as_str().is_some(), "{soe}");
    // An AL state the slave refuses, with its AL status code (the DO8 has no bootstrap).
    let al = fails_as(address, &["states", "-p", "1", "BOOT"], 4, "refused");
    assert_eq!(al["reason"], "STATE_REFUSED", "{al}");
    assert_eq!(al["abort_code"], "0x00000013", "{al}");

    // Unreachable: nothing listens at the address.
    let nobody = format!("127.0.0.1:{}", closed_port());
    let unreachable = fails_as(&nobody, &["slaves"], 6, "unreachable");
    assert!(
        unreachable["message"]
            .as_str()
            .unwrap()
            .contains("cannot connect"),
        "{unreachable}"
    );

    // Other: standard output cannot be written.
    for json in [false, true] {
        let mut args = vec!["slaves"];
        if json {
            args.insert(0, "--json");
        }
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .expect("/dev/full opens");
        let run = ecat_with(address, &args, Stdio::from(full));
        assert_eq!(run.code, 1, "{}", run.stderr);
        if json {
            assert_eq!(failure_json(&run)["class"], "other");
        } else {
            assert!(run.stderr.contains("standard output"), "{}", run.stderr);
        }
    }
}

#[test]
fn a_slave_that_answers_too_late_is_a_timeout() {
    // The CoE store (position 3) answers 10 s after each request; ecatd waits 3 s, so that neither run (human, then
    // JSON) meets the late reply of the one before.
    let mut topology = Topology::default_segment();
    topology.slaves[3].esc = EscSpec {
        response_delay_us: 10_000_000,
        ..EscSpec::default()
    };
    let file = std::env::temp_dir().join(format!("ecat-cli-timeout-{}.toml", std::process::id()));
    std::fs::write(&file, topology.to_toml().expect("the topology serialises"))
        .expect("the topology is written");
    let ecatd = Ecatd::start_with(&["--simulate", file.to_str().unwrap()], &[]);
    std::fs::remove_file(&file).expect("the topology file is removed");
    let timeout = fails_as(
        &ecatd.grpc,
        &["upload", "-p", "3", "0x2001", "0", "--type", "u32"],
        5,
        "timeout",
    );
    assert_eq!(timeout["status"], "DEADLINE_EXCEEDED", "{timeout}");
}

#[test]
fn a_missing_or_too_weak_token_is_a_permission_failure() {
    let config = std::env::temp_dir().join(format!("ecat-cli-tokens-{}.toml", std::process::id()));
    std::fs::write(
        &config,
        "[[tokens]]\nname = \"viewer\"\ntoken = \"read-secret-1-viewer\"\nrole = \"read\"\n",
    )
    .expect("the configuration is written");
    let ecatd = Ecatd::start(&["--config", config.to_str().unwrap()]);
    std::fs::remove_file(&config).expect("the configuration is removed");
    let address = ecatd.grpc.as_str();
    let none = fails_as(address, &["slaves"], 7, "permission");
    assert_eq!(none["status"], "UNAUTHENTICATED");
    let write = [
        "--token",
        "read-secret-1-viewer",
        "download",
        "-p",
        "3",
        "0x2001",
        "0",
        "--type",
        "u32",
        "7",
    ];
    let weak = fails_as(address, &write, 7, "permission");
    assert_eq!(weak["status"], "PERMISSION_DENIED");
    // The same token reads.
    let read = ecat(address, &["--token", "read-secret-1-viewer", "slaves"]);
    assert_eq!(read.code, 0, "{}", read.stderr);
}
