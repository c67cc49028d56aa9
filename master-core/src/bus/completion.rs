//! A one-shot result slot between the bus thread and one caller, for async and blocking
//! callers alike.
//!
//! The caller holds a [`Pending`]; the bus holds the matching [`Completer`]. The bus
//! completes it exactly once. An async caller `.await`s the `Pending` (the waker is stored
//! and woken, never blocking the runtime's thread); a blocking caller calls
//! [`Pending::wait`] and sleeps on a condition variable. The lock is only ever held for a
//! few instructions, never across an `.await` or a wake-up.
//!
//! A `Completer` dropped without completing (the bus thread stopped, or unwound from a bug)
//! completes with [`BusError::Shutdown`], so no caller waits forever.

use std::fmt;
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::task::{Context, Poll, Waker};
use std::time::{Duration, Instant};

use super::error::BusError;
use super::request::DatagramResponse;

/// The outcome of one datagram.
pub type DatagramResult = Result<DatagramResponse, BusError>;

/// The result of a submitted datagram, to `.await` or to [`wait`](Pending::wait) for.
///
/// Dropping it does not take the datagram back: a datagram already queued is still sent.
#[must_use = "a datagram's result tells whether it was carried out"]
pub struct Pending {
    slot: Arc<Slot>,
}

/// The bus's end of a [`Pending`].
pub(crate) struct Completer {
    slot: Option<Arc<Slot>>,
}

struct Slot {
    state: Mutex<State>,
    done: Condvar,
    /// A blocking caller sleeps on `done` (set under the lock before it sleeps). Almost
    /// every caller awaits instead, and a condition variable's notify is a system call
    /// whether anyone sleeps or not: the bus thread makes it only when someone does.
    blocked: AtomicBool,
}

enum State {
    /// Not completed; the waker of the last poll, if any.
    Waiting(Option<Waker>),
    /// Completed, result not taken yet.
    Done(DatagramResult),
    /// The result was handed to the caller.
    Taken,
}

/// Makes a connected pair.
pub(crate) fn pair() -> (Pending, Completer) {
    let slot = Arc::new(Slot {
        state: Mutex::new(State::Waiting(None)),
        done: Condvar::new(),
        blocked: AtomicBool::new(false),
    });
    (
        Pending {
            slot: Arc::clone(&slot),
        },
        Completer { slot: Some(slot) },
    )
}

impl Slot {
    fn lock(&self) -> MutexGuard<'_, State> {
        // Every update is a single assignment, so a poisoned lock still holds a valid state.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl Pending {
    /// A `Pending` that already holds `result` (a request refused before it was queued).
    pub(crate) fn ready(result: DatagramResult) -> Pending {
        let (pending, completer) = pair();
        completer.complete(result);
        pending
    }

    /// Blocks the calling thread until the result is there.
    ///
    /// Never call this from an async task: `.await` the `Pending` instead.
    pub fn wait(self) -> DatagramResult {
        let mut state = self.slot.lock();
        loop {
            if let Some(result) = take(&mut state) {
                return result;
            }
            self.slot.blocked.store(true, Ordering::Relaxed);
            state = self
                .slot
                .done
                .wait(state)
                .unwrap_or_else(PoisonError::into_inner);
        }
    }

    /// Blocks the calling thread until the result is there or `timeout` has passed; `None`
    /// on timeout (the `Pending` can be waited for again).
    pub fn wait_timeout(&mut self, timeout: Duration) -> Option<DatagramResult> {
        let deadline = Instant::now() + timeout;
        let mut state = self.slot.lock();
        loop {
            if let Some(result) = take(&mut state) {
                return Some(result);
            }
            let now = Instant::now();
            if now >= deadline {
                return None;
            }
            self.slot.blocked.store(true, Ordering::Relaxed);
            state = self
                .slot
                .done
                .wait_timeout(state, deadline - now)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
    }

    /// Whether the result is there (so that `wait` would not block).
    pub fn is_ready(&self) -> bool {
        matches!(*self.slot.lock(), State::Done(_))
    }
}

/// Takes a completed result out of the state.
fn take(state: &mut State) -> Option<DatagramResult> {
    match std::mem::replace(state, State::Taken) {
        State::Done(result) => Some(result),
        other => {
            *state = other;
            None
        }
    }
}

impl Future for Pending {
    type Output = DatagramResult;

    fn poll(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<DatagramResult> {
        let mut state = self.slot.lock();
        if let Some(result) = take(&mut state) {
            return Poll::Ready(result);
        }
        match &mut *state {
            State::Waiting(Some(waker)) if waker.will_wake(cx.waker()) => {}
            State::Waiting(waker) => *waker = Some(cx.waker().clone()),
            // Polled again after it returned Ready: a caller bug. Say so instead of hanging.
            State::Done(_) | State::Taken => {
                return Poll::Ready(Err(BusError::InvalidRequest(
                    "result already taken (polled after completion)",
                )));
            }
        }
        Poll::Pending
    }
}

impl fmt::Debug for Pending {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Pending")
            .field("ready", &self.is_ready())
            .finish()
    }
}

impl Completer {
    /// Hands `result` to the caller and wakes it.
    pub(crate) fn complete(mut self, result: DatagramResult) {
        if let Some(slot) = self.slot.take() {
            fulfil(&slot, result);
        }
    }
}

fn fulfil(slot: &Slot, result: DatagramResult) {
    let (waker, blocked) = {
        let mut state = slot.lock();
        // Read under the lock: a caller that is to sleep set it before releasing the lock.
        let blocked = slot.blocked.load(Ordering::Relaxed);
        match std::mem::replace(&mut *state, State::Done(result)) {
            State::Waiting(waker) => (waker, blocked),
            // A slot is completed once; keep what came first.
            earlier => {
                *state = earlier;
                (None, false)
            }
        }
    };
    // Wake outside the lock: a waker may run executor code, a waiting thread re-locks.
    if blocked {
        slot.done.notify_all();
    }
    if let Some(waker) = waker {
        waker.wake();
    }
}

impl Drop for Completer {
    fn drop(&mut self) {
        if let Some(slot) = self.slot.take() {
            fulfil(&slot, Err(BusError::Shutdown));
        }
    }
}

impl fmt::Debug for Completer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Completer")
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::task::Wake;

    use super::*;
    use crate::bus::data::DatagramData;
    use crate::wire::command::DatagramAddress;

    /// One moment for every response, so that two made alike compare equal.
    static SENT: std::sync::LazyLock<std::time::Instant> =
        std::sync::LazyLock::new(std::time::Instant::now);

    fn response(byte: u8) -> DatagramResponse {
        DatagramResponse {
            data: DatagramData::from([byte]),
            wkc: 1,
            address: DatagramAddress::broadcast(0),
            irq: 0,
            sent_at: crate::bus::Stamp::from_instant(*SENT),
            polled_us: 0,
        }
    }

    struct CountingWaker(AtomicUsize);

    impl Wake for CountingWaker {
        fn wake(self: Arc<Self>) {
            self.0.fetch_add(1, Ordering::SeqCst);
        }
    }

    #[test]
    fn a_blocking_caller_gets_the_result_from_another_thread() {
        let (pending, completer) = pair();
        let thread = std::thread::spawn(move || completer.complete(Ok(response(7))));
        assert_eq!(pending.wait(), Ok(response(7)));
        thread.join().unwrap();
    }

    #[test]
    fn a_polled_caller_is_woken_once_and_then_ready() {
        let (mut pending, completer) = pair();
        let counter = Arc::new(CountingWaker(AtomicUsize::new(0)));
        let waker = Waker::from(Arc::clone(&counter));
        let mut cx = Context::from_waker(&waker);
        assert!(Pin::new(&mut pending).poll(&mut cx).is_pending());
        assert!(Pin::new(&mut pending).poll(&mut cx).is_pending());
        completer.complete(Ok(response(1)));
        assert_eq!(counter.0.load(Ordering::SeqCst), 1);
        assert!(pending.is_ready());
        assert_eq!(
            Pin::new(&mut pending).poll(&mut cx),
            Poll::Ready(Ok(response(1)))
        );
    }

    #[test]
    fn a_dropped_completer_reports_shutdown() {
        let (pending, completer) = pair();
        drop(completer);
        assert_eq!(pending.wait(), Err(BusError::Shutdown));
    }

    #[test]
    fn wait_timeout_gives_up_and_can_be_repeated() {
        let (mut pending, completer) = pair();
        assert_eq!(pending.wait_timeout(Duration::from_millis(1)), None);
        completer.complete(Err(BusError::QueueFull));
        assert_eq!(
            pending.wait_timeout(Duration::from_secs(5)),
            Some(Err(BusError::QueueFull))
        );
        assert!(Pending::ready(Ok(response(3))).is_ready());
    }
}
