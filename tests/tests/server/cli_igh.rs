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
    assert!(
        json(bare, &["pd", "-p", "0"])["entries"].is_array(),
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

#[test]
fn ip_takes_igh_keyword_pairs_and_a_prefix() {
    let ecatd = Ecatd::start(&[]);
    let address = ecatd.grpc.as_str();
    // IgH's form: keyword/value pairs, the address with a prefix length.
    ok(
        address,
        &[
            "ip",
            "-p",
            "4",
            "addr",
            "192.168.10.5/24",
            "default",
            "192.168.10.1",
            "dns",
            "192.168.10.2",
            "name",
            "drive4",
        ],
    );
    let ip = json(address, &["ip", "-p", "4"]);
    assert_eq!(ip["ip"], "192.168.10.5", "{ip}");
    assert_eq!(ip["subnet_mask"], "255.255.255.0", "{ip}");
    assert_eq!(ip["default_gateway"], "192.168.10.1", "{ip}");
    assert_eq!(ip["dns_server"], "192.168.10.2", "{ip}");
    assert_eq!(ip["dns_name"], "drive4", "{ip}");

    // The option form with a prefix, read by the same parser.
    ok(address, &["ip", "-p", "4", "--ip", "10.77.0.2/16"]);
    let ip = json(address, &["ip", "-p", "4"]);
    assert_eq!(ip["ip"], "10.77.0.2", "{ip}");
    assert_eq!(ip["subnet_mask"], "255.255.0.0", "{ip}");

    // A bad prefix, a keyword without its value, an unknown keyword: usage errors, and
    // nothing changed on the slave.
    for args in [
        &["ip", "-p", "4", "addr", "10.1.1.1/33"][..],
        &["ip", "-p", "4", "addr"],
        &["ip", "-p", "4", "gateway", "10.1.1.1"],
    ] {
        let run = ecat(address, args);
        assert_eq!(run.code, 2, "{args:?}: {}", run.stderr);
    }
    assert_eq!(json(address, &["ip", "-p", "4"])["ip"], "10.77.0.2");
}

#[test]
fn sdos_over_every_slave_quietly_and_soe_read_on_drive_zero() {
    let ecatd = Ecatd::start(&[]);
    let address = ecatd.grpc.as_str();
    let slaves = json(address, &["slaves"]);
    let with_coe: Vec<u64> = slaves
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| {
            s["mailbox_protocols"]
                .as_array()
                .is_some_and(|p| p.iter().any(|p| p == "CoE"))
        })
        .map(|s| s["position"].as_u64().unwrap())
        .collect();
    assert!(with_coe.len() > 1, "{slaves}");

    // -q: the objects only, without their entries.
    let quiet = ok(address, &["sdos", "-q"]);
    let headers: Vec<&str> = quiet.lines().filter(|l| l.starts_with("===")).collect();
    let expected: Vec<String> = with_coe
        .iter()
        .map(|p| format!("=== Master 0, Slave {p} ==="))
        .collect();
    assert_eq!(headers, expected, "{quiet}");
    assert!(quiet.contains("SDO 0x2001, \"Parameter\""), "{quiet}");
    assert!(!quiet.lines().any(|l| l.starts_with("  0x")), "{quiet}");
    // The selected slave's list is the same as its part of the whole.
    let one = ok(address, &["sdos", "-p", "3", "-q"]);
    let part: Vec<&str> = quiet
        .lines()
        .skip_while(|l| *l != "=== Master 0, Slave 3 ===")
        .skip(1)
        .take_while(|l| !l.starts_with("==="))
        .collect();
    assert_eq!(one.trim_end().lines().collect::<Vec<_>>(), part);
    // Without -q the entries follow their object.
    let full = ok(address, &["sdos", "-p", "3"]);
    assert!(
        full.contains("  0x2001:00, rwrwrw, uint32, 32 bit"),
        "{full}"
    );
    let everything = json(address, &["sdos", "-q"]);
    assert_eq!(everything.as_array().unwrap().len(), with_coe.len());

    // soe_read -d 0 (IgH's drive option) reads the same IDN as without it.
    let plain = ok(
        address,
        &["soe_read", "-p", "0", "P-0-0100", "-t", "uint16"],
    );
    assert_eq!(plain.trim(), "253");
    assert_eq!(
        ok(
            address,
            &["soe_read", "-p", "0", "-d", "0", "P-0-0100", "-t", "uint16"]
        ),
        plain
    );
    assert_eq!(
        ok(
            address,
            &[
                "soe_read", "-p", "0", "--drive", "0", "P-0-0100", "-t", "uint16"
            ]
        ),
        plain
    );
}

#[test]
fn config_lists_the_slave_configurations() {
    let file = std::env::temp_dir().join(format!("ecat-cli-config-{}.toml", std::process::id()));
    std::fs::write(
        &file,
        "[[slave]]\nstation = 1004\n\n[[slave.startup]]\ntransition = \"PS\"\nindex = 0x2001\n\
         subindex = 0\nvalue = 8\ntype = \"u32\"\n\n\
         [[slave]]\nposition = 9\nvendor_id = 2\nproduct_code = 3\n",
    )
    .expect("the configuration is written");
    let ecatd = Ecatd::start(&["--config", file.to_str().unwrap()]);
    std::fs::remove_file(&file).expect("the configuration is removed");
    let address = ecatd.grpc.as_str();
    let lines: Vec<Vec<String>> = ok(address, &["config"])
        .lines()
        .map(|l| l.split_whitespace().map(str::to_owned).collect())
        .collect();
    assert_eq!(lines.len(), 2, "{lines:?}");
    // The store at station 1004 is attached (position 3); nothing answers at position 9.
    assert_eq!(lines[0][0], "#1004");
    assert_eq!(lines[0][2], "3");
    assert_eq!(lines[0][3], "OP");
    assert_eq!(lines[1], ["0:9", "0x00000002/0x00000003", "-", "-"]);
    let verbose = ok(address, &["config", "-v"]);
    assert!(verbose.contains("Attached slave: 3 (OP)"), "{verbose}");
    assert!(verbose.contains("PS 0x2001:00 = 8 (u32)"), "{verbose}");
    assert!(verbose.contains("Attached slave: none"), "{verbose}");
    let configs = json(address, &["config"]);
    assert_eq!(configs[0]["attached"], 3, "{configs}");
    // ecatd's whole configuration moved to --toml.
    let toml = ok(address, &["config", "--toml"]);
    assert!(toml.contains("station = 1004"), "{toml}");
    assert!(toml.contains("[bus]"), "{toml}");

    // Without [[slave]] entries every slave found is configured as it is.
    let plain = Ecatd::start(&[]);
    let listed = ok(&plain.grpc, &["config"]);
    let topology = Topology::default_segment();
    assert_eq!(listed.lines().count(), topology.slaves.len(), "{listed}");
    assert!(listed.lines().all(|l| l.ends_with("OP")), "{listed}");
}

/// ecrt.h's public declarations the output of `cstruct` uses, as IgH's header declares them.
const ECRT_SUBSET: &str = "#include <stddef.h>
#include <stdint.h>
typedef enum { EC_DIR_INVALID, EC_DIR_OUTPUT, EC_DIR_INPUT, EC_DIR_COUNT } ec_direction_t;
typedef enum { EC_WD_DEFAULT, EC_WD_ENABLE, EC_WD_DISABLE } ec_watchdog_mode_t;
typedef struct { uint16_t index; uint8_t subindex; uint8_t bit_length; } ec_pdo_entry_info_t;
typedef struct {
    uint16_t index;
    unsigned int n_entries;
    ec_pdo_entry_info_t const *entries;
} ec_pdo_info_t;
typedef struct {
    uint8_t index;
    ec_direction_t dir;
    unsigned int n_pdos;
    ec_pdo_info_t const *pdos;
    ec_watchdog_mode_t watchdog_mode;
} ec_sync_info_t;
";

#[test]
fn cstruct_output_compiles_against_igh_types() {
    let ecatd = Ecatd::start(&[]);
    let c = ok(&ecatd.grpc, &["cstruct"]);
    for n in 0..Topology::default_segment().slaves.len() {
        assert!(
            c.contains(&format!("ec_sync_info_t slave_{n}_syncs[] = {{")),
            "{c}"
        );
    }
    assert!(c.contains("{0x7000, 0x01, 1}, /* Output 1 */"), "{c}");
    assert!(
        c.contains("EC_DIR_OUTPUT") && c.contains("EC_DIR_INPUT"),
        "{c}"
    );
    assert!(c.contains("    {0xff}\n};"), "{c}");
    let Some(cc) = ["cc", "gcc", "clang"]
        .into_iter()
        .find(|cc| Command::new(cc).arg("--version").output().is_ok())
    else {
        eprintln!("SKIPPED the compile: no C compiler (cc, gcc, clang) on this machine");
        return;
    };
    let dir = std::env::temp_dir().join(format!("ecat-cstruct-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let source = dir.join("slaves.c");
    std::fs::write(&source, format!("{ECRT_SUBSET}\n{c}")).unwrap();
    let compiled = Command::new(cc)
        .args(["-std=c99", "-Wall", "-Werror", "-c"])
        .arg(&source)
        .arg("-o")
        .arg(dir.join("slaves.o"))
        .output()
        .expect("the compiler runs");
    let object = dir.join("slaves.o").exists();
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(
        compiled.status.success() && object,
        "{cc} refused the output:\n{}\n{c}",
        String::from_utf8_lossy(&compiled.stderr)
    );
}

#[test]
fn man_pages_and_completions_name_every_command() {
    // Neither needs ecatd: the address is never dialled.
    let nowhere = "127.0.0.1:9";
    let commands: Vec<String> = {
        let help = ok(nowhere, &["--help"]);
        help.lines()
            .skip_while(|l| !l.starts_with("Commands:"))
            .skip(1)
            .take_while(|l| l.starts_with("  "))
            .filter_map(|l| l.split_whitespace().next().map(str::to_owned))
            .filter(|c| c != "help")
            .collect()
    };
    assert!(commands.len() > 30, "{commands:?}");
    for must in ["slaves", "cstruct", "config", "ip", "completions", "man"] {
        assert!(commands.iter().any(|c| c == must), "{must}: {commands:?}");
    }
    let top = ok(nowhere, &["man"]);
    for command in &commands {
        assert!(top.contains(command.as_str()), "ecat.1 lacks {command}");
        let page = ok(nowhere, &["man", command]);
        assert!(
            page.contains(&format!(".TH ecat-{command} 1")),
            "ecat man {command}:\n{page}"
        );
    }
    assert!(ok(nowhere, &["man", "ecatd"]).contains(".TH ecatd 8"));
    let dir = std::env::temp_dir().join(format!("ecat-man-{}", std::process::id()));
    ok(nowhere, &["man", "--out", dir.to_str().unwrap()]);
    for command in &commands {
        let page = std::fs::read_to_string(dir.join(format!("ecat-{command}.1")))
            .unwrap_or_else(|err| panic!("ecat-{command}.1: {err}"));
        assert!(!page.is_empty());
    }
    assert!(dir.join("ecat.1").exists() && dir.join("ecatd.8").exists());
    std::fs::remove_dir_all(&dir).unwrap();

    for shell in ["bash", "zsh", "fish"] {
        let script = ok(nowhere, &["completions", shell]);
        for command in &commands {
            assert!(script.contains(command.as_str()), "{shell} lacks {command}");
        }
        let ecatd = Command::new(bin_dir().join("ecatd"))
            .args(["--completions", shell])
            .output()
            .expect("ecatd runs");
        assert!(ecatd.status.success());
        let script = String::from_utf8_lossy(&ecatd.stdout);
        for flag in ["simulate", "grpc-listen", "completions"] {
            assert!(script.contains(flag), "ecatd {shell} lacks {flag}");
        }
    }
    let page = Command::new(bin_dir().join("ecatd"))
        .arg("--man")
        .output()
        .expect("ecatd runs");
    assert!(String::from_utf8_lossy(&page.stdout).contains(".TH ecatd 8"));
}
