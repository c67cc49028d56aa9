//! `[events]`: how many events ecatd keeps in memory and, optionally, the JSON-lines journal
//! that keeps them across restarts (docs/operations.md, "Events").

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// The most events kept in memory.
pub const MAX_HISTORY: usize = 1_000_000;
/// The smallest journal file (a few dozen events: smaller would rotate on every event).
pub const MIN_FILE_KIB: u64 = 16;
/// The largest journal file.
pub const MAX_FILE_KIB: u64 = 1 << 20;
/// The most journal files.
pub const MAX_FILES: usize = 1000;

/// The event history's settings.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EventSettings {
    /// Events kept in memory (the newest; the history queries answer from them).
    pub history: usize,
    /// The journal: every kept event appended as one JSON line to this file, read back at
    /// start so that the history and the event numbers survive a restart. Absent: no
    /// journal.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub journal: Option<PathBuf>,
    /// Journal files: the file itself and its rotated predecessors `FILE.1` (newest) to
    /// `FILE.{journal_files - 1}`; when the file would grow past `journal_file_kib` it
    /// becomes `FILE.1` and the oldest is removed.
    pub journal_files: usize,
    /// A journal file is rotated before it would grow past this many KiB.
    pub journal_file_kib: u64,
}

impl Default for EventSettings {
    fn default() -> EventSettings {
        EventSettings {
            history: 10_000,
            journal: None,
            journal_files: 4,
            journal_file_kib: 4096,
        }
    }
}

impl EventSettings {
    /// Refuses settings the history or the journal cannot keep.
    pub fn check(&self) -> Result<(), String> {
        if !(1..=MAX_HISTORY).contains(&self.history) {
            return Err(format!(
                "[events] history = {} must be 1..={MAX_HISTORY}",
                self.history
            ));
        }
        if !(1..=MAX_FILES).contains(&self.journal_files) {
            return Err(format!(
                "[events] journal_files = {} must be 1..={MAX_FILES}",
                self.journal_files
            ));
        }
        if !(MIN_FILE_KIB..=MAX_FILE_KIB).contains(&self.journal_file_kib) {
            return Err(format!(
                "[events] journal_file_kib = {} must be {MIN_FILE_KIB}..={MAX_FILE_KIB}",
                self.journal_file_kib
            ));
        }
        if self
            .journal
            .as_ref()
            .is_some_and(|p| p.file_name().is_none())
        {
            return Err("[events] journal must name a file".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_parse_with_their_defaults_and_their_bounds_are_checked() {
        let s: EventSettings =
            toml::from_str("journal = \"/var/lib/ecatd/events.jsonl\"\nhistory = 500").unwrap();
        assert_eq!(s.history, 500);
        assert_eq!(s.journal_files, 4, "the default");
        assert!(s.check().is_ok());
        assert_eq!(EventSettings::default().history, 10_000);
        for bad in [
            "history = 0",
            "journal_files = 0",
            "journal_file_kib = 8",
            "journal = \"/\"",
        ] {
            let err = toml::from_str::<EventSettings>(bad)
                .unwrap()
                .check()
                .unwrap_err();
            assert!(err.starts_with("[events]"), "{bad}: {err}");
        }
        assert!(toml::from_str::<EventSettings>("size = 3").is_err());
    }
}
