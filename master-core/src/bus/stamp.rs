//! A moment on the bus's clock in 8 bytes, for the replies that carry one: an `Instant` is
//! 16, and a reply travels inside every working-counter error, which must stay small.

use std::sync::LazyLock;
use std::time::{Duration, Instant};

/// Nanoseconds since the process's first bus was made (the clock is `Instant`'s; 584
/// years fit).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Stamp(u64);

/// The zero of every [`Stamp`]: set before any bus sends a frame ([`Stamp::start_clock`]),
/// so that no stamped moment lies before it.
static EPOCH: LazyLock<Instant> = LazyLock::new(Instant::now);

impl Stamp {
    /// Starts the clock, if no bus did yet.
    pub(crate) fn start_clock() {
        LazyLock::force(&EPOCH);
    }

    /// The stamp of `at` (the clock's zero for a moment before it).
    pub fn from_instant(at: Instant) -> Stamp {
        let since = at.saturating_duration_since(*EPOCH).as_nanos();
        Stamp(u64::try_from(since).unwrap_or(u64::MAX))
    }

    /// The moment stamped.
    pub fn instant(self) -> Instant {
        *EPOCH + Duration::from_nanos(self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stamp_gives_back_its_moment_to_the_nanosecond() {
        Stamp::start_clock();
        let now = Instant::now();
        assert_eq!(Stamp::from_instant(now).instant(), now);
        let later = now + Duration::from_micros(1_234);
        let (a, b) = (Stamp::from_instant(now), Stamp::from_instant(later));
        assert!(a < b);
        assert_eq!(b.instant() - a.instant(), Duration::from_micros(1_234));
    }
}
