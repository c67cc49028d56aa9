//! The Ethernet side of an EoE slave handed to something outside the simulator (ecat-sim's
//! TAP bridge), instead of the slave's own IP host.
//!
//! A [`HostPort`] is made with every EoE service and does nothing until
//! [`HostPort::attach`]: from then on every frame the master sends through EoE, and every
//! Set IP parameter the slave accepts, goes to [`HostPort::next_event`]; frames given to
//! [`HostPort::send_to_master`] go to the master through the slave's mailbox. Both ways are
//! bounded queues; what does not fit is dropped and counted, so a stalled side never makes
//! the other grow. A host side that can hold its frames itself (a TAP's reader: the kernel
//! queues them) waits for room instead, with [`HostPort::send_to_master_waiting`], as a
//! network card whose transmit ring is full stops its queue rather than drop.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use super::ip_config::IpConfig;

/// Frames (and settings) waiting in each direction before more are dropped: enough for a
/// TCP window's burst between two mailbox reads, small enough to keep the queue's delay
/// short.
pub const QUEUE_CAPACITY: usize = 64;

/// What the master sent the device behind the slave.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HostEvent {
    /// An Ethernet frame (destination MAC first, no FCS).
    Frame(Vec<u8>),
    /// The slave accepted Set IP parameter; these are its settings now.
    IpConfig(IpConfig),
}

/// Frames dropped because a queue was full.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PortDrops {
    /// Master → host: the host side did not take events fast enough.
    pub to_host: u64,
    /// Host → master: the mailbox did not take frames fast enough.
    pub to_master: u64,
}

/// The shared port; clones are handles to the same one.
#[derive(Debug, Clone, Default)]
pub struct HostPort(Arc<Shared>);

#[derive(Debug, Default)]
struct Shared {
    attached: AtomicBool,
    to_host: Queue<HostEvent>,
    to_master: Queue<Vec<u8>>,
}

impl HostPort {
    /// Hands the slave's Ethernet side to the host: the slave's own IP host stops seeing
    /// frames, and the queues start to fill.
    pub fn attach(&self) {
        self.0.attached.store(true, Ordering::Release);
    }

    /// Whether [`HostPort::attach`] was called.
    pub fn is_attached(&self) -> bool {
        self.0.attached.load(Ordering::Acquire)
    }

    /// Queues a frame for the master (the host side's reader); `false` if it was dropped
    /// because the queue is full.
    pub fn send_to_master(&self, frame: Vec<u8>) -> bool {
        self.0.to_master.push(frame)
    }

    /// Queues a frame for the master, waiting up to `timeout` while the queue is full; the
    /// frame comes back if it is still full then (nothing is dropped or counted). The
    /// device's stack then meets backpressure, as from a network card with a full transmit
    /// ring, where dropping would cost it a retransmission for every frame lost.
    pub fn send_to_master_waiting(&self, frame: Vec<u8>, timeout: Duration) -> Result<(), Vec<u8>> {
        self.0.to_master.push_waiting(frame, timeout)
    }

    /// Waits up to `timeout` for what the master sent.
    pub fn next_event(&self, timeout: Duration) -> Option<HostEvent> {
        self.0.to_host.pop_wait(timeout)
    }

    /// The drop counters.
    pub fn drops(&self) -> PortDrops {
        PortDrops {
            to_host: self.0.to_host.dropped.load(Ordering::Relaxed),
            to_master: self.0.to_master.dropped.load(Ordering::Relaxed),
        }
    }

    /// The EoE service's side: a frame from the master (dropped and counted when full).
    pub(super) fn deliver(&self, event: HostEvent) {
        self.0.to_host.push(event);
    }

    /// The EoE service's side: the oldest frame for the master.
    pub(super) fn take_for_master(&self) -> Option<Vec<u8>> {
        self.0.to_master.pop()
    }
}

/// A bounded FIFO one thread waits on.
#[derive(Debug)]
struct Queue<T> {
    items: Mutex<VecDeque<T>>,
    ready: Condvar,
    /// Signalled when a full queue has room again and a pusher waits for it.
    room: Condvar,
    /// Pushers waiting for room (changed under the lock).
    waiting: AtomicUsize,
    dropped: AtomicU64,
}

impl<T> Default for Queue<T> {
    fn default() -> Self {
        Queue {
            items: Mutex::new(VecDeque::with_capacity(QUEUE_CAPACITY)),
            ready: Condvar::new(),
            room: Condvar::new(),
            waiting: AtomicUsize::new(0),
            dropped: AtomicU64::new(0),
        }
    }
}

impl<T> Queue<T> {
    fn lock(&self) -> MutexGuard<'_, VecDeque<T>> {
        self.items.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn push(&self, item: T) -> bool {
        let mut items = self.lock();
        if items.len() >= QUEUE_CAPACITY {
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return false;
        }
        items.push_back(item);
        drop(items);
        self.ready.notify_one();
        true
    }

    /// Waits for room up to `timeout`; the item comes back if there is none.
    fn push_waiting(&self, item: T, timeout: Duration) -> Result<(), T> {
        let mut items = self.lock();
        if items.len() >= QUEUE_CAPACITY {
            self.waiting.fetch_add(1, Ordering::Relaxed);
            items = self
                .room
                .wait_timeout_while(items, timeout, |items| items.len() >= QUEUE_CAPACITY)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
            self.waiting.fetch_sub(1, Ordering::Relaxed);
        }
        if items.len() >= QUEUE_CAPACITY {
            return Err(item);
        }
        items.push_back(item);
        drop(items);
        self.ready.notify_one();
        Ok(())
    }

    fn pop(&self) -> Option<T> {
        let mut items = self.lock();
        let item = items.pop_front();
        let waiting = self.waiting.load(Ordering::Relaxed) > 0;
        drop(items);
        // The frame loop pops: no system call unless a pusher waits.
        if waiting {
            self.room.notify_one();
        }
        item
    }

    fn pop_wait(&self, timeout: Duration) -> Option<T> {
        let items = self.lock();
        let (mut items, _) = self
            .ready
            .wait_timeout_while(items, timeout, |items| items.is_empty())
            .unwrap_or_else(PoisonError::into_inner);
        items.pop_front()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn queues_are_bounded_and_count_what_they_drop() {
        let port = HostPort::default();
        for i in 0..QUEUE_CAPACITY + 3 {
            let accepted = port.send_to_master(vec![i as u8]);
            assert_eq!(accepted, i < QUEUE_CAPACITY);
            port.deliver(HostEvent::Frame(vec![i as u8]));
        }
        assert_eq!(
            port.drops(),
            PortDrops {
                to_host: 3,
                to_master: 3
            }
        );
        assert_eq!(port.take_for_master(), Some(vec![0]));
        assert_eq!(
            port.next_event(Duration::ZERO),
            Some(HostEvent::Frame(vec![0]))
        );
    }

    #[test]
    fn a_waiting_sender_gets_in_once_a_frame_is_taken_and_nothing_is_dropped() {
        let port = HostPort::default();
        for i in 0..QUEUE_CAPACITY {
            assert!(port.send_to_master(vec![i as u8]));
        }
        assert_eq!(
            port.send_to_master_waiting(vec![0xee], Duration::from_millis(1)),
            Err(vec![0xee]),
            "still full: the frame comes back"
        );
        let sender = port.clone();
        let (done, result) = std::sync::mpsc::channel();
        let thread = std::thread::spawn(move || {
            let _ = done.send(sender.send_to_master_waiting(vec![0xff], Duration::from_secs(120)));
        });
        // Bounded: the sender waits within a few scheduler ticks.
        for _ in 0..1_000_000 {
            if port.0.to_master.waiting.load(Ordering::Relaxed) == 1 {
                break;
            }
            std::thread::yield_now();
        }
        assert_eq!(
            port.0.to_master.waiting.load(Ordering::Relaxed),
            1,
            "the sender waits"
        );
        assert_eq!(port.take_for_master(), Some(vec![0]));
        // Woken by the take, long before its own timeout would let it look again.
        assert_eq!(result.recv_timeout(Duration::from_secs(60)), Ok(Ok(())));
        thread.join().unwrap();
        let mut taken = Vec::new();
        while let Some(frame) = port.take_for_master() {
            taken.push(frame);
        }
        assert_eq!(
            taken.len(),
            QUEUE_CAPACITY,
            "63 left and the one that waited"
        );
        assert_eq!(taken.last(), Some(&vec![0xff]), "and it went in last");
        assert_eq!(port.drops(), PortDrops::default(), "nothing dropped");
    }

    #[test]
    fn a_waiting_reader_gets_the_event_another_thread_delivers() {
        let port = HostPort::default();
        let sender = port.clone();
        let thread = std::thread::spawn(move || sender.deliver(HostEvent::Frame(vec![7])));
        let event = port.next_event(Duration::from_secs(30));
        thread.join().unwrap();
        assert_eq!(event, Some(HostEvent::Frame(vec![7])));
        assert!(port.next_event(Duration::from_millis(1)).is_none());
    }
}
