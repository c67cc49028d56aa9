//! An in-process link: two ends joined by bounded frame queues, like a short cable.
//!
//! Used by tests and to run the simulator on its own thread without a network interface.
//! Each direction is a ring of fixed-size slots allocated once, so passing a frame copies it
//! but never allocates.

use std::io;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use super::{Link, MAX_FRAME_LEN, Wait};

/// One end of an in-process link made by [`MemoryLink::pair`].
///
/// What one end sends, the other receives, in order and byte for byte. A sender never
/// blocks: when the receiving end's queue is full the frame is dropped, as a busy wire would
/// lose it, and counted in [`MemoryLink::dropped`].
#[derive(Debug)]
pub struct MemoryLink {
    /// Frames this end sends (the peer's receive queue).
    tx: Arc<Queue>,
    /// Frames this end receives.
    rx: Arc<Queue>,
    /// Frames this end sent that were lost because the peer's queue was full.
    dropped: u64,
}

impl MemoryLink {
    /// Makes two joined ends, each able to hold `capacity` frames it has not yet received.
    ///
    /// Each direction reserves `capacity` × [`MAX_FRAME_LEN`] bytes up front.
    ///
    /// # Panics
    /// If `capacity` is zero: such a link could carry nothing.
    pub fn pair(capacity: usize) -> (MemoryLink, MemoryLink) {
        assert!(
            capacity > 0,
            "a memory link needs room for at least one frame"
        );
        let a_to_b = Arc::new(Queue::new(capacity));
        let b_to_a = Arc::new(Queue::new(capacity));
        let a = MemoryLink {
            tx: Arc::clone(&a_to_b),
            rx: Arc::clone(&b_to_a),
            dropped: 0,
        };
        let b = MemoryLink {
            tx: b_to_a,
            rx: a_to_b,
            dropped: 0,
        };
        (a, b)
    }

    /// How many frames this end sent that were dropped because the other end's queue was
    /// full.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// How many frames are waiting to be received by this end.
    pub fn pending(&self) -> usize {
        self.rx.lock().len
    }
}

impl Link for MemoryLink {
    /// Queues `frame` for the other end, or drops it (counting it) if that queue is full.
    ///
    /// Fails with `InvalidInput` for a frame longer than [`MAX_FRAME_LEN`], and with
    /// `BrokenPipe` once the other end has been dropped.
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        if frame.len() > MAX_FRAME_LEN {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "frame of {} bytes is longer than the {MAX_FRAME_LEN} bytes a memory link carries",
                    frame.len()
                ),
            ));
        }
        let mut ring = self.tx.lock();
        if ring.closed {
            return Err(peer_gone());
        }
        if ring.push(frame) {
            drop(ring);
            self.tx.ready.notify_one();
        } else {
            self.dropped += 1;
        }
        Ok(())
    }

    /// Takes the oldest queued frame, waiting for one until the deadline.
    ///
    /// Frames already queued are delivered even after the other end is dropped; after that,
    /// fails with `BrokenPipe` so that a simulator thread knows its master is gone.
    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> io::Result<Option<usize>> {
        let mut ring = self.rx.lock();
        loop {
            if let Some(len) = ring.pop_into(buf) {
                return Ok(Some(len));
            }
            if ring.closed {
                return Err(peer_gone());
            }
            let Wait::Until(deadline) = wait else {
                return Ok(None);
            };
            let now = Instant::now();
            if now >= deadline {
                return Ok(None);
            }
            // A spurious or early wake-up just goes round the loop again with the time left.
            ring = self
                .rx
                .ready
                .wait_timeout(ring, deadline - now)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
    }
}

impl Drop for MemoryLink {
    fn drop(&mut self) {
        // Tell the other end, including a receiver blocked in `recv`, that nobody is left.
        for queue in [&self.tx, &self.rx] {
            queue.lock().closed = true;
            queue.ready.notify_all();
        }
    }
}

fn peer_gone() -> io::Error {
    io::Error::new(
        io::ErrorKind::BrokenPipe,
        "the other end of the memory link was dropped",
    )
}

/// One direction of a pair: a ring of frames and a condition variable for waiting receivers.
#[derive(Debug)]
struct Queue {
    ring: Mutex<Ring>,
    ready: Condvar,
}

impl Queue {
    fn new(capacity: usize) -> Queue {
        Queue {
            ring: Mutex::new(Ring {
                bytes: vec![0; capacity * MAX_FRAME_LEN].into_boxed_slice(),
                lens: vec![0; capacity].into_boxed_slice(),
                head: 0,
                len: 0,
                closed: false,
            }),
            ready: Condvar::new(),
        }
    }

    fn lock(&self) -> MutexGuard<'_, Ring> {
        // The ring is left consistent at every point where a holder could panic (there are
        // none between updates), so a poisoned lock is still safe to use.
        self.ring.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// Fixed-size slots of [`MAX_FRAME_LEN`] bytes, `lens[i]` bytes used in slot `i`.
#[derive(Debug)]
struct Ring {
    bytes: Box<[u8]>,
    lens: Box<[usize]>,
    /// Slot of the oldest frame.
    head: usize,
    /// Frames queued.
    len: usize,
    /// Set when either end is dropped (the other end is then the only one left).
    closed: bool,
}

impl Ring {
    fn capacity(&self) -> usize {
        self.lens.len()
    }

    /// The byte range of slot `index` in `bytes`.
    fn slot(index: usize) -> std::ops::Range<usize> {
        index * MAX_FRAME_LEN..(index + 1) * MAX_FRAME_LEN
    }

    /// Appends a frame of at most [`MAX_FRAME_LEN`] bytes; false if the ring is full.
    fn push(&mut self, frame: &[u8]) -> bool {
        if self.len == self.capacity() {
            return false;
        }
        let index = (self.head + self.len) % self.capacity();
        self.bytes[Ring::slot(index)][..frame.len()].copy_from_slice(frame);
        self.lens[index] = frame.len();
        self.len += 1;
        true
    }

    /// Moves the oldest frame into `buf` (cut to fit), returning the bytes copied.
    fn pop_into(&mut self, buf: &mut [u8]) -> Option<usize> {
        if self.len == 0 {
            return None;
        }
        let index = self.head;
        let len = self.lens[index].min(buf.len());
        buf[..len].copy_from_slice(&self.bytes[Ring::slot(index)][..len]);
        self.head = (self.head + 1) % self.capacity();
        self.len -= 1;
        Some(len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ring_keeps_order_across_wrap_around_and_refuses_when_full() {
        let queue = Queue::new(3);
        let mut ring = queue.lock();
        let mut buf = [0u8; 8];
        for round in 0u8..5 {
            assert!(ring.push(&[round, 1]));
            assert!(ring.push(&[round, 2, 2]));
            assert!(ring.push(&[round]));
            assert!(!ring.push(&[0xff]), "a fourth frame fits in three slots");
            assert_eq!(ring.pop_into(&mut buf), Some(2));
            assert_eq!(&buf[..2], &[round, 1]);
            assert_eq!(ring.pop_into(&mut buf), Some(3));
            assert_eq!(&buf[..3], &[round, 2, 2]);
            assert_eq!(ring.pop_into(&mut buf), Some(1));
            assert_eq!(&buf[..1], &[round]);
            assert_eq!(ring.pop_into(&mut buf), None);
        }
    }
}
