//! A capture of a bring-up, written by the pcap tap, decodes in Wireshark (`tshark`) with no
//! malformed frame and no error-level expert item.

use crate::master_support;

use crate::tshark;

use std::fs::File;

use master_core::bus::BusConfig;
use master_core::link::PcapTap;
use master_core::master::MasterConfig;
use master_support::{block_on, rig_with};
use pcap_file::pcap::PcapReader;
use sim::topology::Topology;

#[test]
fn a_bring_up_capture_decodes_in_wireshark_without_malformed_frames() {
    let path = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("master-bringup-{}.pcap", std::process::id()));
    let config = MasterConfig {
        watch_interval: None,
        ..MasterConfig::default()
    };
    let rig = rig_with(
        Topology::default_segment(),
        config,
        BusConfig::default(),
        |link| PcapTap::create(link, &path).expect("capture file"),
    );
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let mut tap = rig.stop();
    tap.flush().expect("flush capture");
    assert!(tap.capture_error().is_none());
    drop(tap);

    let mut reader = PcapReader::new(File::open(&path).expect("capture")).expect("pcap");
    let mut frames = Vec::new();
    while let Some(packet) = reader.next_packet() {
        frames.push(packet.expect("packet").data.into_owned());
    }
    let _ = std::fs::remove_file(&path);
    assert!(
        frames.len() > 100,
        "a bring-up takes more than {} frames",
        frames.len()
    );
    let capture = tshark::Capture::write("master-bringup", &frames);
    assert_eq!(tshark::flagged_frames(&capture), Vec::<String>::new());
    // Wireshark sees the bring-up's commands: the BRD count, the APWR station addresses,
    // FPWR/FPRD configuration and the cyclic LRW.
    let commands: std::collections::BTreeSet<String> = tshark::fields(&capture, &["ecat.cmd"])
        .into_iter()
        .filter_map(|f| f.get("ecat.cmd").cloned())
        .flat_map(|v| v.split(',').map(str::to_owned).collect::<Vec<_>>())
        .collect();
    for cmd in ["0x07", "0x02", "0x04", "0x05", "0x0c"] {
        assert!(
            commands.contains(cmd),
            "command {cmd} missing from {commands:?}"
        );
    }
}
