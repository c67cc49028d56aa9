//! A link wrapper that hands copies of the frames to a live capture on request, without
//! slowing the bus: [`CaptureTap`] sits around the bus's link for the whole run; while a
//! [`Capture`] is open it copies each frame into a bounded queue read by another thread, and
//! counts a frame it cannot queue (queue full) as dropped instead of waiting.
//!
//! Idle, the tap costs one relaxed atomic load per frame.

use std::io;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
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

/// The tap's side shared with whoever opens captures.
#[derive(Debug, Default)]
pub struct CaptureHub {
    active: AtomicBool,
    sink: Mutex<Option<SyncSender<CapturedFrame>>>,
    dropped: AtomicU64,
}

/// An open capture: frames from now on, until dropped.
#[derive(Debug)]
pub struct Capture {
    hub: Arc<CaptureHub>,
    frames: Receiver<CapturedFrame>,
    dropped_before: u64,
}

impl CaptureHub {
    /// A hub with no capture open.
    pub fn new() -> Arc<CaptureHub> {
        Arc::default()
    }

    /// Opens a capture whose queue holds `capacity` frames; `None` while another one is
    /// open (one at a time, so that no capture steals the other's frames).
    pub fn open(self: &Arc<Self>, capacity: usize) -> Option<Capture> {
        let mut sink = self.sink.lock().unwrap_or_else(PoisonError::into_inner);
        if sink.is_some() {
            return None;
        }
        let (tx, rx) = sync_channel(capacity.max(1));
        *sink = Some(tx);
        self.active.store(true, Ordering::Release);
        Some(Capture {
            hub: Arc::clone(self),
            frames: rx,
            dropped_before: self.dropped.load(Ordering::Relaxed),
        })
    }

    /// Called by the tap on the bus thread: never blocks.
    fn offer(&self, sent: bool, frame: &[u8]) {
        if !self.active.load(Ordering::Relaxed) {
            return;
        }
        // The lock is only contended while a capture opens or closes: skip, counted.
        let Ok(sink) = self.sink.try_lock() else {
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return;
        };
        let Some(tx) = sink.as_ref() else { return };
        let at = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        let copy = CapturedFrame {
            at,
            sent,
            frame: frame.to_vec(),
        };
        if let Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) = tx.try_send(copy) {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

impl Capture {
    /// The next frame, waiting at most `timeout`.
    pub fn next(&self, timeout: Duration) -> Option<CapturedFrame> {
        self.frames.recv_timeout(timeout).ok()
    }

    /// Frames the tap could not queue since this capture opened.
    pub fn dropped(&self) -> u64 {
        self.hub.dropped.load(Ordering::Relaxed) - self.dropped_before
    }
}

impl Drop for Capture {
    fn drop(&mut self) {
        self.hub.active.store(false, Ordering::Release);
        *self.hub.sink.lock().unwrap_or_else(PoisonError::into_inner) = None;
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::MemoryLink;

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
}
