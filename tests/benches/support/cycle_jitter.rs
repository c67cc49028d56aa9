//! ecatd's cycle jitter as its `/metrics` reports it: snapshots of the
//! `ecat_process_data_cycle_jitter_seconds` histogram, of
//! `ecat_process_data_cycles_missed_total` and of `ecat_process_data_cycles_lost_total`
//! (a cycle whose frame was not back within the period: the slaves', or here the
//! simulator's, lateness, not the master's), and the quantiles of a window between two
//! snapshots, printed as the benches' jitter table. The figures are the histogram's bucket
//! bounds (5, 10, 25, 50, 100, 250 µs...): a window's p99 is the bound of the bucket it
//! falls in, not an interpolation.

use std::time::Instant;

/// The percentiles of the cycle's jitter the table shows.
pub const JITTER_QUANTILES: [f64; 4] = [0.5, 0.9, 0.99, 0.999];

/// What ecatd's `/metrics` says of its cycle: the cumulative buckets of the jitter
/// histogram (upper bound s, count) and the periods missed (no cycle ran in them).
pub struct CycleMetrics {
    /// Cumulative buckets: upper bound in s (the last `+Inf`), cycles at or below it.
    pub buckets: Vec<(f64, u64)>,
    /// Cycle periods in which no cycle ran.
    pub missed: u64,
    /// Cycles whose frame did not come back in time.
    pub lost: u64,
    /// When the page was read.
    pub at: Instant,
}

/// ecatd's `/metrics` page.
pub fn metrics_text(agent: &ureq::Agent, http: &str) -> String {
    agent
        .get(format!("{http}/metrics"))
        .call()
        .expect("/metrics")
        .body_mut()
        .read_to_string()
        .expect("metrics text")
}

/// A snapshot of ecatd's cycle figures, read from its `/metrics`.
pub fn cycle_metrics(agent: &ureq::Agent, http: &str) -> CycleMetrics {
    let text = metrics_text(agent, http);
    let value = |rest: &str| rest.rsplit(' ').next()?.parse::<f64>().ok();
    let buckets = text
        .lines()
        .filter_map(|l| l.strip_prefix("ecat_process_data_cycle_jitter_seconds_bucket{le=\""))
        .filter_map(|l| {
            let (le, rest) = l.split_once('"')?;
            let le = if le == "+Inf" {
                f64::INFINITY
            } else {
                le.parse().ok()?
            };
            Some((le, value(rest)? as u64))
        })
        .collect();
    let counter = |name: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(value)
            .unwrap_or(0.0) as u64
    };
    CycleMetrics {
        buckets,
        missed: counter("ecat_process_data_cycles_missed_total"),
        lost: counter("ecat_process_data_cycles_lost_total"),
        at: Instant::now(),
    }
}

/// Cycles counted between two bucket snapshots and the bucket bound (µs) below which each
/// of `quantiles` falls.
pub fn jitter_between(
    before: &[(f64, u64)],
    after: &[(f64, u64)],
    quantiles: &[f64],
) -> (u64, Vec<f64>) {
    let diff: Vec<(f64, u64)> = after
        .iter()
        .zip(before)
        .map(|(&(le, a), &(_, b))| (le, a.saturating_sub(b)))
        .collect();
    let total = diff.last().map_or(0, |d| d.1);
    let bounds = quantiles
        .iter()
        .map(|q| {
            let want = (q * total as f64).ceil() as u64;
            diff.iter()
                .find(|d| d.1 >= want.max(1))
                .map_or(f64::NAN, |d| d.0 * 1e6)
        })
        .collect();
    (total, bounds)
}

/// The jitter table's header (its rows: [`print_window`]).
pub fn print_header() {
    println!(
        "{:<28} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}",
        "", "window s", "cycles", "missed", "lost", "p50 ≤", "p90 ≤", "p99 ≤", "p99.9 ≤"
    );
}

/// Prints the window from `before` to `after` as a row of the jitter table named `name`;
/// returns its bucket bounds (µs) at [`JITTER_QUANTILES`].
pub fn print_window(name: &str, before: &CycleMetrics, after: &CycleMetrics) -> Vec<f64> {
    let (cycles, q) = jitter_between(&before.buckets, &after.buckets, &JITTER_QUANTILES);
    let window = after.at.duration_since(before.at).as_secs_f64();
    let missed = after.missed.saturating_sub(before.missed);
    let lost = after.lost.saturating_sub(before.lost);
    println!(
        "{name:<28} {window:>8.1} {cycles:>8} {missed:>8} {lost:>8} {:>8} {:>8} {:>8} {:>8}",
        q[0], q[1], q[2], q[3]
    );
    q
}
