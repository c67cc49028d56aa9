//! The event journal (`[events] journal`): every kept event appended as one JSON line, the
//! files rotated by size, and read back at start so that the history and the event numbers
//! go on across a restart (a client's `Last-Event-ID` from before it still resumes).
//!
//! Writing is a thread of its own behind a bounded queue: publishing an event never waits
//! for the disk. When the queue is full (the disk stalls) events are left out of the
//! journal, counted and logged, and stay in memory and on the streams.

use std::collections::VecDeque;
use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError};

use super::view::EventView;
use crate::config::events::EventSettings;

/// Lines the writer may be behind by.
const QUEUE: usize = 4096;

/// What the journal held at start.
#[derive(Debug, Default)]
pub struct Restored {
    /// The newest events (at most the history's size), oldest first.
    pub events: Vec<EventView>,
    /// The highest event number in the files (numbering goes on after it).
    pub last_id: u64,
    /// Lines that did not parse (a line cut by a crash, a hand edit); skipped.
    pub skipped: usize,
}

/// The writing end; see the [module documentation](self).
pub struct Journal {
    tx: Option<SyncSender<String>>,
    dropped: Arc<AtomicU64>,
    writer: Option<std::thread::JoinHandle<()>>,
}

impl Journal {
    /// Reads what `settings.journal` holds (its rotated files first) and starts the writer
    /// that appends to it. `None` without a journal.
    pub fn open(settings: &EventSettings) -> Result<Option<(Journal, Restored)>, String> {
        let Some(path) = &settings.journal else {
            return Ok(None);
        };
        let files = Files {
            path: path.clone(),
            count: settings.journal_files,
            limit: settings.journal_file_kib * 1024,
        };
        let restored = files.read(settings.history)?;
        let file = files.open_current()?;
        let (tx, rx) = std::sync::mpsc::sync_channel(QUEUE);
        let writer = std::thread::Builder::new()
            .name("ecatd-journal".into())
            .spawn(move || files.write(file, rx))
            .map_err(|err| format!("[events] journal: cannot start its writer: {err}"))?;
        Ok(Some((
            Journal {
                tx: Some(tx),
                dropped: Arc::default(),
                writer: Some(writer),
            },
            restored,
        )))
    }

    /// Queues `view` for the file; never blocks.
    pub fn append(&self, view: &EventView) {
        let Some(tx) = &self.tx else { return };
        let line = match serde_json::to_string(view) {
            Ok(line) => line,
            Err(err) => {
                tracing::warn!(%err, id = view.id, "event not journaled");
                return;
            }
        };
        match tx.try_send(line) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) => {
                if self.dropped.fetch_add(1, Ordering::Relaxed) == 0 {
                    tracing::warn!(
                        id = view.id,
                        "the event journal is behind: events left out of it (kept in memory)"
                    );
                }
            }
            Err(TrySendError::Disconnected(_)) => {}
        }
    }

    /// Events left out of the file because the writer was behind.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

impl Drop for Journal {
    /// Writes what is queued before the journal goes.
    fn drop(&mut self) {
        self.tx.take();
        if let Some(writer) = self.writer.take() {
            let _ = writer.join();
        }
    }
}

/// The journal's files: `path` and its rotated predecessors `path.1` (newest) ...
struct Files {
    path: PathBuf,
    count: usize,
    limit: u64,
}

impl Files {
    fn rotated(&self, n: usize) -> PathBuf {
        let mut name = self.path.as_os_str().to_owned();
        name.push(format!(".{n}"));
        PathBuf::from(name)
    }

    /// The newest `keep` events of every file, oldest file first.
    fn read(&self, keep: usize) -> Result<Restored, String> {
        let mut restored = Restored::default();
        let mut events = VecDeque::new();
        let oldest_first = (1..self.count)
            .rev()
            .map(|n| self.rotated(n))
            .chain([self.path.clone()]);
        for path in oldest_first {
            let file = match File::open(&path) {
                Ok(file) => file,
                Err(err) if err.kind() == std::io::ErrorKind::NotFound => continue,
                Err(err) => return Err(format!("[events] journal {}: {err}", path.display())),
            };
            for line in BufReader::new(file).lines() {
                let line =
                    line.map_err(|err| format!("[events] journal {}: {err}", path.display()))?;
                match serde_json::from_str::<EventView>(&line) {
                    Ok(view) => {
                        restored.last_id = restored.last_id.max(view.id);
                        if events.len() == keep {
                            events.pop_front();
                        }
                        events.push_back(view);
                    }
                    Err(_) => restored.skipped += 1,
                }
            }
        }
        restored.events = events.into();
        Ok(restored)
    }

    /// The current file, opened for appending (its directory made if missing).
    fn open_current(&self) -> Result<File, String> {
        let fail = |err: std::io::Error| format!("[events] journal {}: {err}", self.path.display());
        if let Some(dir) = self.path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(fail)?;
        }
        OpenOptions::new()
            .create(true)
            .append(true)
            .open(&self.path)
            .map_err(fail)
    }

    /// The writer thread: appends the queued lines, a batch at a time, until the journal is
    /// dropped.
    fn write(self, file: File, rx: Receiver<String>) {
        let mut size = file.metadata().map(|m| m.len()).unwrap_or(0);
        let mut out = BufWriter::new(file);
        while let Ok(first) = rx.recv() {
            let mut next = Some(first);
            while let Some(line) = next {
                let bytes = line.len() as u64 + 1;
                if size > 0 && size + bytes > self.limit {
                    match self.rotate(out) {
                        Ok(file) => {
                            out = BufWriter::new(file);
                            size = 0;
                        }
                        Err(err) => {
                            tracing::error!(%err, "event journal: rotation failed; writing stops");
                            return;
                        }
                    }
                }
                if let Err(err) = writeln!(out, "{line}") {
                    tracing::error!(%err, "event journal: write failed; writing stops");
                    return;
                }
                size += bytes;
                next = rx.try_recv().ok();
            }
            if let Err(err) = out.flush() {
                tracing::error!(%err, "event journal: write failed; writing stops");
                return;
            }
        }
        let _ = out.flush();
    }

    /// `path` becomes `path.1`, `path.1` becomes `path.2`, ..., the oldest goes; a new
    /// `path` is opened.
    fn rotate(&self, out: BufWriter<File>) -> std::io::Result<File> {
        out.into_inner()
            .map_err(|err| err.into_error())?
            .sync_all()?;
        if self.count == 1 {
            std::fs::remove_file(&self.path)?;
        } else {
            let _ = std::fs::remove_file(self.rotated(self.count - 1));
            for n in (1..self.count - 1).rev() {
                rename_if_there(&self.rotated(n), &self.rotated(n + 1))?;
            }
            std::fs::rename(&self.path, self.rotated(1))?;
        }
        OpenOptions::new()
            .create(true)
            .append(true)
            .open(&self.path)
    }
}

fn rename_if_there(from: &Path, to: &Path) -> std::io::Result<()> {
    match std::fs::rename(from, to) {
        Err(err) if err.kind() == std::io::ErrorKind::NotFound => Ok(()),
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn event(id: u64) -> EventView {
        EventView {
            id,
            time: "2026-11-29T07:10:00.123Z".into(),
            kind: "state_changed".into(),
            position: 1,
            text: format!("event {id}"),
            ..EventView::lagged(0)
        }
    }

    fn settings(dir: &Path, files: usize, history: usize) -> EventSettings {
        EventSettings {
            history,
            journal: Some(dir.join("events.jsonl")),
            journal_files: files,
            journal_file_kib: 16,
        }
    }

    fn temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("ecatd-journal-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    #[test]
    fn what_is_written_is_read_back_across_rotated_files_newest_kept() {
        let dir = temp_dir("rotate");
        let (journal, restored) = Journal::open(&settings(&dir, 3, 100)).unwrap().unwrap();
        assert_eq!(restored.events.len(), 0, "a new journal");
        // About 180 bytes a line: 16 KiB holds about 90, so 400 events need more than the
        // three files kept: the oldest went.
        for id in 1..=400 {
            journal.append(&event(id));
        }
        drop(journal);
        let names: Vec<bool> = ["events.jsonl", "events.jsonl.1", "events.jsonl.2"]
            .iter()
            .map(|n| dir.join(n).exists())
            .collect();
        assert_eq!(names, [true, true, true]);
        assert!(!dir.join("events.jsonl.3").exists(), "three files at most");
        for n in ["events.jsonl", "events.jsonl.1", "events.jsonl.2"] {
            let len = std::fs::metadata(dir.join(n)).unwrap().len();
            assert!(len <= 16 * 1024, "{n}: {len} bytes");
        }
        let (_journal, restored) = Journal::open(&settings(&dir, 3, 100)).unwrap().unwrap();
        assert_eq!(restored.last_id, 400);
        let ids: Vec<u64> = restored.events.iter().map(|e| e.id).collect();
        assert_eq!(
            ids,
            (301..=400).collect::<Vec<_>>(),
            "the newest 100, in order"
        );
        assert_eq!(restored.events[99], event(400));
        let oldest = std::fs::read_to_string(dir.join("events.jsonl.2")).unwrap();
        let first: EventView = serde_json::from_str(oldest.lines().next().unwrap()).unwrap();
        assert!(first.id > 1, "the first events rotated out: {}", first.id);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_cut_line_is_skipped_and_numbering_goes_on_from_the_files() {
        let dir = temp_dir("cut");
        std::fs::create_dir_all(&dir).unwrap();
        let good = serde_json::to_string(&event(7)).unwrap();
        std::fs::write(
            dir.join("events.jsonl"),
            format!("{good}\n{{\"id\":8,\"ti\n"),
        )
        .unwrap();
        let (_journal, restored) = Journal::open(&settings(&dir, 2, 10)).unwrap().unwrap();
        assert_eq!(restored.last_id, 7);
        assert_eq!(restored.skipped, 1);
        assert_eq!(restored.events, [event(7)]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn an_unusable_path_is_refused_with_its_name() {
        let err = Journal::open(&EventSettings {
            journal: Some("/proc/ecatd/events.jsonl".into()),
            ..EventSettings::default()
        })
        .err()
        .expect("refused");
        assert!(err.contains("/proc/ecatd/events.jsonl"), "{err}");
    }
}
