//! The `ecat` command line against `ecatd --simulate`: every subcommand, human and JSON
//! output, values from the simulator's topology.

use crate::server_support;

use std::process::Command;
use std::time::{Duration, Instant};

use serde_json::Value;
use server_support::streaming::Streaming;
use server_support::{Ecatd, bin_dir};
use sim::topology::{SIM_VENDOR_ID, Topology};

struct Ecat<'a> {
    ecatd: &'a Ecatd,
}

impl Ecat<'_> {
    fn run(&self, args: &[&str]) -> (bool, String, String) {
        let output = server_support::ecat_output(&self.ecatd.grpc, args);
        (
            output.status.success(),
            String::from_utf8_lossy(&output.stdout).into_owned(),
            String::from_utf8_lossy(&output.stderr).into_owned(),
        )
    }

    /// Standard output as bytes, after checking the command succeeded.
    fn raw(&self, args: &[&str]) -> Vec<u8> {
        let output = server_support::ecat_output(&self.ecatd.grpc, args);
        assert!(
            output.status.success(),
            "ecat {args:?} failed: {}",
            String::from_utf8_lossy(&output.stderr)
        );
        output.stdout
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
        ecat.ok(&["upload", "-p", "0", "0x1018", "1", "--type", "uint32"])
            .trim(),
        format!("0x{SIM_VENDOR_ID:08x} {SIM_VENDOR_ID}"),
        "IgH's upload line"
    );
    // Without --type the slave's SDO Information names the type (0x1018:01 is UNSIGNED32).
    assert_eq!(
        ecat.ok(&["upload", "-p", "0", "0x1018", "1"]).trim(),
        format!("0x{SIM_VENDOR_ID:08x} {SIM_VENDOR_ID}")
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
    assert!(sdos.contains("SDO 0x2001, \"Parameter\""), "{sdos}");
    assert!(
        sdos.contains("  0x2001:00, rwrwrw, uint32, 32 bit, \"Parameter\""),
        "entries with access, type, bit length and name:\n{sdos}"
    );

    assert_eq!(
        ecat.ok(&["soe_read", "-p", "0", "0x8064", "--type", "u16"])
            .trim(),
        "253"
    );
    assert_eq!(
        ecat.ok(&["soe_read", "-p", "0", "P-0-0100", "-t", "uint16"])
            .trim(),
        "253",
        "IDN syntax"
    );
    let (ok, _, stderr) = ecat.run(&["soe_write", "-p", "0", "P-0-0100", "1", "--type", "u16"]);
    assert!(
        !ok && stderr.contains("FailedPrecondition"),
        "read-only IDN: {stderr}"
    );

    let dir = std::env::temp_dir().join(format!("ecat-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let firmware = dir.join("firmware.bin");
    ecat.ok(&[
        "foe_read",
        "-p",
        "0",
        "firmware.bin",
        "-o",
        firmware.to_str().unwrap(),
    ]);
    let expected: Vec<u8> = (0..topology.slaves[0].foe_files[0].size)
        .map(|i| (i % 251) as u8)
        .collect();
    assert_eq!(std::fs::read(&firmware).unwrap(), expected);
    // IgH's order: the local file, then -o for the name on the slave.
    let written = ecat.json(&[
        "foe_write",
        "-p",
        "0",
        firmware.to_str().unwrap(),
        "-o",
        "update.bin",
    ]);
    assert_eq!(written["written"], expected.len());
    std::fs::remove_dir_all(&dir).unwrap();

    assert_eq!(
        ecat.json(&["voe", "-p", "0", "0x1164", "1", "00ff0f"])["data"],
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

/// Every line of `ecat slaves` in IgH's columns: position, alias:relpos, state, flag, name.
fn igh_line(line: &str) -> Option<(u32, u32, u32, String, String)> {
    let mut fields = line.split("  ").filter(|f| !f.is_empty()).map(str::trim);
    let position = fields.next()?.parse().ok()?;
    let (alias, relpos) = fields.next()?.split_once(':')?;
    let state = fields.next()?.to_owned();
    let flag = fields.next()?;
    let name = fields.collect::<Vec<_>>().join("  ");
    (flag == "+" || flag == "E").then_some(())?;
    Some((
        position,
        alias.parse().ok()?,
        relpos.parse().ok()?,
        state,
        name,
    ))
}

#[test]
fn slaves_in_igh_columns_and_every_slave_name_form() {
    let ecatd = Ecatd::start(&[]);
    let ecat = Ecat { ecatd: &ecatd };
    let topology = Topology::default_segment();
    ecat.ok(&["alias", "-p", "2", "66"]);
    let table = ecat.ok(&["slaves"]);
    let rows: Vec<_> = table
        .lines()
        .map(|l| igh_line(l).unwrap_or_else(|| panic!("{l:?}")))
        .collect();
    assert_eq!(rows.len(), topology.slaves.len(), "{table}");
    // Slaves 0 and 1 count from the start, 2 carries the alias, 3 and 4 count from it.
    let relpos: Vec<(u32, u32)> = rows.iter().map(|r| (r.1, r.2)).collect();
    assert_eq!(
        relpos,
        [(0, 0), (0, 1), (66, 0), (66, 1), (66, 2)],
        "{table}"
    );
    for (row, spec) in rows.iter().zip(&topology.slaves) {
        assert_eq!(row.4, spec.name);
    }
    // The same slave (position 3, station 1004) by each name form.
    for args in [
        vec!["-p", "3"],
        vec!["-p", "pos:3"],
        vec!["-p", "station:1004"],
        vec!["-p", "#0x3ec"],
        vec!["-p", "66:1"],
        vec!["-p", "alias:66+1"],
        vec!["-p", "alias:0x42+1"],
        vec!["-a", "0x42", "-p", "1"],
    ] {
        let mut all = vec!["reg_read"];
        all.extend(&args);
        all.extend(["0x10", "2"]);
        assert_eq!(
            ecat.json(&all)["data"],
            hex_le(1004),
            "station register of {args:?}"
        );
    }
    assert_eq!(
        ecat.json(&["reg_read", "-a", "66", "0x10", "2"])["data"],
        hex_le(1003)
    );
    let (ok, _, stderr) = ecat.run(&["reg_read", "-p", "alias:66+9", "0x10", "2"]);
    assert!(!ok && stderr.contains("NotFound"), "{stderr}");
    let (ok, _, stderr) = ecat.run(&["reg_read", "-p", "slot:3", "0x10", "2"]);
    assert!(!ok && stderr.contains("bad slave name"), "{stderr}");

    let verbose = ecat.ok(&["slaves", "-v", "-p", "1"]);
    for part in [
        "=== Master 0, Slave 1 ===",
        "Vendor Id:       0x",
        "Distributed clocks: yes",
        "Port  Type  Link  Loop    Signal",
        "   0  MII   up    open    yes",
        "Mailboxes:",
        "Name: ECATD-SIM DO8",
    ] {
        assert!(verbose.contains(part), "{part:?} missing:\n{verbose}");
    }
    assert!(!verbose.contains("Slave 2 ==="), "-p selects one slave");
    let one = ecat.json(&["slaves", "-v", "-p", "0"]);
    assert_eq!(one[0]["esc"]["mailboxes"]["protocols"][0], "CoE", "{one}");
}

fn hex_le(value: u16) -> String {
    value
        .to_le_bytes()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[test]
fn a_write_without_a_slave_on_a_multi_slave_segment_is_refused_and_changes_nothing() {
    let ecatd = Ecatd::start(&[]);
    let ecat = Ecat { ecatd: &ecatd };
    let before = ecat.json(&["upload", "-p", "3", "0x2001", "0"])["data"].clone();
    for args in [
        vec!["download", "0x2001", "0", "0x55", "--type", "u32"],
        vec!["reg_write", "0xa00", "a5"],
        vec!["alias", "0x99"],
        vec!["sii_write", "/nonexistent/image.bin"],
    ] {
        let (ok, _, stderr) = ecat.run(&args);
        assert!(!ok, "{args:?} ran without a slave");
        if args[0] != "sii_write" {
            assert!(
                stderr.contains("works on one slave and the segment has 5")
                    && stderr.contains("-p POSITION"),
                "{args:?}: {stderr}"
            );
        }
    }
    assert_eq!(
        ecat.json(&["upload", "-p", "3", "0x2001", "0"])["data"],
        before
    );
    assert_eq!(
        ecat.json(&["reg_read", "-p", "0", "0x12", "2"])["data"],
        "0000",
        "no alias set"
    );
}

#[test]
fn foe_read_and_sii_read_print_the_exact_bytes() {
    let ecatd = Ecatd::start(&[]);
    let ecat = Ecat { ecatd: &ecatd };
    let topology = Topology::default_segment();
    let expected: Vec<u8> = (0..topology.slaves[0].foe_files[0].size)
        .map(|i| (i % 251) as u8)
        .collect();
    assert_eq!(ecat.raw(&["foe_read", "-p", "0", "firmware.bin"]), expected);
    let sii = ecat.raw(&["sii_read", "-p", "0"]);
    let hex = ecat.json(&["sii_read", "-p", "0"])["data"]
        .as_str()
        .unwrap()
        .to_owned();
    let text: String = sii.iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(text, hex);
    // Words 8-11: vendor id, product code of the simulated drive.
    assert_eq!(&sii[16..20], &SIM_VENDOR_ID.to_le_bytes());
}

#[test]
fn sii_write_checks_the_checksum_of_the_image() {
    let ecatd = Ecatd::start(&[]);
    let ecat = Ecat { ecatd: &ecatd };
    let dir = std::env::temp_dir().join(format!("ecat-sii-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let original = ecat.raw(&["sii_read", "-p", "2"]);
    // Word 5 (reserved) changed, word 7 left: the checksum no longer matches.
    let mut image = original.clone();
    image[10] ^= 0x5a;
    let file = dir.join("changed.bin");
    std::fs::write(&file, &image).unwrap();
    let (ok, _, stderr) = ecat.run(&["sii_write", "-p", "2", file.to_str().unwrap()]);
    assert!(!ok && stderr.contains("checksum"), "{stderr}");
    assert_eq!(
        ecat.raw(&["sii_read", "-p", "2"]),
        original,
        "nothing written"
    );
    ecat.ok(&["sii_write", "-p", "2", "--fix", file.to_str().unwrap()]);
    let written = ecat.raw(&["sii_read", "-p", "2"]);
    assert_eq!(written[10], image[10]);
    assert_ne!(written[14], original[14], "checksum recomputed");
    assert_eq!(&written[15..], &image[15..]);
    // The recomputed image is valid: writing it back unchanged is accepted.
    std::fs::write(&file, &written).unwrap();
    ecat.ok(&["sii_write", "-p", "2", file.to_str().unwrap()]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn master_version_rescan_crc_graph_pdos_completion_and_man() {
    let ecatd = Ecatd::start(&[]);
    let ecat = Ecat { ecatd: &ecatd };
    let master = ecat.ok(&["master"]);
    let status = ecat.json(&["master"]);
    // `simulate`, or the interface when the suite runs over veth.
    let link = status["link"].as_str().unwrap().to_owned();
    assert!(!link.is_empty());
    assert!(
        master.contains("Slaves: 5") && master.contains(&format!("({link})")),
        "{master}"
    );
    assert_eq!(status["ready"], true);
    assert_eq!(status["dc_reference"], 0, "the drive is the first DC slave");
    assert!(status["frames_sent"].as_u64().unwrap() > 0);
    let version = ecat.ok(&["version"]);
    let expected = format!("ecat {0}\necatd {0}\n", env!("CARGO_PKG_VERSION"));
    assert_eq!(version, expected);
    assert_eq!(ecat.json(&["rescan"])["slaves"], 5);
    let crc = ecat.ok(&["crc"]);
    assert!(crc.starts_with("Pos  |CRC A|"), "{crc}");
    assert_eq!(crc.lines().count(), 6, "{crc}");
    let graph = ecat.ok(&["graph"]);
    assert!(graph.starts_with("digraph"), "{graph}");
    for edge in ["master -> slave0", "slave0 -> slave1", "slave3 -> slave4"] {
        assert!(graph.contains(edge), "{edge}: {graph}");
    }
    let pdos = ecat.ok(&["pdos", "-p", "0"]);
    assert!(
        pdos.contains("RxPDO 0x1600") && pdos.contains("PDO entry 0x6040:00, 16 bit"),
        "{pdos}"
    );
    let bash = ecat.ok(&["completion", "bash"]);
    assert!(
        bash.contains("foe_read") && bash.contains("sii_write"),
        "bash completion"
    );
    let man = ecat.ok(&["man"]);
    assert!(
        man.starts_with(".ie") || man.contains(".TH ecat"),
        "roff: {}",
        &man[..80.min(man.len())]
    );
}

/// Bytes from bit `offset` of `image`, `bits` long, as a little-endian number.
fn bits_at(image: &[u8], offset: u64, bits: u64) -> u64 {
    (0..bits).fold(0, |value, i| {
        let bit = offset + i;
        let set = image[(bit / 8) as usize] >> (bit % 8) & 1;
        value | u64::from(set) << i
    })
}

#[test]
fn domains_and_data_show_the_process_image_as_laid_out() {
    let ecatd = Ecatd::start(&[]);
    let ecat = Ecat { ecatd: &ecatd };
    let topology = Topology::default_segment();

    let domains = ecat.json(&["domains", "-v"]);
    let domains = domains.as_array().unwrap();
    assert_eq!(domains.len(), 1, "one default group: {domains:?}");
    let d = &domains[0];
    assert_eq!(d["index"], 0);
    assert_eq!(d["logical_address"], 0);
    // Every slave's outputs then inputs, whole bytes each.
    let bytes = |rx: bool, spec: &sim::topology::SlaveSpec| -> u64 {
        let bits: u32 = spec
            .pdos
            .iter()
            .filter(|p| p.is_rx() == rx)
            .map(|p| p.bits())
            .sum();
        u64::from(bits.div_ceil(8))
    };
    let size: u64 = topology
        .slaves
        .iter()
        .map(|s| bytes(true, s) + bytes(false, s))
        .sum();
    assert_eq!(d["size"], size);
    assert_eq!(d["data"].as_str().unwrap().len() as u64, 2 * size);
    assert_eq!(d["last_wkc"], d["expected_wkc"], "{d}");
    assert!(d["expected_wkc"].as_u64().unwrap() > 0);
    let with_pdos: Vec<u64> = (0u64..)
        .zip(&topology.slaves)
        .filter(|(_, s)| !s.pdos.is_empty())
        .map(|(p, _)| p)
        .collect();
    assert_eq!(d["slaves"], serde_json::json!(with_pdos));
    let expected: Vec<(u64, u64, u64)> = topology
        .slaves
        .iter()
        .flat_map(|s| {
            let mut pdos: Vec<_> = s.pdos.iter().collect();
            pdos.sort_by_key(|p| !p.is_rx());
            pdos.into_iter()
                .flat_map(|p| p.entries.iter())
                .map(|e| (u64::from(e.index), u64::from(e.subindex), u64::from(e.bits)))
                .collect::<Vec<_>>()
        })
        .collect();
    let entries: Vec<(u64, u64, u64)> = d["entries"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["index"].as_u64().unwrap(),
                e["subindex"].as_u64().unwrap(),
                e["bit_length"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(entries, expected);
    let human = ecat.ok(&["domains", "-v"]);
    assert!(
        human.starts_with(&format!(
            "Domain0: LogBaseAddr 0x00000000, Size {size:>3}, WorkingCounter "
        )),
        "{human}"
    );
    assert!(human.contains("0x6041:00"), "{human}");

    // `data`: the raw image, where the drive's statusword is what an upload reads.
    let image = ecat.raw(&["data"]);
    assert_eq!(image.len() as u64, size);
    let statusword = d["entries"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["index"] == 0x6041)
        .unwrap()["bit_offset"]
        .as_u64()
        .unwrap();
    let uploaded = ecat.json(&["upload", "-p", "0", "0x6041", "0", "--type", "uint16"]);
    assert_eq!(
        bits_at(&image, statusword, 16).to_string(),
        uploaded["value"].as_str().unwrap(),
        "{uploaded}"
    );
    let dump = ecat.ok(&["data", "--hex"]);
    assert!(dump.starts_with("0x00000000: "), "{dump}");
    assert_eq!(
        dump.split_whitespace()
            .filter(|w| !w.ends_with(':'))
            .count() as u64,
        size
    );

    // Bad input: a domain that does not exist.
    let (ok, _, stderr) = ecat.run(&["domains", "-d", "7"]);
    assert!(!ok && stderr.contains("no domain 7"), "{stderr}");
    let (ok, _, stderr) = ecat.run(&["data", "-d", "x"]);
    assert!(!ok && stderr.contains("domain"), "{stderr}");
}

#[test]
fn diag_decodes_the_drives_diagnosis_history() {
    let ecatd = Ecatd::start(&[]);
    let ecat = Ecat { ecatd: &ecatd };
    let diag = ecat.json(&["diag", "-p", "0"]);
    let sent = sim::topology::diag_history::drive_messages();
    assert_eq!(diag["max_messages"], 4);
    assert_eq!(diag["newest"], 5 + sent.len());
    assert_eq!(diag["new_messages_available"], true);
    let messages = diag["messages"].as_array().unwrap();
    assert_eq!(
        messages.len(),
        sent.len(),
        "the unused slot is left out: {diag}"
    );
    for (m, raw) in messages.iter().zip(&sent) {
        let u32_at = |at: usize| u32::from_le_bytes(raw[at..at + 4].try_into().unwrap());
        assert_eq!(m["code"], u32_at(0));
        assert_eq!(m["flags"], u32_at(4) & 0xFFFF);
        assert_eq!(m["text_id"], u32_at(4) >> 16);
        assert_eq!(
            m["timestamp_ns"],
            u64::from_le_bytes(raw[8..16].try_into().unwrap())
        );
    }
    let types: Vec<&str> = messages
        .iter()
        .map(|m| m["type"].as_str().unwrap())
        .collect();
    assert_eq!(types, ["info", "warning", "error"]);
    let params = |i: usize| -> Vec<String> {
        messages[i]["parameters"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| {
                format!(
                    "{} {}",
                    p["kind"].as_str().unwrap(),
                    p["value"].as_str().unwrap()
                )
            })
            .collect()
    };
    assert_eq!(params(0), ["unsigned16 350 (0x15e)"]);
    assert_eq!(
        params(1),
        ["unsigned32 74565 (0x12345)", "string \"axis 1\""]
    );
    assert_eq!(params(2), ["bytes deadbe"]);
    let human = ecat.ok(&["diag", "-p", "0"]);
    assert!(human.contains("newest 0x08"), "{human}");
    assert!(
        human.contains("* 0x08 error"),
        "the newest is marked:\n{human}"
    );

    // A slave without a mailbox has no diagnosis history: a clear error.
    let (ok, _, stderr) = ecat.run(&["diag", "-p", "1"]);
    assert!(!ok && stderr.contains("0x10F3"), "{stderr}");
    // And diag works on one slave.
    let (ok, _, stderr) = ecat.run(&["diag"]);
    assert!(!ok && stderr.contains("works on one slave"), "{stderr}");
}

#[test]
fn xml_generates_an_esi_fragment_from_the_sii() {
    let ecatd = Ecatd::start(&[]);
    let ecat = Ecat { ecatd: &ecatd };
    let topology = Topology::default_segment();
    let drive = &topology.slaves[0];
    let xml = ecat.ok(&["xml", "-p", "0"]);
    assert!(
        xml.contains(&format!("<Id>#x{SIM_VENDOR_ID:08x}</Id>")),
        "{xml}"
    );
    assert!(
        xml.contains(&format!(
            "<Type ProductCode=\"#x{:08x}\" RevisionNo=\"#x{:08x}\">",
            drive.product_code, drive.revision
        )),
        "{xml}"
    );
    assert!(
        xml.contains(&format!("<Name>{}</Name>", drive.name)),
        "{xml}"
    );
    for pdo in &drive.pdos {
        let element = if pdo.is_rx() { "RxPdo" } else { "TxPdo" };
        assert!(
            xml.contains(&format!("<{element} Sm=\"{}\"", pdo.sm)),
            "{xml}"
        );
        assert!(
            xml.contains(&format!("<Index>#x{:04x}</Index>", pdo.index)),
            "{xml}"
        );
        for e in &pdo.entries {
            assert!(xml.contains(&format!("<Name>{}</Name>", e.name)), "{xml}");
        }
    }
    assert_eq!(
        xml.matches("<Entry>").count(),
        drive.pdos.iter().map(|p| p.entries.len()).sum::<usize>()
    );
    assert!(xml.contains("<CoE />") && xml.contains("<FoE />"), "{xml}");
    assert_eq!(
        xml.matches("<Sm ").count(),
        4,
        "two mailbox and two process-data SMs"
    );
    // Well-formed XML.
    let mut check = Command::new("python3")
        .args([
            "-c",
            "import sys, xml.dom.minidom; xml.dom.minidom.parseString(sys.stdin.read())",
        ])
        .stdin(std::process::Stdio::piped())
        .spawn()
        .expect("python3 runs");
    use std::io::Write as _;
    check
        .stdin
        .take()
        .unwrap()
        .write_all(xml.as_bytes())
        .unwrap();
    assert!(check.wait().unwrap().success(), "not well-formed:\n{xml}");
    // Every slave without -p; a slave without a mailbox has no <Mailbox>.
    let all = ecat.json(&["xml"]);
    assert_eq!(all.as_array().unwrap().len(), topology.slaves.len());
    assert!(!all[1]["xml"].as_str().unwrap().contains("<Mailbox>"));
}

#[test]
fn debug_shows_and_replaces_the_log_filter_and_reg_rdwr_swaps_registers() {
    let ecatd = Ecatd::start(&[]);
    let ecat = Ecat { ecatd: &ecatd };
    assert_eq!(ecat.ok(&["debug"]).trim(), "info");
    assert_eq!(ecat.ok(&["debug", "1"]).trim(), "debug", "IgH's level 1");
    assert_eq!(ecat.json(&["debug"])["filter"], "debug");
    ecat.ok(&["debug", "info,master_core::bus=trace"]);
    // A bad filter is refused and the old one stays.
    let (ok, _, stderr) = ecat.run(&["debug", "info,[[nonsense"]);
    assert!(!ok && stderr.contains("InvalidArgument"), "{stderr}");
    assert_eq!(ecat.ok(&["debug"]).trim(), "info,master_core::bus=trace");
    let (ok, _, stderr) = ecat.run(&["debug", " "]);
    assert!(!ok && stderr.contains("give a filter"), "{stderr}");
    ecat.ok(&["debug", "0"]);
    // The change is audited.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while !ecatd.log().contains("set_log_filter") {
        assert!(
            std::time::Instant::now() < deadline,
            "no audit line:\n{}",
            ecatd.log()
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }

    // reg_rdwr: one FPRW; each call prints what the register held before its write.
    assert_eq!(
        ecat.ok(&["reg_rdwr", "-p", "1", "0x0f10", "3412"]).trim(),
        "0x00 0x00"
    );
    assert_eq!(
        ecat.json(&["reg_rdwr", "-p", "1", "0x0f10", "7856"])["data"],
        "3412"
    );
    assert_eq!(
        ecat.json(&["reg_read", "-p", "1", "0x0f10", "2"])["data"],
        "7856"
    );
    assert_eq!(
        ecat.ok(&[
            "reg_rdwr", "-p", "1", "0x0f10", "0x1234", "--type", "uint16"
        ])
        .trim(),
        "22136",
        "0x5678 before"
    );
    assert_eq!(
        ecat.ok(&["reg_read", "-p", "1", "0x0f10", "--type", "uint16"])
            .trim(),
        "4660"
    );
    ecat.ok(&["reg_write", "-p", "1", "0x0f10", "-t", "uint16", "0xbeef"]);
    assert_eq!(
        ecat.json(&["reg_read", "-p", "1", "0x0f10", "2"])["data"],
        "efbe"
    );
    // Bad input changes nothing.
    let (ok, _, stderr) = ecat.run(&["reg_rdwr", "-p", "1", "0x0f10", "zz"]);
    assert!(!ok && stderr.contains("not hex"), "{stderr}");
    let (ok, _, stderr) = ecat.run(&["reg_rdwr", "-p", "1", "0x0f10", "70000", "-t", "uint16"]);
    assert!(!ok && stderr.contains("does not fit"), "{stderr}");
    let (ok, _, stderr) = ecat.run(&["reg_rdwr", "0x0f10", "00"]);
    assert!(!ok && stderr.contains("works on one slave"), "{stderr}");
    assert_eq!(
        ecat.json(&["reg_read", "-p", "1", "0x0f10", "2"])["data"],
        "efbe"
    );
}

/// ecatd with the application interface (a force needs it) on a socket of the test's own,
/// so that tests running side by side do not share the default one.
fn ecatd_with_app(name: &str) -> Ecatd {
    let dir = std::env::temp_dir().join(format!("ecatd-cli-pd-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("the test's directory");
    let socket = dir.join("app.sock");
    Ecatd::start(&["--app-socket", socket.to_str().expect("UTF-8 path")])
}

/// The entry `index:subindex` of `ecat --json pd`'s output.
fn pd_entry(values: &Value, index: u64, subindex: u64) -> Value {
    values["entries"]
        .as_array()
        .expect("entries")
        .iter()
        .find(|e| e["index"] == index && e["subindex"] == subindex)
        .unwrap_or_else(|| panic!("no {index:#x}:{subindex} in {values}"))
        .clone()
}

#[test]
fn pd_shows_forces_and_releases_named_entries_and_pdos_lists_every_slave_as_igh_does() {
    let ecatd = ecatd_with_app("pd");
    let ecat = Ecat { ecatd: &ecatd };

    // The drive's entries, named, typed, with their values.
    let table = ecat.ok(&["pd", "-p", "0"]);
    let lines: Vec<&str> = table.lines().collect();
    assert!(
        lines[0].starts_with("Slave  Entry") && lines[0].contains("Forced by"),
        "{table}"
    );
    let line = |name: &str| {
        lines
            .iter()
            .find(|l| l.contains(name))
            .unwrap_or_else(|| panic!("no {name} in:\n{table}"))
            .to_string()
    };
    let control = line("Controlword");
    assert!(
        control.starts_with("0      0x6040:00  Controlword")
            && control.contains("UNSIGNED16  out  0x0000 0"),
        "{control}"
    );
    let status = line("Statusword");
    assert!(
        status.contains("0x6041:00") && status.contains("UNSIGNED16  in   0x00"),
        "{status}"
    );

    // A DO8 output forced on, read back on the DI8 input the simulator wires it to.
    assert_eq!(
        ecat.ok(&["pd", "--force", "-p", "1", "0x7000", "1", "1"]),
        ""
    );
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let values = ecat.json(&["pd", "-p", "2"]);
        let input = pd_entry(&values, 0x6000, 1);
        if input["value"] == true {
            assert_eq!(input["name"], "Input 1");
            assert_eq!(input["direction"], "in");
            break;
        }
        assert!(Instant::now() < deadline, "0x6000:01 stays {input}");
        // Poll interval of the value check; the loop ends on the value or the deadline.
        std::thread::sleep(Duration::from_millis(5));
    }
    let output = pd_entry(&ecat.json(&["pd", "-p", "1"]), 0x7000, 1);
    assert_eq!(output["forced_by"], "anonymous", "{output}");
    let forced = ecat.ok(&["pd", "--forced"]);
    assert!(
        forced.contains("0x7000:01  Output 1  BOOLEAN  true   anonymous  no"),
        "{forced}"
    );
    // An input cannot be forced; the refusal names it.
    let (ok, _, stderr) = ecat.run(&["pd", "--force", "-p", "2", "0x6000", "1", "1"]);
    assert!(
        !ok && stderr.contains("InvalidArgument") && stderr.contains("is an input"),
        "{stderr}"
    );
    // INDEX SUB only with --force or --release.
    let (ok, _, stderr) = ecat.run(&["pd", "-p", "1", "0x7000", "1"]);
    assert!(!ok && stderr.contains("--force or --release"), "{stderr}");

    // --watch: without a terminal, the whole table whenever something changed; with --json
    // one object of the changed entries per line.
    let mut watch = Command::new(bin_dir().join("ecat"));
    watch.args([
        "--address",
        &format!("http://{}", ecatd.grpc),
        "pd",
        "-p",
        "2",
        "--watch",
        "50ms",
    ]);
    let table = Streaming::start(&mut watch);
    let mut json_watch = Command::new(bin_dir().join("ecat"));
    json_watch.args([
        "--address",
        &format!("http://{}", ecatd.grpc),
        "--json",
        "pd",
        "-p",
        "2",
        "--watch",
    ]);
    let lines = Streaming::start(&mut json_watch);
    table.wait_for_line("Input 8");
    lines.wait_for_line("Input 8");
    ecat.ok(&["pd", "--force", "-p", "1", "0x7000", "2", "true"]);
    table.wait_for("a second block with input 2 on", |text| {
        (text.matches("Cycle ").count() >= 2
            && text
                .lines()
                .any(|l| l.contains("0x6000:02") && l.contains(" true")))
        .then_some(())
    });
    let change = lines.wait_for("the change", |text| {
        text.lines()
            .map(|l| serde_json::from_str::<Value>(l).expect("one JSON object per line"))
            .find(|v| v["entries"].as_array().is_some_and(|e| e.len() == 1))
    });
    assert_eq!(change["entries"][0]["index"], 0x6000, "{change}");
    assert_eq!(change["entries"][0]["subindex"], 2, "{change}");
    assert_eq!(change["entries"][0]["value"], true, "{change}");
    drop((table, lines));

    // Release one output, then every forced output of the slave; again, there is none.
    assert_eq!(ecat.ok(&["pd", "--release", "-p", "1", "0x7000", "1"]), "");
    let (ok, _, stderr) = ecat.run(&["pd", "--release", "-p", "1", "0x7000", "1"]);
    assert!(!ok && stderr.contains("NotFound"), "{stderr}");
    let released = ecat.json(&["pd", "--release", "-p", "1"]);
    assert_eq!(released["released"][0]["subindex"], 2, "{released}");
    let released = ecat.json(&["pd", "--release", "-p", "1"]);
    assert_eq!(released["released"], serde_json::json!([]));
    assert_eq!(ecat.json(&["pd", "--forced"]), serde_json::json!([]));

    // pdos as IgH prints it: every slave under a header when no slave is selected.
    let pdos = ecat.ok(&["pdos"]);
    for expected in [
        "=== Master 0, Slave 0 ===\nSM0: PhysAddr 0x1000, DefaultSize  128, ControlRegister 0x26, Enable 1\n",
        "SM2: PhysAddr 0x1100, DefaultSize    6, ControlRegister 0x64, Enable 1\n  RxPDO 0x1600 \"Outputs\"\n    PDO entry 0x6040:00, 16 bit, \"Controlword\"\n    PDO entry 0x607a:00, 32 bit, \"Target position\"\n",
        "  TxPDO 0x1a00 \"Inputs\"\n    PDO entry 0x6041:00, 16 bit, \"Statusword\"\n",
        "=== Master 0, Slave 1 ===\nSM0: PhysAddr 0x1000, DefaultSize    1, ControlRegister 0x64, Enable 1\n  RxPDO 0x1600 \"Outputs\"\n    PDO entry 0x7000:01,  1 bit, \"Output 1\"\n",
        "=== Master 0, Slave 2 ===\n",
        "    PDO entry 0x6000:08,  1 bit, \"Input 8\"\n",
    ] {
        assert!(
            pdos.contains(expected),
            "{expected:?} missing from:\n{pdos}"
        );
    }
    let one = ecat.ok(&["pdos", "-p", "2"]);
    assert!(
        one.starts_with("SM0: PhysAddr 0x1000") && !one.contains("==="),
        "one slave, no header:\n{one}"
    );
    assert!(!ecat.ok(&["pdos", "-p", "0", "-q"]).contains("PDO entry"));
    let json = ecat.json(&["pdos", "-p", "1"]);
    let sm = &json[0]["sync_managers"][0];
    assert_eq!(sm["pdo_type"], "rx", "{json}");
    assert_eq!(sm["pdos"][0]["entries"].as_array().map(Vec::len), Some(8));
    assert_eq!(sm["pdos"][0]["entries"][7]["name"], "Output 8");
}

/// `ecat events`: the kept events with their times, narrowed by kind and slave, as JSON too;
/// `-f` prints them, then a state change made afterwards as it comes.
#[test]
fn events_shows_the_history_and_follows_the_new_ones() {
    let ecatd = Ecatd::start(&[]);
    let ecat = Ecat { ecatd: &ecatd };
    let slaves = Topology::default_segment().slaves.len();
    let found = ecat.json(&["events", "--kind", "slave_found"]);
    let found = found.as_array().unwrap();
    assert_eq!(found.len(), slaves, "{found:?}");
    assert!(
        found
            .iter()
            .all(|e| e["time"].as_str().unwrap().ends_with('Z'))
    );
    let one = ecat.ok(&["events", "-p", "2", "--kind", "state_changed", "-n", "1"]);
    let lines: Vec<&str> = one.lines().collect();
    assert_eq!(lines.len(), 1, "{one}");
    assert!(
        lines[0].contains("state_changed") && lines[0].ends_with("slave 2: SAFEOP -> OP"),
        "{one}"
    );
    let (ok, _, stderr) = ecat.run(&["events", "--since", "last tuesday"]);
    assert!(!ok && stderr.contains("since"), "{stderr}");

    let follow = Streaming::start(
        Command::new(bin_dir().join("ecat"))
            .args(["--address", &format!("http://{}", ecatd.grpc)])
            .args(["events", "-f", "-p", "1", "--kind", "state_changed"]),
    );
    // The kept ones first: slave 1 came up to OP.
    follow.wait_for("slave 1's history", |t| {
        t.contains("slave 1: SAFEOP -> OP").then_some(())
    });
    ecat.ok(&["states", "-p", "1", "SAFEOP"]);
    follow.wait_for("the new state change", |t| {
        t.contains("slave 1: OP -> SAFEOP").then_some(())
    });
    // Slave 1's only: nothing of the others.
    assert!(!follow.text().contains("slave 2:"), "{}", follow.text());
}
