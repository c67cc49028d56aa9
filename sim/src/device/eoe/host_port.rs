//! The Ethernet side of an EoE slave handed to something outside the simulator (ecat-sim's
//! TAP bridge), instead of the slave's own IP host.
//!
//! A [`HostPort`] is made with every EoE service and does nothing until
//! [`HostPort::attach`]: from then on every frame the master sends through EoE, and every
//! Set IP parameter the slave accepts, goes to [`HostPort::next_event`]; frames given to
//! [`HostPort::send_to_master`] go to the master through the slave's mailbox. Both ways are
//! bounded queues; what does not fit is dropped and counted, so a stalled side never makes
//! the other grow.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
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
    dropped: AtomicU64,
}

impl<T> Default for Queue<T> {
    fn default() -> Self {
        Queue {
            items: Mutex::new(VecDeque::with_capacity(QUEUE_CAPACITY)),
            ready: Condvar::new(),
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

    fn pop(&self) -> Option<T> {
        self.lock().pop_front()
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
