//! Sub-millisecond pauses for the owner tasks.
//!
//! Tokio's timer counts in whole milliseconds and its runtime parks for at least one, so a
//! 50 µs pause between two reads of SM1 would last 1 to 2 ms. The pauses of the poll
//! back-off ([`super::exchange`]) are what a slow slave's answer waits on, so they run on
//! a thread of their own that sleeps on a condition variable with the minimal timer slack,
//! as the bus thread does, and wakes each owner through a [`Notify`] when its pause is over.
//!
//! At most one pause per owner is asked for at a time; one that is abandoned (the owner was
//! woken by a "mailbox full" notice first) stays queued until it is due, then wakes nobody.
//! So the queue holds at most a few entries per slave.

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::io;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use tokio::sync::Notify;

/// A pause that ends at `at`.
struct Entry {
    at: Instant,
    slot: Arc<Notify>,
}

impl PartialEq for Entry {
    fn eq(&self, other: &Entry) -> bool {
        self.at == other.at
    }
}

impl Eq for Entry {}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Entry) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Entry {
    /// The earliest first out of the (max-)heap.
    fn cmp(&self, other: &Entry) -> Ordering {
        other.at.cmp(&self.at)
    }
}

#[derive(Default)]
struct State {
    queue: BinaryHeap<Entry>,
    stopped: bool,
}

struct Inner {
    state: Mutex<State>,
    wake: Condvar,
}

impl Inner {
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// The owners' handle on the pause thread; cheap to clone.
#[derive(Clone)]
pub(crate) struct Timer {
    inner: Arc<Inner>,
}

/// Stops the pause thread when dropped (with the engine).
pub(crate) struct TimerThread {
    timer: Timer,
}

impl Timer {
    /// Starts the pause thread (named `ecat-mbx-timer`).
    pub fn start() -> io::Result<(Timer, TimerThread)> {
        let timer = Timer {
            inner: Arc::new(Inner {
                state: Mutex::new(State::default()),
                wake: Condvar::new(),
            }),
        };
        let inner = Arc::clone(&timer.inner);
        std::thread::Builder::new()
            .name("ecat-mbx-timer".into())
            .spawn(move || run(&inner))?;
        Ok((timer.clone(), TimerThread { timer }))
    }

    /// Waits for `pause`, to within the scheduler's wake-up latency. Returns at once once
    /// the engine has stopped.
    pub async fn sleep(&self, pause: Duration) {
        let slot = Arc::new(Notify::new());
        let at = Instant::now() + pause;
        {
            let mut state = self.inner.lock();
            if state.stopped {
                return;
            }
            let earliest = state.queue.peek().is_none_or(|first| at < first.at);
            state.queue.push(Entry {
                at,
                slot: Arc::clone(&slot),
            });
            if earliest {
                self.inner.wake.notify_one();
            }
        }
        // `notify_one` leaves a permit if the thread fires before this waits.
        slot.notified().await;
    }
}

impl Drop for TimerThread {
    fn drop(&mut self) {
        let mut state = self.timer.inner.lock();
        state.stopped = true;
        for entry in state.queue.drain() {
            entry.slot.notify_one();
        }
        self.timer.inner.wake.notify_one();
    }
}

fn run(inner: &Inner) {
    crate::bus::set_min_timer_slack();
    let mut state = inner.lock();
    loop {
        if state.stopped {
            return;
        }
        let now = Instant::now();
        while state.queue.peek().is_some_and(|first| first.at <= now) {
            if let Some(entry) = state.queue.pop() {
                entry.slot.notify_one();
            }
        }
        state = match state.queue.peek().map(|first| first.at - now) {
            Some(wait) => {
                inner
                    .wake
                    .wait_timeout(state, wait)
                    .unwrap_or_else(PoisonError::into_inner)
                    .0
            }
            None => inner
                .wake
                .wait(state)
                .unwrap_or_else(PoisonError::into_inner),
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pauses_end_in_order_each_not_before_its_time() {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .build()
            .unwrap();
        let (timer, thread) = Timer::start().unwrap();
        runtime.block_on(async {
            let start = Instant::now();
            let long = timer.sleep(Duration::from_millis(20));
            let short = timer.sleep(Duration::from_micros(200));
            tokio::pin!(long);
            // The short pause, asked for second, ends first.
            tokio::select! {
                biased;
                () = &mut long => panic!("the 20 ms pause ended before the 200 µs one"),
                () = short => {}
            }
            assert!(start.elapsed() >= Duration::from_micros(200));
            long.await;
            assert!(start.elapsed() >= Duration::from_millis(20));
        });
        // Once the engine is gone, nobody waits on a pause that would never end.
        drop(thread);
        runtime.block_on(timer.sleep(Duration::from_secs(3600)));
    }
}
