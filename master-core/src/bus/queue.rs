//! The bounded submission queue between callers and the bus thread, and the bus thread's
//! control requests (shutdown, a new cyclic task).
//!
//! Callers push under a mutex held for a few instructions; the bus thread moves everything
//! queued into its own staging area in one go, so callers and the bus hardly ever contend.
//! The bus thread parks on the condition variable only when it has nothing in flight;
//! callers notify it only when it is parked, which keeps a system call off the common
//! submission path.

use std::collections::VecDeque;
use std::os::fd::{AsFd, BorrowedFd};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use super::completion::Completer;
use super::cyclic::CyclicTask;
use super::error::BusError;
use super::guest::Guest;
use super::request::DatagramRequest;
use crate::link::EventFd;

/// One queued datagram.
#[derive(Debug)]
pub(crate) struct Queued {
    pub request: DatagramRequest,
    pub completer: Completer,
    /// How many datagrams of its group start here, this one included: 1 for a lone datagram,
    /// `n, n-1, ..., 1` along a group of `n` that must share a frame.
    pub group_left: u16,
    /// Sent once only: if its frame is lost it fails with `Timeout` instead of being sent
    /// again (see [`BusHandle::submit_once`](super::BusHandle::submit_once)).
    pub once: bool,
    /// Sent again at once, up to this many more times, while it comes back with working
    /// counter 0 (see [`BusHandle::submit_once_polling`](super::BusHandle::submit_once_polling)).
    pub again: u16,
    /// When a poll sent again first left (`None` until it is sent again).
    pub first_sent: Option<Instant>,
    /// The steps of its chain still to go, on the first datagram of a chain's step: staged
    /// once this one came back counted, skipped otherwise (see [`super::chain`]).
    pub then: Option<Box<super::chain::Chain>>,
}

/// A change of cyclic task asked for: `Some(task)` to run one, `None` to stop.
pub(crate) type CyclicChange = Option<Box<dyn CyclicTask>>;

/// What the bus thread is asked to do besides moving datagrams.
#[derive(Default)]
pub(crate) struct Control {
    pub shutdown: bool,
    pub cyclic: Option<CyclicChange>,
    /// A guest to install (`Some(Some(_))`) or to remove (`Some(None)`).
    pub guest: Option<Option<Box<dyn Guest>>>,
}

/// The queue and the bus thread's wake-up.
pub(crate) struct Submissions {
    state: Mutex<State>,
    wake: Condvar,
    capacity: usize,
    /// Datagrams queued, readable without the lock (the busy-polling bus checks it each turn).
    queued: AtomicUsize,
    /// Set when a [`Control`] request waits, readable without the lock.
    control_pending: AtomicBool,
    /// Written instead of the condition variable while the bus thread is parked in
    /// `ppoll(2)` beside a guest ([`Submissions::park_beside`]).
    eventfd: Option<EventFd>,
}

struct State {
    entries: VecDeque<Queued>,
    /// Set once the bus thread has stopped taking submissions.
    closed: bool,
    /// The bus thread sleeps on `wake` and must be notified.
    parked: bool,
    /// It sleeps in `ppoll(2)` beside a guest, on `eventfd`, not on `wake`.
    beside: bool,
    control: Control,
}

impl Submissions {
    /// A queue of `capacity` datagrams, its memory reserved now.
    pub fn new(capacity: usize) -> Submissions {
        Submissions {
            state: Mutex::new(State {
                entries: VecDeque::with_capacity(capacity),
                closed: false,
                parked: false,
                beside: false,
                control: Control::default(),
            }),
            wake: Condvar::new(),
            capacity,
            queued: AtomicUsize::new(0),
            control_pending: AtomicBool::new(false),
            eventfd: EventFd::new().ok(),
        }
    }

    /// Wakes the parked bus thread where it waits (`state` is the locked state).
    fn wake_parked(&self, state: &State) {
        match &self.eventfd {
            Some(eventfd) if state.beside => eventfd.signal(),
            _ => self.wake.notify_one(),
        }
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // No update can be left half done by a panic (each is a push, a take or a flag),
        // so the state behind a poisoned lock is still consistent.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// How many datagrams are waiting.
    pub fn len(&self) -> usize {
        self.queued.load(Ordering::Acquire)
    }

    /// Queues all of `batch` or none of it (a group must not be split by a full queue),
    /// and says whether it woke the parked bus thread. On refusal the batch is handed back
    /// with the reason.
    pub fn push(
        &self,
        batch: impl ExactSizeIterator<Item = Queued>,
    ) -> Result<bool, (BusError, Vec<Queued>)> {
        let mut state = self.lock();
        if state.closed {
            return Err((BusError::Shutdown, batch.collect()));
        }
        if state.entries.len() + batch.len() > self.capacity {
            return Err((BusError::QueueFull, batch.collect()));
        }
        let count = batch.len();
        state.entries.extend(batch);
        self.queued.fetch_add(count, Ordering::Release);
        if state.parked {
            self.wake_parked(&state);
        }
        Ok(state.parked)
    }

    /// Moves every queued datagram to the end of `staging` (bus thread). `staging` should
    /// be empty and hold `capacity` entries, so that this never allocates.
    pub fn take_into(&self, staging: &mut VecDeque<Queued>) {
        if self.len() == 0 {
            return;
        }
        let mut state = self.lock();
        let count = state.entries.len();
        staging.extend(state.entries.drain(..));
        self.queued.fetch_sub(count, Ordering::Release);
    }

    /// Asks the bus thread to stop; idempotent.
    pub fn request_shutdown(&self) {
        self.with_control(|control| control.shutdown = true);
    }

    /// Asks the bus thread to change its cyclic task.
    pub fn request_cyclic(&self, change: CyclicChange) {
        // A change not yet taken up is replaced (and its task dropped here, not on the bus
        // thread): only the latest wish matters.
        self.with_control(|control| control.cyclic = Some(change));
    }

    /// Asks the bus thread to install a guest, or with `None` to remove it.
    pub fn request_guest(&self, guest: Option<Box<dyn Guest>>) {
        self.with_control(|control| control.guest = Some(guest));
    }

    fn with_control(&self, change: impl FnOnce(&mut Control)) {
        let mut state = self.lock();
        change(&mut state.control);
        self.control_pending.store(true, Ordering::Release);
        if state.parked {
            self.wake_parked(&state);
        }
    }

    /// Takes the pending control requests, if any (bus thread).
    pub fn take_control(&self) -> Option<Control> {
        if !self.control_pending.load(Ordering::Acquire) {
            return None;
        }
        let mut state = self.lock();
        self.control_pending.store(false, Ordering::Release);
        let control = std::mem::take(&mut state.control);
        // Keep answering "shut down" once asked, whatever else comes later.
        state.control.shutdown = control.shutdown;
        Some(control)
    }

    /// Sleeps until a control request arrives, a submission too if `on_submission`, or
    /// `until` passes (bus thread).
    ///
    /// Not waking on submissions lets the bus sleep out a failing link's back-off while
    /// callers keep queueing.
    pub fn park(&self, until: Option<Instant>, on_submission: bool) {
        let mut state = self.lock();
        state.parked = true;
        loop {
            let submitted = on_submission && !state.entries.is_empty();
            if submitted || self.control_pending.load(Ordering::Acquire) {
                break;
            }
            match until {
                None => {
                    state = self
                        .wake
                        .wait(state)
                        .unwrap_or_else(PoisonError::into_inner);
                }
                Some(until) => {
                    let now = Instant::now();
                    if now >= until {
                        break;
                    }
                    state = self
                        .wake
                        .wait_timeout(state, until - now)
                        .unwrap_or_else(PoisonError::into_inner)
                        .0;
                }
            }
        }
        state.parked = false;
    }

    /// [`Self::park`] for a bus thread with a guest: also returns when `beside` (the
    /// guest's descriptor) is readable, and says whether it was. Without an event
    /// descriptor, parks as [`Self::park`] for at most [`PARK_SLICE`] and says "readable".
    pub fn park_beside(
        &self,
        until: Option<Instant>,
        on_submission: bool,
        beside: BorrowedFd<'_>,
    ) -> bool {
        let Some(eventfd) = &self.eventfd else {
            let slice = Instant::now() + PARK_SLICE;
            self.park(
                Some(until.map_or(slice, |until| until.min(slice))),
                on_submission,
            );
            return true;
        };
        {
            let mut state = self.lock();
            let submitted = on_submission && !state.entries.is_empty();
            if submitted || self.control_pending.load(Ordering::Acquire) {
                return false;
            }
            state.parked = true;
            state.beside = true;
        }
        // A submission from here on sees `parked` and writes the event descriptor.
        let timeout = until.map_or(PARK_FOREVER, |until| {
            until.saturating_duration_since(Instant::now())
        });
        let readable = crate::link::which_readable(&[beside, eventfd.as_fd()], timeout);
        {
            let mut state = self.lock();
            state.parked = false;
            state.beside = false;
        }
        // A failed wait counts as both readable: the caller looks, and finds what is there.
        let [guest, woken] = readable.unwrap_or([true, true]);
        if woken {
            eventfd.drain();
        }
        guest
    }

    /// Refuses all further submissions and hands back those still queued (bus thread, when
    /// it stops).
    pub fn close(&self) -> VecDeque<Queued> {
        let mut state = self.lock();
        state.closed = true;
        self.queued.store(0, Ordering::Release);
        std::mem::take(&mut state.entries)
    }
}

/// How often a bus thread that cannot wait on its guest's descriptor looks at it.
const PARK_SLICE: std::time::Duration = std::time::Duration::from_millis(1);

/// How long a park without a deadline waits in `ppoll(2)` before it looks again.
const PARK_FOREVER: std::time::Duration = std::time::Duration::from_secs(3600);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::completion::pair;

    fn queued() -> Queued {
        let (_pending, completer) = pair();
        Queued {
            request: DatagramRequest::brd(0, 2),
            completer,
            group_left: 1,
            once: false,
            again: 0,
            first_sent: None,
            then: None,
        }
    }

    #[test]
    fn a_batch_goes_in_whole_or_not_at_all() {
        let queue = Submissions::new(3);
        queue.push([queued(), queued()].into_iter()).unwrap();
        let (err, back) = queue.push([queued(), queued()].into_iter()).unwrap_err();
        assert_eq!(err, BusError::QueueFull);
        assert_eq!(back.len(), 2);
        assert_eq!(queue.len(), 2);
        let mut staging = VecDeque::with_capacity(3);
        queue.take_into(&mut staging);
        assert_eq!((staging.len(), queue.len()), (2, 0));
        queue.push([queued()].into_iter()).unwrap();
        assert_eq!(queue.close().len(), 1);
        let (err, _) = queue.push([queued()].into_iter()).unwrap_err();
        assert_eq!(err, BusError::Shutdown);
    }

    #[test]
    fn shutdown_stays_requested_and_park_returns_at_once_while_control_waits() {
        let queue = Submissions::new(1);
        assert!(queue.take_control().is_none());
        queue.request_shutdown();
        // Does not sleep: a control request is pending.
        queue.park(None, true);
        assert!(queue.take_control().unwrap().shutdown);
        queue.request_cyclic(None);
        let control = queue.take_control().unwrap();
        assert!(control.shutdown && control.cyclic.is_some());
    }
}
