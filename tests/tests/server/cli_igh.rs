//! `ecat` takes what IgH's `ethercat` users type (issue 36, item 2), against `ecatd
//! --simulate`: `-m 0`, abbreviated commands, `--address host:port`, `ip` with keyword
//! pairs, `sdos -q`, `soe_read -d`, `pdos` and `sdos` over every slave, `config` as the
//! slave configurations, `cstruct` that a C compiler takes, man pages and completions.

use crate::server_support;

use std::process::{Command, Stdio};

use serde_json::Value;
use server_support::{Ecatd, bin_dir};
use sim::topology::Topology;

/// What one `ecat` run gave.
pub struct Run {
    /// Exit status (-1: killed by a signal).
    pub code: i32,
    pub stdout: String,
    pub stderr: String,
}

/// Runs `ecat --address ADDRESS ARGS` (the address as given: `host:port` has no scheme).
pub fn ecat(address: &str, args: &[&str]) -> Run {
    ecat_with(address, args, Stdio::piped())
}

/// [`ecat`] with standard output going to `stdout` (not captured unless piped).
pub fn ecat_with(address: &str, args: &[&str], stdout: Stdio) -> Run {
    let output = Command::new(bin_dir().join("ecat"))
        .args(["--address", address])
        .args(args)
        .stdout(stdout)
        .output()
        .expect("ecat runs");
    Run {
        code: output.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&output.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&output.stderr).into_owned(),
    }
}

/// Standard output of a run that must succeed.
fn ok(address: &str, args: &[&str]) -> String {
    let run = ecat(address, args);
    assert_eq!(run.code, 0, "ecat {args:?}: {}", run.stderr);
    run.stdout
}

/// The `--json` output of a run that must succeed.
fn json(address: &str, args: &[&str]) -> Value {
    let mut all = vec!["--json"];
    all.extend_from_slice(args);
    serde_json::from_str(&ok(address, &all)).expect("ecat --json prints JSON")
}

#[test]
fn master_zero_abbreviations_and_a_bare_address_are_taken() {
    let ecatd = Ecatd::start(&[]);
    // The address without http://, as grpcurl and IgH users write host:port.
    let bare = ecatd.grpc.as_str();
    let slaves = ok(bare, &["slaves"]);
    assert_eq!(
        slaves.lines().count(),
        Topology::default_segment().slaves.len(),
        "{slaves}"
    );
    assert_eq!(ok(&format!("http://{bare}"), &["slaves"]), slaves);

    // IgH's -m in its forms, before or after the command.
    for args in [
        &["-m", "0", "slaves"][..],
        &["--master", "0", "slaves"],
        &["--master=0", "slaves"],
        &["slaves", "-m", "0"],
        &["-m", "-", "slaves"],
        &["-m", "0-0", "slaves"],
    ] {
        assert_eq!(ok(bare, args), slaves, "{args:?}");
    }
    for index in ["1", "0,1", "0-3"] {
        let run = ecat(bare, &["-m", index, "slaves"]);
        assert_eq!(run.code, 2, "-m {index}: {}", run.stderr);
        assert!(run.stderr.contains("one master, index 0"), "{}", run.stderr);
    }

    // Abbreviations: a unique prefix runs its command; a full name wins over a longer one.
    assert_eq!(ok(bare, &["sl"]), slaves);
    assert_eq!(ok(bare, &["-m", "0", "sla"]), slaves);
    assert_eq!(
        ok(bare, &["up", "-p", "0", "0x1018", "1"]),
        ok(bare, &["upload", "-p", "0", "0x1018", "1"])
    );
    assert_eq!(
        json(bare, &["pd", "-p", "0"])["entries"].is_array(),
        true,
        "pd is pd, not pdos"
    );
    let ambiguous = ecat(bare, &["s"]);
    assert_eq!(ambiguous.code, 2, "{}", ambiguous.stderr);
    for candidate in ["slaves", "sdos", "states", "soe_read", "sii_read"] {
        assert!(
            ambiguous.stderr.contains(candidate),
            "{candidate} missing: {}",
            ambiguous.stderr
        );
    }
    let unknown = ecat(bare, &["zzz"]);
    assert_eq!(unknown.code, 2, "{}", unknown.stderr);
}
