//! Live bus capture: `ecat pcap -c 1000 -w f.pcapng` while the mailbox gateway is under
//! load gives a pcapng file tshark reads with exactly 1000 frames and nothing malformed;
//! the REST route gives the same format. The rolling capture (`[capture] rolling`) keeps a
//! ring of pcapng files within its bound, each of which tshark reads, and hands out the
//! whole ring.

use crate::server_support;

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

/// The ring files in `dir`, by number.
fn ring_files(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .flatten()
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|e| e == "pcapng"))
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
}

#[test]
fn the_rolling_capture_keeps_a_bounded_ring_that_tshark_reads() {
    const FILES: usize = 3;
    const FILE_KIB: u64 = 16;
    let dir = std::env::temp_dir().join(format!("ecatd-rolling-{}", std::process::id()));
    let ring = dir.join("ring");
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("ecatd.toml");
    std::fs::write(
        &config,
        format!(
            "[capture]\nrolling = true\ndir = \"{}\"\nfiles = {FILES}\nfile_kib = {FILE_KIB}\n",
            ring.display()
        ),
    )
    .unwrap();
    let ecatd = Ecatd::start(&["--config", config.to_str().unwrap()]);

    // Watch the ring rotate well past its count: it never holds more than FILES files of
    // at most FILE_KIB KiB.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    let mut closed = Vec::new();
    loop {
        let files = ring_files(&ring);
        assert!(files.len() <= FILES, "{files:?}");
        for file in &files {
            // A file may be removed between the listing and this look: fine.
            if let Ok(meta) = std::fs::metadata(file) {
                assert!(
                    meta.len() <= FILE_KIB * 1024,
                    "{}: {} bytes",
                    file.display(),
                    meta.len()
                );
            }
        }
        // Every file but the newest is closed (complete): copy it for tshark, if it is
        // still there.
        if let Some((_, older)) = files.split_last() {
            for file in older {
                let copy = dir.join(file.file_name().unwrap());
                if !copy.exists() && std::fs::copy(file, &copy).is_ok() {
                    closed.push(copy);
                }
            }
        }
        let newest = files.last().and_then(|f| {
            f.file_stem()?
                .to_str()?
                .strip_prefix("rolling-")?
                .parse::<usize>()
                .ok()
        });
        if newest.is_some_and(|n| n > 3 * FILES) && closed.len() >= FILES {
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "the ring did not rotate: {files:?}"
        );
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    // A full ring's worth of closed files, the newest ones (tshark takes a second a run).
    for file in &closed[closed.len() - FILES..] {
        assert!(
            tshark_frames(file, "ecat") > 0,
            "{}: EtherCAT decoded",
            file.display()
        );
        assert_eq!(
            tshark_frames(file, "_ws.malformed || _ws.expert.severity >= error"),
            0,
            "{}",
            file.display()
        );
    }

    // The whole window through ecat: one file of several sections, every frame readable.
    let window = dir.join("window.pcapng");
    let output = Command::new(bin_dir().join("ecat"))
        .args(["--address", &format!("http://{}", ecatd.grpc), "--json"])
        .args(["pcap", "--rolling", "-w", window.to_str().unwrap()])
        .output()
        .expect("ecat runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let frames = summary["frames"].as_u64().unwrap();
    assert!(frames > 0, "{summary}");
    assert!(
        summary["bytes"].as_u64().unwrap() <= FILES as u64 * FILE_KIB * 1024,
        "{summary}"
    );
    assert_eq!(tshark_frames(&window, "") as u64, frames);
    assert_eq!(
        tshark_frames(&window, "_ws.malformed || _ws.expert.severity >= error"),
        0
    );

    // REST gives the window too; drops are counted in the metrics.
    let rest = dir.join("rest.pcapng");
    let (status, _) = curl(&[
        "-s",
        "-o",
        rest.to_str().unwrap(),
        &format!("{}/api/v1/capture?rolling=true", ecatd.http),
    ]);
    assert_eq!(status, 200);
    assert_eq!(tshark_frames(&rest, "_ws.malformed"), 0);
    let (_, metrics) = curl(&["-s", &format!("{}/metrics", ecatd.http)]);
    let value = |name: &str| -> f64 {
        metrics
            .lines()
            .find_map(|l| l.strip_prefix(name)?.strip_prefix(' ')?.parse().ok())
            .unwrap_or_else(|| panic!("no {name} in the metrics"))
    };
    assert!(value("ecat_capture_rolling_frames_total") >= frames as f64);
    assert!(value("ecat_capture_rolling_rotations_total") >= (3 * FILES) as f64);
    assert_eq!(value("ecat_capture_rolling_errors_total"), 0.0);
    // The tap never waits for the writer: a frame it cannot queue is counted here (the
    // service's unit tests make it drop).
    let _present = value("ecat_capture_rolling_dropped_frames_total");

    // An on-demand capture runs beside the rolling one.
    let (status, _) = curl(&[
        "-s",
        "-o",
        dir.join("live.pcapng").to_str().unwrap(),
        &format!("{}/api/v1/capture?frames=20", ecatd.http),
    ]);
    assert_eq!(status, 200);
    assert_eq!(tshark_frames(&dir.join("live.pcapng"), ""), 20);
    drop(ecatd);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn without_a_rolling_capture_the_window_is_unavailable() {
    let ecatd = Ecatd::start(&[]);
    let (status, body) = curl(&["-s", &format!("{}/api/v1/capture?rolling=true", ecatd.http)]);
    assert_eq!(status, 503, "{body}");
    assert!(body.contains("rolling = true"), "{body}");
}
