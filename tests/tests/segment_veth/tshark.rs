//! Wireshark decodes a whole pysoem session with the simulator: `ecat-sim --pcap` records
//! it, and tshark must find no malformed frame and must decode the EtherCAT datagrams and
//! the CoE, SDO Information and FoE mailbox traffic of the session.
//!
//! The capture check reuses master-core's tshark helper (`ecat_tests::tshark`, compiled
//! from master-core/tests/tshark_support/mod.rs). Needs root, tshark and the venv from
//! `scripts/test`.

use std::collections::BTreeSet;

use ecat_tests::pysoem_session::{FOE_FILE, plan, pysoem_session};
use ecat_tests::tshark::{Capture, fields, flagged_frames};
use pcap_file::pcap::PcapReader;
use sim::topology::Topology;

/// The frames of a pcap file.
fn read_frames(path: &std::path::Path) -> Vec<Vec<u8>> {
    let file = std::fs::File::open(path).expect("capture written by ecat-sim");
    let mut reader = PcapReader::new(file).expect("a pcap file");
    let mut frames = Vec::new();
    while let Some(packet) = reader.next_packet() {
        frames.push(packet.expect("a whole packet").data.into_owned());
    }
    frames
}

#[test]
fn tshark_decodes_the_pysoem_session_without_malformed_frames() {
    let dir = std::env::temp_dir().join(format!("ecatd-sim-capture-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let pcap = dir.join("session.pcap");
    let (_, status) = pysoem_session(&["--pcap", pcap.to_str().unwrap()]);
    assert!(status.success(), "ecat-sim exit after SIGTERM: {status}");
    let frames = read_frames(&pcap);
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        frames.len() > 100,
        "a whole session: {} frames",
        frames.len()
    );

    // The tshark helper works on a capture it wrote itself; same frames, same order.
    let capture = Capture::write("pysoem-session", &frames);
    assert_eq!(
        flagged_frames(&capture),
        Vec::<String>::new(),
        "malformed frames"
    );

    let names = [
        "frame.protocols",
        "ecat_mailbox.coe.sdoidx",
        "ecat_mailbox.coe.sdoinfoopcode",
        "ecat_mailbox.foe_filename",
    ];
    let rows = fields(&capture, &names);
    assert_eq!(rows.len(), frames.len());
    let all = |name: &str| -> BTreeSet<String> {
        rows.iter()
            .filter_map(|row| row.get(name))
            .flat_map(|v| v.split(','))
            .map(str::to_owned)
            .collect()
    };
    assert!(
        rows.iter()
            .all(|r| r.get("frame.protocols").is_some_and(|p| p.contains("ecat"))),
        "every frame is EtherCAT"
    );
    let topology = Topology::default_segment();
    let plan = plan(&topology);
    let sdo_indices = all("ecat_mailbox.coe.sdoidx");
    for index in [0x1018, plan.large.1] {
        assert!(
            sdo_indices.contains(&format!("0x{index:04x}")),
            "SDO 0x{index:04x} decoded: {sdo_indices:?}"
        );
    }
    assert!(
        !all("ecat_mailbox.coe.sdoinfoopcode").is_empty(),
        "SDO Information decoded"
    );
    assert!(
        all("ecat_mailbox.foe_filename").contains(FOE_FILE),
        "FoE file name decoded"
    );
}
