//! A lock-free histogram of durations with fixed log-linear buckets.
//!
//! Each power of two of nanoseconds is split into four buckets, so any recorded value is
//! known to within 25 % (an estimate at the bucket's middle is within ±12.5 %), from 1 ns to
//! about 18 minutes, in 156 counters. Recording is two relaxed atomic adds (the bucket and
//! the exact sum, so that Prometheus' `_sum` and averages are not estimates); a snapshot
//! copies the counters and can be taken at any time from any thread.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// Sub-buckets per power of two, as a power of two.
const SUB_BITS: u32 = 2;
const SUB: u64 = 1 << SUB_BITS;
/// Number of buckets: values below `SUB` have one each, then `SUB` per power of two up to
/// 2^40 ns (about 18 minutes); longer values go to the last bucket.
pub const BUCKETS: usize = (SUB + (40 - SUB_BITS as u64) * SUB) as usize;

/// Recorded durations (the live, shared counters).
#[derive(Debug)]
pub struct Histogram {
    counts: [AtomicU64; BUCKETS],
    /// Sum of every value recorded, in nanoseconds (wraps after about 584 years).
    sum_nanos: AtomicU64,
}

/// A copy of a histogram's counters at one moment.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HistogramSnapshot {
    counts: [u64; BUCKETS],
    sum_nanos: u64,
}

/// The bucket of a value in nanoseconds.
fn bucket_of(nanos: u64) -> usize {
    if nanos < SUB {
        return nanos as usize;
    }
    let power = u64::from(63 - nanos.leading_zeros());
    let sub = (nanos >> (power - u64::from(SUB_BITS))) & (SUB - 1);
    let index = SUB + (power - u64::from(SUB_BITS)) * SUB + sub;
    (index as usize).min(BUCKETS - 1)
}

/// The range of values in nanoseconds that fall into `bucket`: `[low, high)`.
fn bucket_range(bucket: usize) -> (u64, u64) {
    let bucket = bucket as u64;
    if bucket < SUB {
        return (bucket, bucket + 1);
    }
    let power = (bucket - SUB) / SUB + u64::from(SUB_BITS);
    let sub = (bucket - SUB) % SUB;
    let step = 1u64 << (power - u64::from(SUB_BITS));
    let low = (SUB + sub) * step;
    (low, low + step)
}

impl Histogram {
    /// An empty histogram.
    pub fn new() -> Histogram {
        Histogram {
            counts: std::array::from_fn(|_| AtomicU64::new(0)),
            sum_nanos: AtomicU64::new(0),
        }
    }

    /// Counts one duration.
    pub fn record(&self, value: Duration) {
        let nanos = u64::try_from(value.as_nanos()).unwrap_or(u64::MAX);
        self.counts[bucket_of(nanos)].fetch_add(1, Ordering::Relaxed);
        self.sum_nanos.fetch_add(nanos, Ordering::Relaxed);
    }

    /// Sets every counter back to zero (not atomic as a whole: a value recorded meanwhile
    /// may survive).
    pub(crate) fn reset(&self) {
        for count in &self.counts {
            count.store(0, Ordering::Relaxed);
        }
        self.sum_nanos.store(0, Ordering::Relaxed);
    }

    /// Copies the counters.
    pub fn snapshot(&self) -> HistogramSnapshot {
        HistogramSnapshot {
            counts: std::array::from_fn(|i| self.counts[i].load(Ordering::Relaxed)),
            sum_nanos: self.sum_nanos.load(Ordering::Relaxed),
        }
    }
}

impl Default for Histogram {
    fn default() -> Histogram {
        Histogram::new()
    }
}

impl HistogramSnapshot {
    /// What was recorded after `earlier` (a snapshot of the same histogram): the window
    /// between the two.
    pub fn since(&self, earlier: &HistogramSnapshot) -> HistogramSnapshot {
        HistogramSnapshot {
            counts: std::array::from_fn(|i| self.counts[i].saturating_sub(earlier.counts[i])),
            sum_nanos: self.sum_nanos.saturating_sub(earlier.sum_nanos),
        }
    }

    /// How many durations were recorded.
    pub fn count(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// The exact sum of the durations recorded (not an estimate from the buckets).
    pub fn sum(&self) -> Duration {
        Duration::from_nanos(self.sum_nanos)
    }

    /// An estimate of the `q` quantile (`0.5` for the median, `0.99` for p99): the middle of
    /// the bucket holding it, within ±12.5 %. `None` if nothing was recorded.
    pub fn quantile(&self, q: f64) -> Option<Duration> {
        let total = self.count();
        if total == 0 {
            return None;
        }
        // The rank of the wanted value, 1-based: at least the first, at most the last.
        let rank = ((q.clamp(0.0, 1.0) * total as f64).ceil() as u64).clamp(1, total);
        let mut seen = 0;
        for (bucket, &count) in self.counts.iter().enumerate() {
            seen += count;
            if seen >= rank {
                let (low, high) = bucket_range(bucket);
                return Some(Duration::from_nanos(low + (high - low) / 2));
            }
        }
        None
    }

    /// Estimated median.
    pub fn p50(&self) -> Option<Duration> {
        self.quantile(0.5)
    }

    /// Estimated 99th percentile.
    pub fn p99(&self) -> Option<Duration> {
        self.quantile(0.99)
    }

    /// The non-empty buckets as `(low, high, count)`: values in `[low, high)`.
    pub fn buckets(&self) -> impl Iterator<Item = (Duration, Duration, u64)> + '_ {
        self.counts
            .iter()
            .enumerate()
            .filter(|(_, count)| **count > 0)
            .map(|(bucket, &count)| {
                let (low, high) = bucket_range(bucket);
                (Duration::from_nanos(low), Duration::from_nanos(high), count)
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_value_falls_into_its_bucket_range() {
        for nanos in (0..5000).chain([1 << 20, 123_456_789, 1 << 39, (1 << 40) - 1]) {
            let bucket = bucket_of(nanos);
            let (low, high) = bucket_range(bucket);
            assert!(low <= nanos && nanos < high, "{nanos} in [{low}, {high})");
        }
        assert_eq!(bucket_of(u64::MAX), BUCKETS - 1);
        // Consecutive buckets tile the line without gaps.
        for bucket in 1..BUCKETS {
            assert_eq!(bucket_range(bucket - 1).1, bucket_range(bucket).0);
        }
    }

    #[test]
    fn quantiles_are_within_an_eighth() {
        let histogram = Histogram::new();
        assert_eq!(histogram.snapshot().p50(), None);
        for micros in 1..=100u64 {
            histogram.record(Duration::from_micros(micros));
        }
        let snapshot = histogram.snapshot();
        assert_eq!(snapshot.count(), 100);
        let near = |got: Duration, want: f64| {
            let got = got.as_secs_f64() * 1e6;
            assert!((got - want).abs() <= want * 0.125 + 0.01, "{got} vs {want}");
        };
        near(snapshot.p50().unwrap(), 50.0);
        near(snapshot.p99().unwrap(), 99.0);
        near(snapshot.quantile(0.0).unwrap(), 1.0);
        assert_eq!(snapshot.buckets().map(|(_, _, n)| n).sum::<u64>(), 100);
        // 1 + 2 + ... + 100 µs, exactly.
        assert_eq!(snapshot.sum(), Duration::from_micros(5050));
    }

    #[test]
    fn a_window_holds_what_came_after_its_start() {
        let histogram = Histogram::new();
        histogram.record(Duration::from_micros(10));
        let start = histogram.snapshot();
        histogram.record(Duration::from_millis(3));
        histogram.record(Duration::from_millis(3));
        let window = histogram.snapshot().since(&start);
        assert_eq!(window.count(), 2);
        assert_eq!(window.sum(), Duration::from_millis(6));
        assert!(window.quantile(0.0).unwrap() >= Duration::from_micros(2600));
    }
}
