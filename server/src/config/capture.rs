//! `[capture]`: the rolling capture, a ring of pcapng files ecatd keeps of the live bus so
//! that the frames before a fault are there when someone looks (`ecat pcap --rolling`).

use std::path::PathBuf;
use std::time::Duration;

use serde::{Deserialize, Serialize};

/// The smallest file of the ring (a few dozen frames: smaller would rotate on every cycle).
pub const MIN_FILE_KIB: u64 = 16;
/// The largest file of the ring.
pub const MAX_FILE_KIB: u64 = 1 << 20;
/// The most files in the ring.
pub const MAX_FILES: usize = 1000;

/// The rolling capture's settings.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CaptureSettings {
    /// Keep a rolling capture at all.
    pub rolling: bool,
    /// The directory of the ring's files (`rolling-NNNNNN.pcapng`; created if missing, its
    /// old ring files removed at start).
    pub dir: PathBuf,
    /// Files in the ring: when a new one starts beyond this, the oldest is removed.
    pub files: usize,
    /// A file is closed before it would grow past this many KiB.
    pub file_kib: u64,
    /// A file is closed once it covers this long, whatever its size (the ring then holds
    /// about `files` × `file_time`); absent: by size only.
    #[serde(
        with = "humantime_serde::option",
        skip_serializing_if = "Option::is_none",
        default
    )]
    pub file_time: Option<Duration>,
    /// Frames the tap may queue ahead of the writer; beyond, frames are dropped and counted
    /// (`ecat_capture_rolling_dropped_frames_total`).
    pub queue: usize,
}

impl Default for CaptureSettings {
    fn default() -> CaptureSettings {
        CaptureSettings {
            rolling: false,
            dir: PathBuf::from("/var/lib/ecatd/capture"),
            files: 8,
            file_kib: 8192,
            file_time: None,
            queue: 4096,
        }
    }
}

impl CaptureSettings {
    /// Refuses settings the ring cannot keep.
    pub fn check(&self) -> Result<(), String> {
        if !self.rolling {
            return Ok(());
        }
        if !(2..=MAX_FILES).contains(&self.files) {
            return Err(format!(
                "[capture] files = {} must be 2..={MAX_FILES}",
                self.files
            ));
        }
        if !(MIN_FILE_KIB..=MAX_FILE_KIB).contains(&self.file_kib) {
            return Err(format!(
                "[capture] file_kib = {} must be {MIN_FILE_KIB}..={MAX_FILE_KIB}",
                self.file_kib
            ));
        }
        if self
            .file_time
            .is_some_and(|t| t < Duration::from_millis(100))
        {
            return Err("[capture] file_time must be at least 100ms".into());
        }
        if !(1..=1 << 20).contains(&self.queue) {
            return Err(format!(
                "[capture] queue = {} must be 1..=1048576",
                self.queue
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> CaptureSettings {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn settings_parse_and_the_ring_s_bounds_are_checked() {
        let s = parse(
            "rolling = true\ndir = \"/tmp/ring\"\nfiles = 3\nfile_kib = 16\nfile_time = \"10m\"",
        );
        assert_eq!(s.file_time, Some(Duration::from_secs(600)));
        assert_eq!(s.queue, 4096, "the default");
        assert!(s.check().is_ok());
        let off = parse("files = 1");
        assert!(off.check().is_ok(), "not checked while off");
        for bad in [
            "rolling = true\nfiles = 1",
            "rolling = true\nfile_kib = 8",
            "rolling = true\nfile_time = \"10ms\"",
            "rolling = true\nqueue = 0",
        ] {
            let err = parse(bad).check().unwrap_err();
            assert!(err.starts_with("[capture]"), "{bad}: {err}");
        }
        assert!(toml::from_str::<CaptureSettings>("rolling = true\nsize = 3").is_err());
    }
}
