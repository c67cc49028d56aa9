//! [`InProcessLink`]: a `ecat_link::Link` whose wire is a simulated segment, and
//! [`RingPort`]: the two ports of a master wired to a segment as a ring (cable redundancy).
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
use std::os::fd::{AsFd, BorrowedFd};
use std::sync::{Arc, Mutex, MutexGuard};

use ecat_link::{EventFd, Link, MAX_FRAME_LEN, Wait};

use crate::segment::{Port, Segment};

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
    /// Readable while `returned` holds a frame: the link's [`Link::wait_fd`], so that the
    /// bus can wait on it beside a guest's descriptor (`None` if the system gave none).
    waiting: Option<EventFd>,
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
            waiting: EventFd::new().ok(),
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
                if self.returned.len() == 1
                    && let Some(waiting) = &self.waiting
                {
                    waiting.signal();
                }
            }
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], _wait: Wait) -> io::Result<Option<usize>> {
        // Nothing can arrive later: every frame came back during its send.
        let frame = self.returned.pop_front();
        if frame.is_some()
            && self.returned.is_empty()
            && let Some(waiting) = &self.waiting
        {
            waiting.drain();
        }
        Ok(frame.map(|frame| {
            let len = frame.len().min(buf.len());
            buf[..len].copy_from_slice(&frame[..len]);
            len
        }))
    }

    fn wait_fd(&self) -> Option<BorrowedFd<'_>> {
        self.waiting.as_ref().map(AsFd::as_fd)
    }
}

/// The frames waiting at a ring master's two ports, by [`Port`].
#[derive(Debug)]
struct RingQueues {
    returned: [VecDeque<Vec<u8>>; 2],
    dropped: [u64; 2],
    capacity: usize,
}

impl RingQueues {
    fn index(port: Port) -> usize {
        match port {
            Port::Primary => 0,
            Port::Backup => 1,
        }
    }
}

/// One of the two ports of a master wired to a simulated segment as a ring: a frame sent
/// on it runs through the segment at once from this port, and waits on the port it comes
/// back on (this one, the other one, or none when it is lost), as
/// [`crate::segment::Segment::process_from`] decides. Deterministic like [`InProcessLink`]:
/// no thread, no clock, and `recv` never waits.
#[derive(Debug)]
pub struct RingPort {
    port: Port,
    segment: SharedSegment,
    queues: Arc<Mutex<RingQueues>>,
}

impl RingPort {
    /// The two ports of a master wired to `segment` as a ring: (primary, backup). Wires the
    /// segment's last slave back to the backup port ([`Segment::set_ring`]). A frame sent
    /// on one port is processed at once and queued on the port it returns on (at most
    /// `capacity` frames wait per port; more are dropped and counted).
    pub fn pair(segment: SharedSegment, capacity: usize) -> (RingPort, RingPort) {
        lock(&segment).set_ring(true);
        let queues = Arc::new(Mutex::new(RingQueues {
            returned: [VecDeque::new(), VecDeque::new()],
            dropped: [0; 2],
            capacity,
        }));
        let port = |port| RingPort {
            port,
            segment: Arc::clone(&segment),
            queues: Arc::clone(&queues),
        };
        (port(Port::Primary), port(Port::Backup))
    }

    /// The segment handle.
    pub fn segment(&self) -> SharedSegment {
        Arc::clone(&self.segment)
    }

    /// Which of the master's ports this is.
    pub fn port(&self) -> Port {
        self.port
    }

    /// Frames dropped on this port because its queue was full.
    pub fn dropped(&self) -> u64 {
        self.queues().dropped[RingQueues::index(self.port)]
    }

    /// Frames waiting on this port.
    pub fn pending(&self) -> usize {
        self.queues().returned[RingQueues::index(self.port)].len()
    }

    fn queues(&self) -> MutexGuard<'_, RingQueues> {
        self.queues
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

impl Link for RingPort {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        if frame.len() > MAX_FRAME_LEN {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "frame longer than an Ethernet frame",
            ));
        }
        let mut buf = frame.to_vec();
        // The segment's lock is let go before the queues' is taken: never both at once.
        let returned = lock(&self.segment).process_from(self.port, &mut buf);
        if let Some(port) = returned {
            let mut queues = self.queues();
            let at = RingQueues::index(port);
            if queues.returned[at].len() >= queues.capacity {
                queues.dropped[at] += 1;
            } else {
                queues.returned[at].push_back(buf);
            }
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], _wait: Wait) -> io::Result<Option<usize>> {
        // Nothing can arrive later: every frame came back during its send.
        let frame = self.queues().returned[RingQueues::index(self.port)].pop_front();
        Ok(frame.map(|frame| {
            let len = frame.len().min(buf.len());
            buf[..len].copy_from_slice(&frame[..len]);
            len
        }))
    }
}

/// Locks a shared segment, taking it over from a thread that panicked with it.
fn lock(segment: &SharedSegment) -> MutexGuard<'_, Segment> {
    segment
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::esc::test_support::slave;
    use ecat_wire::command::{Command, DatagramAddress};
    use ecat_wire::datagram::{DatagramRepr, FrameBuilder};
    use ecat_wire::frame::EthercatFrame;

    const N: usize = 4;

    fn ring(capacity: usize) -> (RingPort, RingPort) {
        let mut segment = Segment::default();
        for _ in 0..N {
            let (esc, device) = slave();
            segment.push(esc, Box::new(device));
        }
        RingPort::pair(Arc::new(Mutex::new(segment)), capacity)
    }

    fn brd() -> Vec<u8> {
        let mut buf = vec![0u8; MAX_FRAME_LEN];
        let mut builder = FrameBuilder::new(&mut buf).unwrap();
        let repr =
            DatagramRepr::request(Command::Brd, 7, DatagramAddress::broadcast(0x0000), &[0, 0]);
        builder.push(&repr).unwrap();
        let len = builder.finish([0x02, 1, 1, 1, 1, 1]).unwrap();
        buf.truncate(len);
        buf
    }

    /// The working counter of the frame waiting on `port`, `None` when none waits.
    fn wkc(port: &mut RingPort) -> Option<u16> {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let len = port.recv(&mut buf, Wait::NoWait).unwrap()?;
        let frame = EthercatFrame::parse(&buf[..len]).unwrap();
        let datagram = frame.datagrams().unwrap().next().unwrap().unwrap();
        Some(datagram.wkc)
    }

    #[test]
    fn a_closed_ring_returns_each_ports_frames_on_the_other_port() {
        let (mut primary, mut backup) = ring(8);
        assert_eq!(
            (primary.port(), backup.port()),
            (Port::Primary, Port::Backup)
        );
        assert!(primary.segment().lock().unwrap().is_ring());
        primary.send(&brd()).unwrap();
        assert_eq!(wkc(&mut primary), None);
        assert_eq!(wkc(&mut backup), Some(N as u16), "processed by every slave");
        backup.send(&brd()).unwrap();
        assert_eq!(wkc(&mut backup), None);
        assert_eq!(wkc(&mut primary), Some(0), "passed every slave unprocessed");
    }

    #[test]
    fn a_broken_ring_returns_each_ports_frames_on_that_port() {
        let (mut primary, mut backup) = ring(8);
        primary.segment().lock().unwrap().break_cable(1).unwrap();
        primary.send(&brd()).unwrap();
        backup.send(&brd()).unwrap();
        assert_eq!(wkc(&mut primary), Some(1));
        assert_eq!(wkc(&mut backup), Some(N as u16 - 1));
        assert_eq!((wkc(&mut primary), wkc(&mut backup)), (None, None));
        // A cut master cable loses what is sent into it.
        primary.segment().lock().unwrap().break_cable(0).unwrap();
        primary.send(&brd()).unwrap();
        assert_eq!((primary.pending(), backup.pending()), (0, 0));
        primary.segment().lock().unwrap().heal();
        primary.send(&brd()).unwrap();
        assert_eq!(wkc(&mut backup), Some(N as u16));
    }

    #[test]
    fn a_full_port_drops_and_counts_frames() {
        let (mut primary, backup) = ring(1);
        primary.send(&brd()).unwrap();
        primary.send(&brd()).unwrap();
        assert_eq!((backup.pending(), backup.dropped()), (1, 1));
        assert_eq!(primary.dropped(), 0);
        let err = primary.send(&[0; MAX_FRAME_LEN + 1]).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
    }
}
