//! Counters of everything the bus does, lock-free, readable at any time.
//!
//! The bus thread is the only writer (one relaxed atomic add per event), but for
//! `wakeups`, which the submitting threads count; any thread may take a
//! [`BusStatsSnapshot`]. Counters taken one after the other are not one consistent cut, but
//! each is exact and never goes down.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use super::histogram::{Histogram, HistogramSnapshot};

/// The live counters, shared between the bus thread and its handles.
#[derive(Debug, Default)]
pub(crate) struct BusStats {
    pub frames_sent: Counter,
    pub frames_received: Counter,
    pub frames_lost: Counter,
    pub retries: Counter,
    pub frames_foreign: Counter,
    pub frames_stale: Counter,
    pub link_errors: Counter,
    pub datagrams_sent: Counter,
    pub datagrams_completed: Counter,
    pub datagrams_failed: Counter,
    pub datagrams_polled_again: Counter,
    pub datagrams_chained: Counter,
    pub wkc_mismatches: Counter,
    pub cycles_run: Counter,
    pub cycles_late: Counter,
    pub cycles_lost: Counter,
    pub round_trip: Histogram,
    pub cycle_start_delay: Histogram,
    /// Acyclic frames held back because a cycle was due before they could be back.
    pub acyclic_held: Counter,
    /// Submissions that woke the sleeping bus thread.
    pub wakeups: Counter,
    /// The bus thread runs under `SCHED_FIFO`.
    pub realtime: AtomicBool,
    /// The bus thread's time slice as the kernel reports it, in ns.
    pub time_slice_ns: AtomicU64,
}

/// One monotonic event counter.
#[derive(Debug, Default)]
pub(crate) struct Counter(AtomicU64);

impl Counter {
    pub fn add(&self, n: u64) {
        self.0.fetch_add(n, Ordering::Relaxed);
    }

    pub fn inc(&self) {
        self.add(1);
    }

    pub fn get(&self) -> u64 {
        self.0.load(Ordering::Relaxed)
    }
}

/// What the bus has done since it started.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BusStatsSnapshot {
    /// Frames handed to the link (cyclic and acyclic, first tries and retries).
    pub frames_sent: u64,
    /// Returned frames matched to a frame in flight.
    pub frames_received: u64,
    /// Frames that did not come back before their deadline.
    pub frames_lost: u64,
    /// Lost acyclic frames that were sent again.
    pub retries: u64,
    /// Received frames that are not EtherCAT datagram frames or do not parse; ignored.
    pub frames_foreign: u64,
    /// Received datagram frames that match no frame in flight (late replies to frames
    /// already retried or given up, duplicates, other masters' frames); ignored.
    pub frames_stale: u64,
    /// Errors the link returned from `send` or `recv`.
    pub link_errors: u64,
    /// Datagrams put on the wire by acyclic frames (each try counts).
    pub datagrams_sent: u64,
    /// Datagrams that completed with a reply (also those whose working counter was wrong).
    pub datagrams_completed: u64,
    /// Datagrams that failed without a reply: timeout or shutdown.
    pub datagrams_failed: u64,
    /// Polls that came back empty (working counter 0) and were sent again by the bus
    /// thread itself ([`BusHandle::submit_once_polling`](super::BusHandle::submit_once_polling));
    /// each try also counts in `datagrams_sent`.
    pub datagrams_polled_again: u64,
    /// Steps of chains the bus thread staged itself after the step before counted
    /// ([`BusHandle::submit_chain`](super::BusHandle::submit_chain)).
    pub datagrams_chained: u64,
    /// Replies whose working counter was not the one the caller expected.
    pub wkc_mismatches: u64,
    /// Cycles of the cyclic task that were started.
    pub cycles_run: u64,
    /// Cycles started a whole period or more after they were due (the missed periods are
    /// skipped, not caught up in a burst).
    pub cycles_late: u64,
    /// Cyclic frames that did not come back in time.
    pub cycles_lost: u64,
    /// Round-trip times of returned frames, from send to receive on the bus thread.
    pub round_trip: HistogramSnapshot,
    /// How long after its due time each cycle started.
    pub cycle_start_delay: HistogramSnapshot,
    /// Times the bus held acyclic frames back because the next cycle was due sooner than
    /// one of them takes (its recent round trip): they went after the cyclic frame.
    pub acyclic_held: u64,
    /// Submissions that found the bus thread asleep and woke it: a system call on the
    /// submitting thread and a wake-up on the bus thread's CPU each (why a mailbox write
    /// and its first read go in one submission:
    /// [`BusHandle::submit_then_poll`](super::BusHandle::submit_then_poll)).
    pub wakeups: u64,
    /// Whether the bus thread got the real-time scheduling it was configured to ask for
    /// ([`ThreadPriority::Realtime`](super::ThreadPriority::Realtime)).
    pub realtime: bool,
    /// The bus thread's time slice under the fair scheduler, in ns, as the kernel reports
    /// it (`sched_getattr(2)`): 100,000 when the thread sleeps between frames
    /// ([`WaitMode::Poll`](super::WaitMode::Poll)) and the kernel grants custom slices
    /// (Linux 6.12 and later), the kernel's default slice otherwise; 0 until the thread has
    /// started, on kernels that report none, and under `SCHED_FIFO`.
    pub time_slice_ns: u64,
}

impl BusStatsSnapshot {
    /// Estimated median round-trip time.
    pub fn rtt_p50(&self) -> Option<Duration> {
        self.round_trip.p50()
    }

    /// Estimated 99th-percentile round-trip time.
    pub fn rtt_p99(&self) -> Option<Duration> {
        self.round_trip.p99()
    }
}

impl BusStats {
    pub fn snapshot(&self) -> BusStatsSnapshot {
        BusStatsSnapshot {
            frames_sent: self.frames_sent.get(),
            frames_received: self.frames_received.get(),
            frames_lost: self.frames_lost.get(),
            retries: self.retries.get(),
            frames_foreign: self.frames_foreign.get(),
            frames_stale: self.frames_stale.get(),
            link_errors: self.link_errors.get(),
            datagrams_sent: self.datagrams_sent.get(),
            datagrams_completed: self.datagrams_completed.get(),
            datagrams_failed: self.datagrams_failed.get(),
            datagrams_polled_again: self.datagrams_polled_again.get(),
            datagrams_chained: self.datagrams_chained.get(),
            wkc_mismatches: self.wkc_mismatches.get(),
            cycles_run: self.cycles_run.get(),
            cycles_late: self.cycles_late.get(),
            cycles_lost: self.cycles_lost.get(),
            round_trip: self.round_trip.snapshot(),
            cycle_start_delay: self.cycle_start_delay.snapshot(),
            acyclic_held: self.acyclic_held.get(),
            wakeups: self.wakeups.get(),
            realtime: self.realtime.load(Ordering::Relaxed),
            time_slice_ns: self.time_slice_ns.load(Ordering::Relaxed),
        }
    }
}
