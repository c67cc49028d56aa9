//! Live bus capture: `ecat pcap -c 1000 -w f.pcapng` while the mailbox gateway is under
//! load gives a pcapng file tshark reads with exactly 1000 frames and nothing malformed;
//! the REST route gives the same format.

mod server_support;

use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use server_support::gateway_client::GatewayClient;
use server_support::{Ecatd, bin_dir, curl};

/// The frame numbers tshark prints for `filter` (all frames when empty).
fn tshark_frames(file: &std::path::Path, filter: &str) -> usize {
    let mut args = vec![
        "-r",
        file.to_str().unwrap(),
        "-T",
        "fields",
        "-e",
        "frame.number",
    ];
    if !filter.is_empty() {
        args.extend(["-Y", filter]);
    }
    let output = Command::new("tshark")
        .args(&args)
        .output()
        .expect("tshark runs");
    assert!(
        output.status.success(),
        "tshark {args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout)
        .lines()
        .filter(|l| !l.trim().is_empty())
        .count()
}

#[test]
fn a_capture_during_gateway_load_has_every_frame_and_nothing_malformed() {
    let ecatd = Ecatd::start(&[]);
    let dir = std::env::temp_dir().join(format!("ecatd-capture-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();

    let stop = Arc::new(AtomicBool::new(false));
    let answered = Arc::new(AtomicU64::new(0));
    let load = {
        let (stop, answered) = (Arc::clone(&stop), Arc::clone(&answered));
        let gateway = ecatd.gateway_addr();
        std::thread::spawn(move || {
            let mut client = GatewayClient::new(gateway);
            while !stop.load(Ordering::Relaxed) {
                if client.sdo_upload(1001, 0x1018, 1).is_ok() {
                    answered.fetch_add(1, Ordering::Relaxed);
                }
            }
        })
    };
    let file = dir.join("f.pcapng");
    let output = Command::new(bin_dir().join("ecat"))
        .args(["--address", &format!("http://{}", ecatd.grpc), "--json"])
        .args(["pcap", "-c", "1000", "-w", file.to_str().unwrap()])
        .output()
        .expect("ecat runs");
    stop.store(true, Ordering::Relaxed);
    load.join().unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(summary["frames"], 1000, "{summary}");
    assert!(
        answered.load(Ordering::Relaxed) > 0,
        "the gateway was under load"
    );
    assert_eq!(tshark_frames(&file, ""), 1000);
    assert_eq!(
        tshark_frames(&file, "_ws.malformed || _ws.expert.severity >= error"),
        0
    );
    assert!(tshark_frames(&file, "ecat") > 0, "EtherCAT decoded");
    // The gateway's mailbox traffic is in the capture.
    assert!(
        tshark_frames(&file, "ecat_mailbox.coe") > 0,
        "CoE mailbox frames captured"
    );

    // REST: the same format, with the counts in headers.
    let rest = dir.join("rest.pcapng");
    let (status, _) = curl(&[
        "-s",
        "-o",
        rest.to_str().unwrap(),
        &format!("{}/api/v1/capture?frames=50", ecatd.http),
    ]);
    assert_eq!(status, 200);
    assert_eq!(tshark_frames(&rest, ""), 50);
    assert_eq!(tshark_frames(&rest, "_ws.malformed"), 0);
    // No limit at all is a bad request.
    let (status, body) = curl(&["-s", &format!("{}/api/v1/capture", ecatd.http)]);
    assert_eq!(status, 400, "{body}");
    std::fs::remove_dir_all(&dir).unwrap();
}
