//! A token bucket for log lines: a fault that repeats without limit (a broken slave, a
//! flapping cable) leaves a burst of lines, then one per refill, and the lines held back
//! are counted and reported with the next one that passes.

use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Lines in a burst, by default (one slave's mailbox failures).
const BURST: u32 = 5;
/// A token comes back this often, by default.
const REFILL: Duration = Duration::from_secs(1);

/// At most `burst` lines at once, then one per `refill`.
#[derive(Debug)]
pub(crate) struct LogLimit {
    burst: u32,
    refill: Duration,
    bucket: Mutex<Bucket>,
}

#[derive(Debug)]
struct Bucket {
    tokens: u32,
    refilled: Instant,
    suppressed: u64,
}

impl Default for LogLimit {
    fn default() -> Self {
        LogLimit::new(BURST, REFILL)
    }
}

impl LogLimit {
    /// A full bucket of `burst` (at least 1) that earns a token back every `refill`.
    pub(crate) fn new(burst: u32, refill: Duration) -> LogLimit {
        let burst = burst.max(1);
        LogLimit {
            burst,
            refill: refill.max(Duration::from_millis(1)),
            bucket: Mutex::new(Bucket {
                tokens: burst,
                refilled: Instant::now(),
                suppressed: 0,
            }),
        }
    }

    /// Whether a line may be logged now, with the number of lines held back since the last
    /// one that was; `None` counts this one as held back.
    pub(crate) fn admit(&self, now: Instant) -> Option<u64> {
        // Never held across an await: taken and released right here.
        let mut bucket = self.bucket.lock().unwrap_or_else(|p| p.into_inner());
        let elapsed = now.saturating_duration_since(bucket.refilled);
        let earned =
            (elapsed.as_micros() / self.refill.as_micros()).min(u128::from(self.burst)) as u32;
        if earned > 0 {
            bucket.tokens = (bucket.tokens + earned).min(self.burst);
            bucket.refilled = now;
        }
        if bucket.tokens == 0 {
            bucket.suppressed += 1;
            return None;
        }
        bucket.tokens -= 1;
        Some(std::mem::take(&mut bucket.suppressed))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_burst_then_one_a_refill_with_the_held_back_count() {
        let limit = LogLimit::default();
        let start = Instant::now();
        for _ in 0..BURST {
            assert_eq!(limit.admit(start), Some(0));
        }
        assert_eq!(limit.admit(start), None);
        assert_eq!(limit.admit(start + Duration::from_millis(500)), None);
        assert_eq!(limit.admit(start + REFILL), Some(2), "two were held back");
        assert_eq!(limit.admit(start + REFILL), None);
        // A long quiet time refills no more than the burst.
        let later = start + REFILL * 100;
        for _ in 0..BURST {
            assert!(limit.admit(later).is_some());
        }
        assert_eq!(limit.admit(later), None);
    }

    #[test]
    fn a_bigger_bucket_takes_a_whole_segment_at_once() {
        let limit = LogLimit::new(64, Duration::from_millis(100));
        let start = Instant::now();
        assert!((0..64).all(|_| limit.admit(start).is_some()));
        assert_eq!(limit.admit(start), None);
        assert_eq!(limit.admit(start + Duration::from_millis(100)), Some(1));
    }
}
