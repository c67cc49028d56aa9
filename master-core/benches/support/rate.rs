//! The highest sustainable cycle rate, measured the same way in-process and over veth.

use std::thread;
use std::time::{Duration, Instant};

use master_core::master::Master;

/// A duration in µs (NaN when there is none).
pub fn micros(d: Option<Duration>) -> f64 {
    d.map_or(f64::NAN, |d| d.as_secs_f64() * 1e6)
}

/// Tries the periods of `periods_us` in turn (longest first), each for `try_for`, and
/// returns the shortest at which no cycle was lost, every working counter was right and at
/// least 90 % of the periods ran, with the cycles per second achieved there and the
/// round-trip median (zero period and NaN if even the first failed).
pub fn fastest_period(
    master: &Master,
    periods_us: &[u64],
    try_for: Duration,
) -> (Duration, f64, f64) {
    let mut best = (Duration::ZERO, 0.0, f64::NAN);
    for &us in periods_us {
        let period = Duration::from_micros(us);
        master.set_cycle_period(period);
        // Settle on the new period before counting (bounded: a stalled cycle ends the wait).
        let settle = master.cycle_stats().completed + 20;
        let deadline = Instant::now() + Duration::from_secs(2);
        while master.cycle_stats().completed < settle && Instant::now() < deadline {
            thread::sleep(Duration::from_millis(5));
        }
        let before = master.cycle_stats();
        let start = Instant::now();
        thread::sleep(try_for);
        let after = master.cycle_stats();
        let elapsed = start.elapsed();
        let cycles = (after.completed - before.completed) as f64;
        let due = elapsed.as_secs_f64() / period.as_secs_f64();
        let lost = after.lost - before.lost;
        let wrong = after.wrong_wkc - before.wrong_wkc;
        if lost > 0 || wrong > 0 || cycles < 0.9 * due {
            break;
        }
        let round_trip = micros(master.cycle_timing().round_trip.quantile(0.5));
        best = (period, cycles / elapsed.as_secs_f64(), round_trip);
    }
    best
}
