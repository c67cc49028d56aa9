//! The rolling capture (`[capture] rolling = true`): a writer thread takes the bus's frames
//! from the [`CaptureHub`]'s standing capture (a bounded queue: frames it cannot queue are
//! dropped and counted, never waited for) and writes them into a ring of pcapng files, each
//! one complete section (header, Ethernet interface at nanosecond resolution, packets). A
//! file is closed before it would pass its size, or once it covers its time; when a new
//! file would make the ring longer than its count, the oldest is removed. So the ring never
//! holds more than `files` × `file_kib` KiB.
//!
//! [`RollingCapture::window`] returns the ring, oldest file first, as one pcapng file of
//! several sections (which pcapng readers take as it is).

use std::collections::VecDeque;
use std::fs::File;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use master_core::link::{CaptureHub, CapturedFrame};

use crate::config::capture::CaptureSettings;

/// Ring files are named `rolling-NNNNNN.pcapng`.
const PREFIX: &str = "rolling-";
const SUFFIX: &str = ".pcapng";
/// Section header and interface description blocks of each file (pcapng: SHB of 28 bytes
/// without options, IDB of 20 plus the 12-byte if_tsresol option and end of options).
const FILE_HEADER: [u8; 60] = file_header();
/// How long the writer waits for a frame before it looks at its stop flag again.
const IDLE: Duration = Duration::from_millis(100);
/// Packets wait in memory at most this long before they go to the file (what a crash
/// loses).
const FLUSH_EVERY: Duration = Duration::from_millis(50);
/// Or until this many bytes wait.
const FLUSH_BYTES: usize = 64 << 10;

/// The file being written: packets gather in `pending` and go to the file whole, so that
/// the file on disk always ends on a block boundary (readable whatever happens to ecatd).
struct Current {
    file: File,
    pending: Vec<u8>,
    flushed_at: Instant,
}

impl Current {
    fn flush(&mut self) -> io::Result<()> {
        if !self.pending.is_empty() {
            self.file.write_all(&self.pending)?;
            self.pending.clear();
        }
        self.flushed_at = Instant::now();
        Ok(())
    }
}

/// Counters of the rolling capture (exported as metrics).
#[derive(Debug, Default)]
pub struct RollingStats {
    /// Frames written to the ring.
    pub frames: AtomicU64,
    /// Frames the tap could not queue (the writer fell behind).
    pub dropped: AtomicU64,
    /// Files closed and replaced by a new one.
    pub rotations: AtomicU64,
    /// Write errors (the frame is lost; the writer starts a new file).
    pub errors: AtomicU64,
}

/// The ring's files and the one being written.
struct Ring {
    dir: PathBuf,
    files: usize,
    file_bytes: u64,
    file_time: Option<Duration>,
    /// Closed files, oldest first, then the current one (last).
    paths: VecDeque<PathBuf>,
    current: Option<Current>,
    current_len: u64,
    current_since: Instant,
    next_number: u64,
}

/// A running rolling capture.
pub struct RollingCapture {
    ring: Arc<Mutex<Ring>>,
    stats: Arc<RollingStats>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl RollingCapture {
    /// Starts the ring in `settings.dir` (made if missing; ring files of an earlier run
    /// removed) over the hub's standing capture.
    pub fn start(hub: &Arc<CaptureHub>, settings: &CaptureSettings) -> Result<Self, String> {
        let dir = settings.dir.clone();
        std::fs::create_dir_all(&dir)
            .map_err(|err| format!("[capture] dir {}: {err}", dir.display()))?;
        remove_old_files(&dir)?;
        let capture = hub
            .open_standing(settings.queue)
            .ok_or("the rolling capture is running already")?;
        let ring = Arc::new(Mutex::new(Ring {
            dir,
            files: settings.files,
            file_bytes: settings.file_kib * 1024,
            file_time: settings.file_time,
            paths: VecDeque::new(),
            current: None,
            current_len: 0,
            current_since: Instant::now(),
            next_number: 1,
        }));
        let stats = Arc::new(RollingStats::default());
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (ring, stats, stop) = (Arc::clone(&ring), Arc::clone(&stats), Arc::clone(&stop));
            std::thread::Builder::new()
                .name("ecatd-rolling-capture".into())
                .spawn(move || {
                    while !stop.load(Ordering::Relaxed) {
                        let frame = capture.next(IDLE);
                        stats.dropped.store(capture.dropped(), Ordering::Relaxed);
                        let mut ring = ring.lock().unwrap_or_else(PoisonError::into_inner);
                        if let Some(frame) = frame {
                            ring.write(&frame, &stats);
                            // Take what queued meanwhile under the same lock, a batch at
                            // most.
                            for _ in 0..256 {
                                let Some(frame) = capture.try_next() else {
                                    break;
                                };
                                ring.write(&frame, &stats);
                            }
                        }
                        ring.flush_if_due(&stats);
                    }
                    ring.lock()
                        .unwrap_or_else(PoisonError::into_inner)
                        .flush(&stats);
                })
                .map_err(|err| format!("cannot start the rolling capture: {err}"))?
        };
        Ok(RollingCapture {
            ring,
            stats,
            stop,
            thread: Some(thread),
        })
    }

    /// The counters.
    pub fn stats(&self) -> &Arc<RollingStats> {
        &self.stats
    }

    /// The ring's files as they are on disk, oldest first (the last one being written).
    pub fn files(&self) -> Vec<PathBuf> {
        let ring = self.ring.lock().unwrap_or_else(PoisonError::into_inner);
        ring.paths.iter().cloned().collect()
    }

    /// The ring as one pcapng file of one section per file, oldest first, at most
    /// `max_bytes` (the newest files that fit), with the number of packets in it.
    /// Blocking: call off the async runtime.
    pub fn window(&self, max_bytes: usize) -> io::Result<(Vec<u8>, u64)> {
        let mut ring = self.ring.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(current) = ring.current.as_mut() {
            current.flush()?;
        }
        let mut sections = Vec::new();
        let mut total = 0;
        for path in ring.paths.iter().rev() {
            let data = std::fs::read(path)?;
            if total + data.len() > max_bytes {
                break;
            }
            total += data.len();
            sections.push(data);
        }
        drop(ring);
        let packets = sections.iter().map(|s| count_packets(s)).sum();
        Ok((sections.into_iter().rev().flatten().collect(), packets))
    }
}

impl Drop for RollingCapture {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Ring {
    /// Appends one frame as an Enhanced Packet Block, rotating first when it would pass
    /// the file's size or the file is older than its time.
    fn write(&mut self, frame: &CapturedFrame, stats: &RollingStats) {
        let block = packet_block(frame);
        let full = self.current_len + block.len() as u64 > self.file_bytes;
        let old = self
            .file_time
            .is_some_and(|t| self.current_since.elapsed() >= t);
        if (self.current.is_none() || full || old)
            && let Err(err) = self.rotate(stats)
        {
            stats.errors.fetch_add(1, Ordering::Relaxed);
            tracing::warn!(%err, "rolling capture: cannot start a new file");
            self.current = None;
            return;
        }
        let Some(current) = self.current.as_mut() else {
            return;
        };
        current.pending.extend_from_slice(&block);
        self.current_len += block.len() as u64;
        stats.frames.fetch_add(1, Ordering::Relaxed);
    }

    /// Closes the current file, removes the oldest ones so that the new one keeps the ring
    /// at its count, and starts the new one.
    fn rotate(&mut self, stats: &RollingStats) -> io::Result<()> {
        if let Some(mut done) = self.current.take() {
            done.flush()?;
            stats.rotations.fetch_add(1, Ordering::Relaxed);
        }
        while self.paths.len() >= self.files {
            if let Some(oldest) = self.paths.pop_front() {
                std::fs::remove_file(&oldest)?;
            }
        }
        let path = self
            .dir
            .join(format!("{PREFIX}{:06}{SUFFIX}", self.next_number));
        self.next_number += 1;
        let mut file = File::create(&path)?;
        file.write_all(&FILE_HEADER)?;
        self.paths.push_back(path);
        self.current = Some(Current {
            file,
            pending: Vec::with_capacity(FLUSH_BYTES),
            flushed_at: Instant::now(),
        });
        self.current_len = FILE_HEADER.len() as u64;
        self.current_since = Instant::now();
        Ok(())
    }

    /// Writes the waiting packets out when they have waited long enough or are many.
    fn flush_if_due(&mut self, stats: &RollingStats) {
        let due = self.current.as_ref().is_some_and(|c| {
            c.pending.len() >= FLUSH_BYTES || c.flushed_at.elapsed() >= FLUSH_EVERY
        });
        if due {
            self.flush(stats);
        }
    }

    /// Writes the waiting packets out; on failure the file is given up (the next frame
    /// starts a new one) and the error counted.
    fn flush(&mut self, stats: &RollingStats) {
        if let Some(current) = self.current.as_mut()
            && let Err(err) = current.flush()
        {
            stats.errors.fetch_add(1, Ordering::Relaxed);
            tracing::warn!(%err, "rolling capture: write failed; starting a new file");
            self.current = None;
        }
    }
}

/// Removes the ring files an earlier run left (only those: the directory may hold more).
fn remove_old_files(dir: &Path) -> Result<(), String> {
    let entries =
        std::fs::read_dir(dir).map_err(|err| format!("[capture] dir {}: {err}", dir.display()))?;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if name.starts_with(PREFIX) && name.ends_with(SUFFIX) {
            std::fs::remove_file(entry.path())
                .map_err(|err| format!("[capture] {}: {err}", entry.path().display()))?;
        }
    }
    Ok(())
}

/// The section header block (byte-order magic, version 1.0, section length unknown) and
/// the interface description block (Ethernet, no snap length, if_tsresol 9: nanoseconds);
/// pcapng, draft-ietf-opsawg-pcapng §4.1 and §4.2, little-endian.
const fn file_header() -> [u8; 60] {
    let mut h = [0u8; 60];
    let shb: [u8; 28] = [
        0x0A, 0x0D, 0x0D, 0x0A, // block type SHB
        28, 0, 0, 0, // block length
        0x4D, 0x3C, 0x2B, 0x1A, // byte-order magic
        1, 0, 0, 0, // version 1.0
        0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, // section length: not given
        28, 0, 0, 0, // block length again
    ];
    let idb: [u8; 32] = [
        1, 0, 0, 0, // block type IDB
        32, 0, 0, 0, // block length
        1, 0, // link type: Ethernet
        0, 0, // reserved
        0, 0, 0, 0, // snap length: none
        9, 0, 1, 0, 9, 0, 0, 0, // option if_tsresol (9), length 1, value 9, padding
        0, 0, 0, 0, // opt_endofopt
        32, 0, 0, 0, // block length again
    ];
    let mut i = 0;
    while i < 28 {
        h[i] = shb[i];
        i += 1;
    }
    while i < 60 {
        h[i] = idb[i - 28];
        i += 1;
    }
    h
}

/// Enhanced Packet Blocks in a section this writer wrote (little-endian blocks, each
/// its type and total length first).
fn count_packets(section: &[u8]) -> u64 {
    let mut at = 0;
    let mut packets = 0;
    while let Some(head) = section.get(at..at + 8) {
        let kind = u32::from_le_bytes([head[0], head[1], head[2], head[3]]);
        let len = u32::from_le_bytes([head[4], head[5], head[6], head[7]]) as usize;
        if len < 12 {
            break;
        }
        packets += u64::from(kind == 6);
        at += len;
    }
    packets
}

/// One Enhanced Packet Block (pcapng §4.3): interface 0, time in ns, the whole frame,
/// padded to 32 bits.
fn packet_block(frame: &CapturedFrame) -> Vec<u8> {
    let len = frame.frame.len();
    let padded = len.div_ceil(4) * 4;
    let total = 32 + padded;
    let ns = u64::try_from(frame.at.as_nanos()).unwrap_or(u64::MAX);
    let mut b = Vec::with_capacity(total);
    b.extend_from_slice(&6u32.to_le_bytes());
    b.extend_from_slice(&(total as u32).to_le_bytes());
    b.extend_from_slice(&0u32.to_le_bytes());
    b.extend_from_slice(&((ns >> 32) as u32).to_le_bytes());
    b.extend_from_slice(&(ns as u32).to_le_bytes());
    b.extend_from_slice(&(len as u32).to_le_bytes());
    b.extend_from_slice(&(len as u32).to_le_bytes());
    b.extend_from_slice(&frame.frame);
    b.resize(28 + padded, 0);
    b.extend_from_slice(&(total as u32).to_le_bytes());
    b
}

#[cfg(test)]
mod tests {
    use super::*;
    use master_core::link::{CaptureTap, Link, MemoryLink};

    fn settings(dir: &Path, files: usize, file_kib: u64, queue: usize) -> CaptureSettings {
        CaptureSettings {
            rolling: true,
            dir: dir.to_path_buf(),
            files,
            file_kib,
            file_time: None,
            queue,
        }
    }

    fn wait_for(what: &str, mut done: impl FnMut() -> bool) {
        let deadline = Instant::now() + Duration::from_secs(10);
        while !done() {
            assert!(Instant::now() < deadline, "timed out waiting for {what}");
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    #[test]
    fn the_ring_rotates_within_its_bound_and_reads_back_whole() {
        let dir = std::env::temp_dir().join(format!("ecatd-rolling-unit-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("rolling-000009.pcapng"), b"stale").unwrap();
        std::fs::write(dir.join("keep.txt"), b"not ours").unwrap();
        let hub = CaptureHub::new();
        let (a, _b) = MemoryLink::pair(4096);
        let mut tap = CaptureTap::new(a, Arc::clone(&hub));
        let rolling = RollingCapture::start(&hub, &settings(&dir, 3, 16, 100_000)).unwrap();
        assert!(
            !dir.join("rolling-000009.pcapng").exists(),
            "stale ring file removed"
        );
        assert!(dir.join("keep.txt").exists(), "other files kept");
        // 1000 frames of 100 bytes: 132 bytes a block, about 8 files of 16 KiB.
        for n in 0..1000u32 {
            let mut frame = vec![0u8; 100];
            frame[..4].copy_from_slice(&n.to_le_bytes());
            tap.send(&frame).unwrap();
        }
        let stats = Arc::clone(rolling.stats());
        wait_for("1000 frames", || {
            stats.frames.load(Ordering::Relaxed) == 1000
        });
        let files = rolling.files();
        assert_eq!(files.len(), 3, "{files:?}");
        assert!(stats.rotations.load(Ordering::Relaxed) >= 5);
        for file in &files {
            let len = std::fs::metadata(file).unwrap().len();
            assert!(len <= 16 * 1024, "{} is {len} bytes", file.display());
        }
        let (window, packets) = rolling.window(usize::MAX).unwrap();
        assert!(packets > 200 && packets < 1000, "{packets}");
        // Every section starts with the header; the last packet is frame 999.
        let sections = window
            .windows(FILE_HEADER.len())
            .filter(|w| *w == FILE_HEADER)
            .count();
        assert_eq!(sections, 3);
        let tail = &window[window.len() - 4 - 100..window.len() - 4];
        assert_eq!(&tail[..4], &999u32.to_le_bytes());
        let (newest_only, _) = rolling.window(16 * 1024).unwrap();
        assert_eq!(newest_only, std::fs::read(&files[2]).unwrap());
        drop(rolling);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_file_older_than_its_time_is_closed_for_a_new_one() {
        let dir = std::env::temp_dir().join(format!("ecatd-rolling-time-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let hub = CaptureHub::new();
        let (a, _b) = MemoryLink::pair(4096);
        let mut tap = CaptureTap::new(a, Arc::clone(&hub));
        let mut config = settings(&dir, 4, 1024, 16);
        config.file_time = Some(Duration::from_millis(100));
        let rolling = RollingCapture::start(&hub, &config).unwrap();
        let stats = Arc::clone(rolling.stats());
        tap.send(&[1; 60]).unwrap();
        wait_for("the first frame", || {
            stats.frames.load(Ordering::Relaxed) == 1
        });
        tap.send(&[2; 60]).unwrap();
        wait_for("the second frame", || {
            stats.frames.load(Ordering::Relaxed) == 2
        });
        assert_eq!(
            rolling.files().len(),
            1,
            "both frames within 100 ms of the file's start"
        );
        // The time under test passing, not a synchronisation.
        std::thread::sleep(Duration::from_millis(150));
        tap.send(&[3; 60]).unwrap();
        wait_for("the third frame", || {
            stats.frames.load(Ordering::Relaxed) == 3
        });
        assert_eq!(rolling.files().len(), 2, "a new file after 100 ms");
        assert_eq!(stats.rotations.load(Ordering::Relaxed), 1);
        let (_, packets) = rolling.window(usize::MAX).unwrap();
        assert_eq!(packets, 3);
        drop(rolling);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn frames_the_writer_cannot_take_are_counted_as_dropped() {
        let dir = std::env::temp_dir().join(format!("ecatd-rolling-drop-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let hub = CaptureHub::new();
        let (a, _b) = MemoryLink::pair(4096);
        let mut tap = CaptureTap::new(a, Arc::clone(&hub));
        let rolling = RollingCapture::start(&hub, &settings(&dir, 2, 16, 1)).unwrap();
        // Hold the ring so that the writer stops taking frames; its queue holds one.
        let held = rolling.ring.lock().unwrap();
        for _ in 0..50 {
            tap.send(&[1; 60]).unwrap();
        }
        drop(held);
        let stats = Arc::clone(rolling.stats());
        wait_for("the drops counted", || {
            stats.dropped.load(Ordering::Relaxed) + stats.frames.load(Ordering::Relaxed) == 50
        });
        assert!(stats.dropped.load(Ordering::Relaxed) >= 47, "{stats:?}");
        drop(rolling);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
