//! The `ecat` command line against `ecatd --simulate`: every subcommand, human and JSON
//! output, values from the simulator's topology.

mod server_support;

use std::process::Command;

use serde_json::Value;
use server_support::{Ecatd, bin_dir};
use sim::topology::{SIM_VENDOR_ID, Topology};

struct Ecat<'a> {
    ecatd: &'a Ecatd,
}

impl Ecat<'_> {
    fn run(&self, args: &[&str]) -> (bool, String, String) {
        let output = Command::new(bin_dir().join("ecat"))
            .args(["--address", &format!("http://{}", self.ecatd.grpc)])
            .args(args)
            .output()
            .expect("ecat runs");
        (
            output.status.success(),
            String::from_utf8_lossy(&output.stdout).into_owned(),
            String::from_utf8_lossy(&output.stderr).into_owned(),
        )
    }

    fn ok(&self, args: &[&str]) -> String {
        let (ok, stdout, stderr) = self.run(args);
        assert!(ok, "ecat {args:?} failed: {stderr}");
        stdout
    }

    fn json(&self, args: &[&str]) -> Value {
        let mut all = vec!["--json"];
        all.extend_from_slice(args);
        serde_json::from_str(&self.ok(&all)).expect("ecat --json prints JSON")
    }
}

#[test]
fn every_subcommand() {
    let ecatd = Ecatd::start(&[]);
    let ecat = Ecat { ecatd: &ecatd };
    let topology = Topology::default_segment();

    let human = ecat.ok(&["slaves"]);
    for spec in &topology.slaves {
        assert!(
            human.contains(&spec.name),
            "{} missing:\n{human}",
            spec.name
        );
    }
    let slaves = ecat.json(&["slaves"]);
    assert_eq!(slaves.as_array().unwrap().len(), topology.slaves.len());
    assert_eq!(slaves[0]["vendor_id"], SIM_VENDOR_ID);

    assert_eq!(
        ecat.ok(&["upload", "-p", "0", "0x1018", "1", "--type", "u32"])
            .trim(),
        SIM_VENDOR_ID.to_string()
    );
    // Without --type the slave's SDO Information names the type (0x1018:01 is UNSIGNED32).
    assert_eq!(
        ecat.ok(&["upload", "-p", "0", "0x1018", "1"]).trim(),
        SIM_VENDOR_ID.to_string()
    );
    assert_eq!(
        ecat.ok(&["upload", "-p", "0", "0x1008", "0"]).trim(),
        topology.slaves[0].name
    );
    ecat.ok(&[
        "download",
        "-p",
        "3",
        "0x2001",
        "0",
        "--type",
        "u32",
        "0xdeadbeef",
    ]);
    assert_eq!(
        ecat.json(&["upload", "-p", "#1004", "0x2001", "0"])["data"],
        "efbeadde"
    );
    let (ok, _, stderr) = ecat.run(&["upload", "-p", "0", "0x6000", "1"]);
    assert!(!ok && stderr.contains("0x06020000"), "{stderr}");

    let sdos = ecat.ok(&["sdos", "-p", "3"]);
    assert!(sdos.contains("0x2001, \"Parameter\""), "{sdos}");

    assert_eq!(
        ecat.ok(&["soe_read", "0x8064", "--type", "u16"]).trim(),
        "253"
    );
    let (ok, _, stderr) = ecat.run(&["soe_write", "0x8064", "1", "--type", "u16"]);
    assert!(!ok && stderr.contains("Aborted"), "read-only IDN: {stderr}");

    let dir = std::env::temp_dir().join(format!("ecat-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let firmware = dir.join("firmware.bin");
    ecat.ok(&["foe_read", "firmware.bin", "-o", firmware.to_str().unwrap()]);
    let expected: Vec<u8> = (0..topology.slaves[0].foe_files[0].size)
        .map(|i| (i % 251) as u8)
        .collect();
    assert_eq!(std::fs::read(&firmware).unwrap(), expected);
    let written = ecat.json(&["foe_write", "update.bin", firmware.to_str().unwrap()]);
    assert_eq!(written["written"], expected.len());
    std::fs::remove_dir_all(&dir).unwrap();

    assert_eq!(
        ecat.json(&["voe", "0x1164", "1", "00ff0f"])["data"],
        "ff00f0"
    );

    ecat.ok(&[
        "ip",
        "-p",
        "4",
        "--ip",
        "192.168.100.46",
        "--mask",
        "255.255.255.0",
    ]);
    assert_eq!(ecat.json(&["ip", "-p", "4"])["ip"], "192.168.100.46");

    assert_eq!(ecat.json(&["alias", "-p", "2", "0x0042"])["alias"], 0x42);
    assert!(ecat.ok(&["slaves"]).contains("DI8"));
    assert_eq!(
        ecat.json(&["reg_read", "-p", "@0x42", "0x12", "2"])["data"],
        "4200",
        "alias register"
    );

    ecat.ok(&["reg_write", "-p", "1", "0xa00", "a5"]);
    let sii = ecat.json(&["sii_read", "-p", "0"]);
    assert_eq!(&sii["data"].as_str().unwrap()[32..40], "010000e0");
    ecat.ok(&["sii_write", "-p", "2", "0x20", "3412"]);
    assert_eq!(
        &ecat.json(&["sii_read", "-p", "2"])["data"]
            .as_str()
            .unwrap()[0x80..0x84],
        "3412"
    );

    let states = ecat.json(&["states", "-p", "1", "PREOP"]);
    assert_eq!(states[0]["state"], "PREOP");
    let all = ecat.json(&["states", "SAFEOP"]);
    assert!(
        all.as_array()
            .unwrap()
            .iter()
            .all(|s| s["state"] == "SAFEOP"),
        "{all}"
    );

    let bound = ecatd.gateway_addr();
    let human = ecat.ok(&["gateway"]);
    assert!(
        human.contains(&format!("running on {bound}")),
        "gateway table:\n{human}"
    );
    assert!(human.contains("master 1"), "{human}");
    let status = ecat.json(&["gateway"]);
    assert_eq!(status["running"], true);
    assert_eq!(status["port"], bound.port());
    assert_eq!(status["stats"]["total_requests"], 0);
    let stopped = ecat.json(&["gateway", "stop"]);
    assert_eq!(stopped["running"], false);
    assert_eq!(stopped["bound_address"], "");
    assert!(ecat.ok(&["gateway"]).contains("gateway      stopped"));
    let started = ecat.json(&["gateway", "start"]);
    assert_eq!(started["running"], true);
    assert_eq!(
        started["bound_address"],
        format!("127.0.0.1:{}", started["port"])
    );
}
