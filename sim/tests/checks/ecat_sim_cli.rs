//! The `ecat-sim` binary's refusals: each with a clear message on stderr and its exit code
//! (2 for a bad topology or arguments, 1 when the interface cannot be used).
//!
//! Runs as root (CI does): opening a raw socket needs CAP_NET_RAW before the interface is
//! even looked up, and the CAP_NET_RAW test drops to an unprivileged user.

use std::os::unix::fs::PermissionsExt;
use std::os::unix::process::CommandExt;
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_ecat-sim");

fn run(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().expect("run ecat-sim")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn require_root() {
    // SAFETY: geteuid has no preconditions and cannot fail.
    let euid = unsafe { libc::geteuid() };
    assert_eq!(
        euid, 0,
        "this test must run as root (raw sockets need CAP_NET_RAW); CI runs it as root"
    );
}

/// A topology file in a fresh temporary directory.
fn topology_file(name: &str, text: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("ecat-sim-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn an_unknown_interface_is_named_and_exits_1() {
    require_root();
    let out = run(&["--iface", "ecatnosuch0"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("network interface ecatnosuch0 not found"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn without_cap_net_raw_the_message_says_so_and_exits_1() {
    require_root();
    // `nobody` may not be able to reach the build directory (a checkout under a private
    // directory): run a copy from the world-readable temporary directory.
    let copy = std::env::temp_dir().join(format!("ecat-sim-nobody-{}", std::process::id()));
    std::fs::copy(BIN, &copy).expect("copy ecat-sim");
    std::fs::set_permissions(&copy, std::fs::Permissions::from_mode(0o755))
        .expect("make the copy executable for everyone");
    // `nobody`: no capabilities at all.
    let out = Command::new(&copy)
        .args(["--iface", "lo"])
        .uid(65534)
        .gid(65534)
        .output();
    let _ = std::fs::remove_file(&copy);
    let out = out.expect("run ecat-sim as nobody");
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("CAP_NET_RAW"), "{}", stderr(&out));
}

#[test]
fn a_bad_topology_file_is_named_with_the_parse_error_and_exits_2() {
    let path = topology_file(
        "bad.toml",
        "[[slave]]\nname = \"x\"\nvendor_id = \"nope\"\n",
    );
    let out = run(&["--iface", "lo", "--topology", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(
        err.contains("bad topology") && err.contains("bad.toml"),
        "{err}"
    );
    assert!(
        err.contains("vendor_id"),
        "the parse error names the field: {err}"
    );
}

#[test]
fn a_topology_that_cannot_be_built_exits_2() {
    // A drive application without CoE.
    let text = "[[slave]]\nname = \"Broken\"\nvendor_id = 1\nproduct_code = 2\n\
                application = { kind = \"drive\" }\n";
    let path = topology_file("unbuildable.toml", text);
    let out = run(&["--iface", "lo", "--topology", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("slave 0 (Broken)"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn a_missing_topology_file_and_an_empty_segment_exit_2() {
    let out = run(&["--iface", "lo", "--topology", "/nonexistent/ecat.toml"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("cannot read topology /nonexistent/ecat.toml"));
    let out = run(&["--iface", "lo", "--slaves", "0"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("no slaves"), "{}", stderr(&out));
}

#[test]
fn topology_and_slaves_together_are_a_usage_error() {
    let out = run(&["--iface", "lo", "--slaves", "3", "--topology", "x.toml"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("cannot be used with"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn an_eoe_tap_without_an_eoe_slave_to_bridge_exits_2_and_makes_no_interface() {
    // Slave 1 of the built-in segment is a digital output terminal: no EoE.
    let out = run(&[
        "--iface",
        "lo",
        "--eoe-tap",
        "eoe-cli-t1",
        "--eoe-slave",
        "1",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("--eoe-slave 1: no EoE slave at that position"),
        "{}",
        stderr(&out)
    );
    // A segment of one slave without a mailbox has nothing to bridge.
    let path = topology_file(
        "no-eoe",
        "[[slave]]\nname = \"DO\"\nvendor_id = 1\nproduct_code = 2\n",
    );
    let topology = path.to_str().unwrap();
    let out = run(&[
        "--iface",
        "lo",
        "--topology",
        topology,
        "--eoe-tap",
        "eoe-cli-t2",
    ]);
    let _ = std::fs::remove_file(&path);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("--eoe-tap: the topology has no EoE slave"),
        "{}",
        stderr(&out)
    );
    assert!(!std::path::Path::new("/sys/class/net/eoe-cli-t1").exists());
    // --eoe-slave means nothing without --eoe-tap.
    let out = run(&["--iface", "lo", "--eoe-slave", "0"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}
