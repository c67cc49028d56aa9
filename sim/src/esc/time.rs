//! The time base the emulated ESCs' local clocks run on.
//!
//! Tests drive a [`ManualTime`] so that distributed-clock results are exact and repeatable;
//! a simulator on a real network uses [`MonotonicTime`].

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// A source of "now" in nanoseconds, read once per frame by a segment.
pub trait TimeSource: Send {
    /// Current time in ns since the source's origin.
    fn now_ns(&self) -> u64;
}

/// Time that moves only when told to. Clones share the same time, so a test keeps one
/// handle and gives another to the segment.
#[derive(Debug, Clone, Default)]
pub struct ManualTime {
    now: Arc<AtomicU64>,
}

impl ManualTime {
    /// A time base starting at `start_ns`.
    pub fn new(start_ns: u64) -> Self {
        ManualTime {
            now: Arc::new(AtomicU64::new(start_ns)),
        }
    }

    /// Moves the time forward by `ns` (saturating).
    pub fn advance(&self, ns: u64) {
        // fetch_update cannot fail with a closure that always returns Some.
        let _ = self
            .now
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |t| {
                Some(t.saturating_add(ns))
            });
    }

    /// Sets the time.
    pub fn set(&self, ns: u64) {
        self.now.store(ns, Ordering::SeqCst);
    }
}

impl TimeSource for ManualTime {
    fn now_ns(&self) -> u64 {
        self.now.load(Ordering::SeqCst)
    }
}

/// The host's monotonic clock, counted from the moment the source was created.
#[derive(Debug, Clone, Copy)]
pub struct MonotonicTime {
    origin: Instant,
}

impl MonotonicTime {
    /// A time base starting now at 0.
    pub fn new() -> Self {
        MonotonicTime {
            origin: Instant::now(),
        }
    }
}

impl Default for MonotonicTime {
    fn default() -> Self {
        Self::new()
    }
}

impl TimeSource for MonotonicTime {
    fn now_ns(&self) -> u64 {
        u64::try_from(self.origin.elapsed().as_nanos()).unwrap_or(u64::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn manual_time_is_shared_between_clones() {
        let a = ManualTime::new(10);
        let b = a.clone();
        a.advance(5);
        assert_eq!(b.now_ns(), 15);
        b.set(u64::MAX - 1);
        a.advance(10);
        assert_eq!(a.now_ns(), u64::MAX, "saturates");
    }

    #[test]
    fn monotonic_time_moves_forward() {
        let t = MonotonicTime::new();
        let first = t.now_ns();
        assert!(t.now_ns() >= first);
    }
}
