//! Writing a capture and asking Wireshark's dissectors what they see in it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use pcap_file::DataLink;
use pcap_file::pcap::{PcapHeader, PcapPacket, PcapWriter};

/// A capture file in a fresh temporary directory, removed on drop.
pub struct Capture {
    dir: PathBuf,
    path: PathBuf,
}

impl Capture {
    /// Writes `frames` (complete Ethernet frames without FCS) to a pcap file.
    pub fn write(name: &str, frames: &[Vec<u8>]) -> Capture {
        let dir = std::env::temp_dir().join(format!("ecatd-ws-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create capture directory");
        let path = dir.join(format!("{name}.pcap"));
        let file = std::fs::File::create(&path).expect("create capture file");
        let header = PcapHeader {
            datalink: DataLink::ETHERNET,
            ..Default::default()
        };
        let mut writer = PcapWriter::with_header(file, header).expect("pcap header");
        for (i, frame) in frames.iter().enumerate() {
            let ts = std::time::Duration::from_millis(i as u64);
            writer
                .write_packet(&PcapPacket::new(ts, frame.len() as u32, frame))
                .expect("write packet");
        }
        Capture { dir, path }
    }

    /// The capture's path.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for Capture {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn tshark() -> Command {
    let mut cmd = Command::new("tshark");
    // No user profile, no name resolution: the same decoding on every machine.
    cmd.arg("-n");
    cmd
}

fn run(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap_or_else(|e| {
        panic!("cannot run tshark ({e}); install it (Debian: apt-get install tshark) or use scripts/test")
    });
    assert!(
        out.status.success(),
        "tshark failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("tshark prints UTF-8")
}

/// The full verbose decode (`tshark -r file -V`).
pub fn verbose(capture: &Capture) -> String {
    run(tshark().arg("-r").arg(capture.path()).arg("-V"))
}

/// Frame numbers (1-based) that Wireshark flags as malformed or with an error-level expert item.
pub fn flagged_frames(capture: &Capture) -> Vec<String> {
    run(tshark()
        .arg("-r")
        .arg(capture.path())
        .args(["-Y", "_ws.malformed || _ws.expert.severity >= \"Error\""])
        .args(["-T", "fields", "-e", "frame.number"]))
    .lines()
    .map(str::to_owned)
    .filter(|l| !l.is_empty())
    .collect()
}

/// Per frame (index 0 = first frame), the value of each requested field as tshark prints it;
/// repeated occurrences are joined with ','; absent fields are missing from the map.
pub fn fields(capture: &Capture, names: &[&str]) -> Vec<BTreeMap<String, String>> {
    let mut cmd = tshark();
    cmd.arg("-r").arg(capture.path());
    cmd.args([
        "-T",
        "fields",
        "-E",
        "occurrence=a",
        "-E",
        "aggregator=,",
        "-E",
        "separator=\t",
    ]);
    for name in names {
        cmd.args(["-e", name]);
    }
    run(&mut cmd)
        .lines()
        .map(|line| {
            names
                .iter()
                .zip(line.split('\t'))
                .filter(|(_, v)| !v.is_empty())
                .map(|(k, v)| ((*k).to_owned(), v.to_owned()))
                .collect()
        })
        .collect()
}
