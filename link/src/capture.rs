//! A link wrapper that hands copies of the frames to a live capture on request, without
//! slowing the bus: [`CaptureTap`] sits around the bus's link for the whole run; while a
//! [`Capture`] is open it copies each frame into a bounded queue read by another thread, and
//! counts a frame it cannot queue (queue full) as dropped instead of waiting.
//!
//! Two captures can be open at once, each with its own queue and drop count: one on demand
//! ([`CaptureHub::open`], one at a time) and one standing ([`CaptureHub::open_standing`],
//! the rolling capture that runs for as long as ecatd does).
//!
//! Idle, the tap costs one relaxed atomic load per frame.

use std::io;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use super::{Link, Wait};

/// One frame as it passed the tap.
#[derive(Debug, Clone)]
pub struct CapturedFrame {
    /// Wall-clock time it passed.
    pub at: Duration,
    /// Sent by the master (true) or received (false).
    pub sent: bool,
    /// The whole Ethernet frame.
    pub frame: Vec<u8>,
}

/// One capture's place in the hub: its queue while open, and the frames it dropped.
#[derive(Debug, Default)]
struct Slot {
    sink: Mutex<Option<SyncSender<CapturedFrame>>>,
    dropped: AtomicU64,
}

/// The slot of on-demand captures.
const LIVE: usize = 0;
/// The slot of the standing (rolling) capture.
const STANDING: usize = 1;

/// The tap's side shared with whoever opens captures.
#[derive(Debug, Default)]
pub struct CaptureHub {
    /// Captures open.
    active: AtomicUsize,
    slots: [Slot; 2],
}

/// An open capture: frames from now on, until dropped.
#[derive(Debug)]
pub struct Capture {
    hub: Arc<CaptureHub>,
    slot: usize,
    frames: Receiver<CapturedFrame>,
    dropped_before: u64,
}

impl CaptureHub {
    /// A hub with no capture open.
    pub fn new() -> Arc<CaptureHub> {
        Arc::default()
    }

    /// Opens a capture whose queue holds `capacity` frames; `None` while another one is
    /// open (one at a time, so that no capture steals the other's frames). The standing
    /// capture does not count: it gets its own copies.
    pub fn open(self: &Arc<Self>, capacity: usize) -> Option<Capture> {
        self.open_slot(LIVE, capacity)
    }

    /// Opens the standing capture (ecatd's rolling capture) beside any on-demand one;
    /// `None` while it is open already.
    pub fn open_standing(self: &Arc<Self>, capacity: usize) -> Option<Capture> {
        self.open_slot(STANDING, capacity)
    }

    fn open_slot(self: &Arc<Self>, slot: usize, capacity: usize) -> Option<Capture> {
        let mut sink = self.slots[slot]
            .sink
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        if sink.is_some() {
            return None;
        }
        let (tx, rx) = sync_channel(capacity.max(1));
        *sink = Some(tx);
        self.active.fetch_add(1, Ordering::AcqRel);
        Some(Capture {
            hub: Arc::clone(self),
            slot,
            frames: rx,
            dropped_before: self.slots[slot].dropped.load(Ordering::Relaxed),
        })
    }

    /// Called by the tap on the bus thread: never blocks.
    fn offer(&self, sent: bool, frame: &[u8]) {
        if self.active.load(Ordering::Relaxed) == 0 {
            return;
        }
        let at = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        for slot in &self.slots {
            // The lock is only contended while a capture opens or closes: skip, counted.
            let Ok(sink) = slot.sink.try_lock() else {
                slot.dropped.fetch_add(1, Ordering::Relaxed);
                continue;
            };
            let Some(tx) = sink.as_ref() else { continue };
            let copy = CapturedFrame {
                at,
                sent,
                frame: frame.to_vec(),
            };
            if let Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) = tx.try_send(copy) {
                slot.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

impl Capture {
    /// The next frame, waiting at most `timeout`.
    pub fn next(&self, timeout: Duration) -> Option<CapturedFrame> {
        self.frames.recv_timeout(timeout).ok()
    }

    /// The next frame if one is queued, without waiting.
    pub fn try_next(&self) -> Option<CapturedFrame> {
        self.frames.try_recv().ok()
    }

    /// Frames the tap could not queue since this capture opened.
    pub fn dropped(&self) -> u64 {
        self.hub.slots[self.slot].dropped.load(Ordering::Relaxed) - self.dropped_before
    }
}

impl Drop for Capture {
    fn drop(&mut self) {
        *self.hub.slots[self.slot]
            .sink
            .lock()
            .unwrap_or_else(PoisonError::into_inner) = None;
        self.hub.active.fetch_sub(1, Ordering::AcqRel);
    }
}

/// Wraps a link and offers every frame that passes, in both directions, to the hub's open
/// capture (if any).
#[derive(Debug)]
pub struct CaptureTap<L: Link> {
    inner: L,
    hub: Arc<CaptureHub>,
}

impl<L: Link> CaptureTap<L> {
    /// Wraps `inner`, feeding `hub`.
    pub fn new(inner: L, hub: Arc<CaptureHub>) -> CaptureTap<L> {
        CaptureTap { inner, hub }
    }
}

impl<L: Link> Link for CaptureTap<L> {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.inner.send(frame)?;
        self.hub.offer(true, frame);
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> io::Result<Option<usize>> {
        let got = self.inner.recv(buf, wait)?;
        if let Some(len) = got {
            self.hub.offer(false, &buf[..len]);
        }
        Ok(got)
    }

    fn wait_fd(&self) -> Option<std::os::fd::BorrowedFd<'_>> {
        self.inner.wait_fd()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MemoryLink;

    #[test]
    fn frames_reach_an_open_capture_and_overflow_is_counted() {
        let (a, mut b) = MemoryLink::pair(64);
        let hub = CaptureHub::new();
        let mut tap = CaptureTap::new(a, Arc::clone(&hub));
        tap.send(&[1; 60]).unwrap();
        let capture = hub.open(2).unwrap();
        assert!(hub.open(2).is_none(), "one capture at a time");
        for n in 0..4u8 {
            tap.send(&[n; 60]).unwrap();
        }
        let first = capture.next(Duration::from_millis(10)).unwrap();
        assert!(first.sent);
        assert_eq!(
            first.frame, [0; 60],
            "the frame before the capture is not in it"
        );
        assert_eq!(
            capture.next(Duration::from_millis(10)).unwrap().frame,
            [1; 60]
        );
        assert!(capture.next(Duration::from_millis(10)).is_none());
        assert_eq!(capture.dropped(), 2, "queue of 2: frames 2 and 3 dropped");
        let mut buf = [0; 64];
        b.send(&[9; 60]).unwrap();
        assert_eq!(tap.recv(&mut buf, Wait::NoWait).unwrap(), Some(60));
        let received = capture.next(Duration::from_millis(10)).unwrap();
        assert!(!received.sent);
        assert_eq!(received.frame, [9; 60]);
        drop(capture);
        assert!(hub.open(2).is_some(), "closed: a new capture may open");
    }

    #[test]
    fn the_standing_capture_gets_its_own_copies_and_drop_count() {
        let (a, _b) = MemoryLink::pair(64);
        let hub = CaptureHub::new();
        let mut tap = CaptureTap::new(a, Arc::clone(&hub));
        let standing = hub.open_standing(8).unwrap();
        assert!(hub.open_standing(8).is_none(), "one standing capture");
        let live = hub.open(1).unwrap();
        for n in 0..3u8 {
            tap.send(&[n; 60]).unwrap();
        }
        for n in 0..3u8 {
            assert_eq!(standing.try_next().unwrap().frame, [n; 60]);
        }
        assert_eq!(standing.dropped(), 0);
        assert_eq!(live.try_next().unwrap().frame, [0; 60]);
        assert!(live.try_next().is_none());
        assert_eq!(live.dropped(), 2, "queue of 1: frames 1 and 2 dropped");
        drop(live);
        tap.send(&[7; 60]).unwrap();
        assert_eq!(standing.try_next().unwrap().frame, [7; 60], "still open");
        drop(standing);
        tap.send(&[8; 60]).unwrap();
        assert!(hub.open_standing(1).unwrap().try_next().is_none());
    }
}
