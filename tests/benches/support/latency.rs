//! One latency row of the request benchmarks: p50 and p99 of the timed requests and the
//! requests per second over the whole run, printed as a table line.

use std::time::{Duration, Instant};

/// p50 and p99 in µs, and requests per second.
#[derive(Clone, Copy)]
pub struct Row {
    pub p50: f64,
    pub p99: f64,
    pub per_second: f64,
}

/// The row of `samples` (one duration per request) taken over `elapsed`.
pub fn row(mut samples: Vec<Duration>, elapsed: Duration) -> Row {
    samples.sort();
    let at = |q: f64| samples[((samples.len() - 1) as f64 * q) as usize].as_secs_f64() * 1e6;
    Row {
        p50: at(0.50),
        p99: at(0.99),
        per_second: samples.len() as f64 / elapsed.as_secs_f64(),
    }
}

/// Prints `name` in a column of `width` and the row's numbers.
pub fn print(name: &str, width: usize, r: &Row) {
    println!(
        "{name:<width$} {:>10.1} {:>10.1} {:>12.0}",
        r.p50, r.p99, r.per_second
    );
}

/// Runs `op` `count` times after a warm-up of a tenth, timing each.
pub fn sequential(count: usize, op: impl FnMut()) -> Row {
    sequential_probed(count, || (), op).0
}

/// [`sequential`], with `probe` taken after the warm-up and after the last timed call
/// (outside the timing): a counter read by `probe` differs between the two by what the
/// `count` timed calls did, and nothing of the warm-up's.
pub fn sequential_probed<P>(
    count: usize,
    mut probe: impl FnMut() -> P,
    mut op: impl FnMut(),
) -> (Row, P, P) {
    for _ in 0..count / 10 {
        op();
    }
    let before = probe();
    let mut samples = Vec::with_capacity(count);
    let start = Instant::now();
    for _ in 0..count {
        let t = Instant::now();
        op();
        samples.push(t.elapsed());
    }
    let elapsed = start.elapsed();
    (row(samples, elapsed), before, probe())
}
