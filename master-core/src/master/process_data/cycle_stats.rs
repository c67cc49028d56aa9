//! What the cyclic exchange counts: completed, lost and wrong-WKC cycles, missed periods,
//! mailbox notices, and histograms of the cycle time, its jitter and the round trip.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use crate::bus::{Histogram, HistogramSnapshot};

/// Counters of the cyclic exchange (see [`Master::cycle_timing`](crate::master::Master::cycle_timing)
/// for the distributions).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CycleStats {
    /// Cycles whose frame came back.
    pub completed: u64,
    /// Cycles whose frame was lost.
    pub lost: u64,
    /// Working counter of the last returned process-data datagram.
    pub last_wkc: u16,
    /// Working counter the process-data datagram should have (2 per slave with outputs,
    /// 1 per slave with inputs).
    pub expected_wkc: u16,
    /// Cycles that came back with a working counter other than expected, on the process
    /// data or on the mailbox-status bits (a slave missing, not in SAFEOP/OP, or a mapping
    /// refused).
    pub wrong_wkc: u64,
    /// Cycles the bus started a whole period or more late.
    pub late: u64,
    /// Periods in which no cycle ran (skipped after a late one).
    pub missed: u64,
    /// Image size in bytes.
    pub image_len: usize,
    /// Slaves whose "mailbox full" bit is mapped into the cyclic frame.
    pub mailbox_status_slaves: u16,
    /// Times a set "mailbox full" bit was handed to the mailbox engine.
    pub mailbox_notices: u64,
}

/// Distributions of the cyclic exchange's timing.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CycleTiming {
    /// The configured period.
    pub period: Duration,
    /// Time between the starts of consecutive cycles.
    pub cycle_time: HistogramSnapshot,
    /// How far each cycle time was from the period (either way).
    pub jitter: HistogramSnapshot,
    /// How late each cycle started after it was due (from the bus).
    pub start_delay: HistogramSnapshot,
    /// From sending the cyclic frame to its return.
    pub round_trip: HistogramSnapshot,
}

/// The live counters, shared by the cyclic task (bus thread) and the master.
#[derive(Debug, Default)]
pub(crate) struct CycleCounters {
    /// The period the cyclic task runs at, ns.
    pub period_ns: AtomicU64,
    pub lost: AtomicU64,
    pub wrong_wkc: AtomicU64,
    pub missed: AtomicU64,
    pub mailbox_notices: AtomicU64,
    pub cycle_time: Histogram,
    pub jitter: Histogram,
    pub round_trip: Histogram,
}

impl CycleCounters {
    /// A cycle starts now; `previous` is when the last one started.
    pub fn started(&self, now: Instant, previous: Option<Instant>, period: Duration) {
        let Some(previous) = previous else {
            return;
        };
        let interval = now.saturating_duration_since(previous);
        self.cycle_time.record(interval);
        self.jitter.record(interval.abs_diff(period));
        let period_ns = period.as_nanos().max(1);
        // Periods that passed without a cycle: the interval rounded to whole periods, less
        // the one that ran.
        let periods = (interval.as_nanos() + period_ns / 2) / period_ns;
        if periods > 1 {
            let missed = u64::try_from(periods - 1).unwrap_or(u64::MAX);
            self.missed.fetch_add(missed, Ordering::Relaxed);
        }
    }

    pub fn count(counter: &AtomicU64) -> u64 {
        counter.load(Ordering::Relaxed)
    }

    pub fn bump(counter: &AtomicU64, by: u64) {
        counter.fetch_add(by, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intervals_feed_the_histograms_and_missed_periods() {
        let c = CycleCounters::default();
        let period = Duration::from_millis(1);
        let t0 = Instant::now();
        c.started(t0, None, period);
        c.started(t0 + Duration::from_micros(1100), Some(t0), period);
        // 3 periods between starts: two missed.
        c.started(
            t0 + Duration::from_micros(4100),
            Some(t0 + Duration::from_micros(1100)),
            period,
        );
        assert_eq!(c.cycle_time.snapshot().count(), 2);
        assert_eq!(CycleCounters::count(&c.missed), 2);
        let jitter = c.jitter.snapshot().quantile(0.0).unwrap();
        assert!(jitter >= Duration::from_micros(80) && jitter <= Duration::from_micros(120));
    }
}
