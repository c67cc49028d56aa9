//! [`InProcessLink`]: a `ecat_link::Link` whose wire is a simulated segment.
//!
//! `send` runs the frame through the segment at once (the slaves process it in place, as
//! the frame passes them) and queues what comes back; `recv` takes the oldest returned
//! frame. No thread and no clock: the same frames in give the same frames out, so a master
//! test on this link is deterministic. A frame the segment does not return (no slave
//! reachable, not an EtherCAT frame) is lost, as on a wire.
//!
//! The segment sits behind a shared handle so a test can reach the slaves (unplug one,
//! drive inputs, read registers) while the master owns the link. Fault injection comes from
//! wrapping the link in `ecat_link::FaultInjector`.

use std::collections::VecDeque;
use std::io;
use std::sync::{Arc, Mutex, MutexGuard};

use ecat_link::{Link, MAX_FRAME_LEN, Wait};

use crate::segment::Segment;

/// A segment shared between the link and the test that built it.
pub type SharedSegment = Arc<Mutex<Segment>>;

/// Frames returned but not yet received, by default.
pub const DEFAULT_QUEUE: usize = 64;

/// A link straight into a simulated segment.
#[derive(Debug)]
pub struct InProcessLink {
    segment: SharedSegment,
    returned: VecDeque<Vec<u8>>,
    capacity: usize,
    dropped: u64,
}

impl InProcessLink {
    /// A link into `segment`, holding at most [`DEFAULT_QUEUE`] returned frames.
    pub fn new(segment: Segment) -> Self {
        Self::shared(Arc::new(Mutex::new(segment)), DEFAULT_QUEUE)
    }

    /// A link into a segment the caller also holds; at most `capacity` returned frames wait
    /// (more are dropped, as a full receive ring would).
    pub fn shared(segment: SharedSegment, capacity: usize) -> Self {
        InProcessLink {
            segment,
            returned: VecDeque::new(),
            capacity,
            dropped: 0,
        }
    }

    /// The segment handle.
    pub fn segment(&self) -> SharedSegment {
        Arc::clone(&self.segment)
    }

    /// Locks the segment (e.g. to reach a slave between frames).
    pub fn lock(&self) -> MutexGuard<'_, Segment> {
        self.segment
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Returned frames dropped because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Returned frames waiting.
    pub fn pending(&self) -> usize {
        self.returned.len()
    }
}

impl Link for InProcessLink {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        if frame.len() > MAX_FRAME_LEN {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "frame longer than an Ethernet frame",
            ));
        }
        let mut buf = frame.to_vec();
        let returned = self.lock().process(&mut buf);
        if returned {
            if self.returned.len() >= self.capacity {
                self.dropped += 1;
            } else {
                self.returned.push_back(buf);
            }
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], _wait: Wait) -> io::Result<Option<usize>> {
        // Nothing can arrive later: every frame came back during its send.
        Ok(self.returned.pop_front().map(|frame| {
            let len = frame.len().min(buf.len());
            buf[..len].copy_from_slice(&frame[..len]);
            len
        }))
    }
}
