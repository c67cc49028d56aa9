//! Bus and cyclic-exchange metrics from the bus statistics and the master's cycle counters.

use std::time::Duration;

use prometheus::proto::{MetricFamily, MetricType};

use super::family::Family;
use crate::service::Core;

/// Upper bounds of the timing histograms, in seconds: from 5 µs (the jitter of a good
/// cycle) to 1 s.
pub(super) const BOUNDS: [f64; 14] = [
    5e-6, 10e-6, 25e-6, 50e-6, 100e-6, 250e-6, 500e-6, 1e-3, 2.5e-3, 5e-3, 10e-3, 25e-3, 100e-3,
    1.0,
];

fn counter(name: &str, help: &str, value: u64) -> Option<MetricFamily> {
    Family::new(name, help, MetricType::COUNTER)
        .counter(&[], value as f64)
        .done()
}

/// The bus families.
pub fn collect(core: &Core) -> Vec<Option<MetricFamily>> {
    let s = core.master().bus_stats();
    let cycle = core.master().cycle_stats();
    let timing = core.master().cycle_timing();
    let mut out = vec![
        counter(
            "ecat_bus_frames_sent_total",
            "Frames handed to the link, cyclic and acyclic, retries included.",
            s.frames_sent,
        ),
        counter(
            "ecat_bus_frames_received_total",
            "Returned frames matched to a frame in flight.",
            s.frames_received,
        ),
        counter(
            "ecat_bus_frames_lost_total",
            "Frames that did not come back before their deadline.",
            s.frames_lost,
        ),
        counter(
            "ecat_bus_retries_total",
            "Lost acyclic frames sent again.",
            s.retries,
        ),
        counter(
            "ecat_bus_frames_foreign_total",
            "Received frames that are not EtherCAT datagram frames.",
            s.frames_foreign,
        ),
        counter(
            "ecat_bus_frames_stale_total",
            "Received frames matching no frame in flight.",
            s.frames_stale,
        ),
        counter(
            "ecat_bus_link_errors_total",
            "Errors the link returned from send or receive.",
            s.link_errors,
        ),
        counter(
            "ecat_bus_datagrams_sent_total",
            "Acyclic datagrams put on the wire.",
            s.datagrams_sent,
        ),
        counter(
            "ecat_bus_datagrams_failed_total",
            "Datagrams that failed without a reply.",
            s.datagrams_failed,
        ),
        counter(
            "ecat_bus_wkc_errors_total",
            "Replies whose working counter was not the expected one.",
            s.wkc_mismatches,
        ),
        counter(
            "ecat_bus_cycles_total",
            "Cycles of the cyclic task started.",
            s.cycles_run,
        ),
        counter(
            "ecat_bus_cycles_late_total",
            "Cycles started a whole period or more late.",
            s.cycles_late,
        ),
        counter(
            "ecat_bus_cycles_lost_total",
            "Cyclic frames that did not come back in time.",
            s.cycles_lost,
        ),
        counter(
            "ecat_process_data_cycles_completed_total",
            "Process-data exchanges that came back.",
            cycle.completed,
        ),
        counter(
            "ecat_process_data_cycles_lost_total",
            "Process-data exchanges lost.",
            cycle.lost,
        ),
        counter(
            "ecat_process_data_cycles_wrong_wkc_total",
            "Process-data exchanges that came back with a working counter other than expected.",
            cycle.wrong_wkc,
        ),
        counter(
            "ecat_process_data_cycles_missed_total",
            "Periods in which no process-data cycle ran (skipped after a late one).",
            cycle.missed,
        ),
        Family::new(
            "ecat_process_data_cycle_period_seconds",
            "The configured period of the cyclic exchange (0: not running).",
            MetricType::GAUGE,
        )
        .gauge(&[], timing.period.as_secs_f64())
        .done(),
        Family::new(
            "ecat_process_data_wkc",
            "Working counter of the last process-data exchange.",
            MetricType::GAUGE,
        )
        .gauge(&[("kind", "last")], f64::from(cycle.last_wkc))
        .gauge(&[("kind", "expected")], f64::from(cycle.expected_wkc))
        .done(),
        Family::new(
            "ecat_bus_thread_realtime",
            "1 when the bus thread runs under SCHED_FIFO ([bus] rt_priority, granted), else 0.",
            MetricType::GAUGE,
        )
        .gauge(&[], if s.realtime { 1.0 } else { 0.0 })
        .done(),
        Family::new(
            "ecat_bus_thread_time_slice_seconds",
            "The bus thread's time slice under the fair scheduler, as the kernel reports it \
             (0: none reported, or SCHED_FIFO).",
            MetricType::GAUGE,
        )
        .gauge(&[], s.time_slice_ns as f64 * 1e-9)
        .done(),
        Family::new(
            "ecat_process_data_image_bytes",
            "Size of the process image.",
            MetricType::GAUGE,
        )
        .gauge(&[], cycle.image_len as f64)
        .done(),
    ];
    out.push(histogram(
        "ecat_bus_round_trip_seconds",
        "Frame round-trip time, send to receive on the bus thread, of frames answered at their first attempt.",
        &s.round_trip,
    ));
    out.push(histogram(
        "ecat_bus_cycle_start_delay_seconds",
        "How long after its due time each cycle started.",
        &s.cycle_start_delay,
    ));
    out.push(histogram(
        "ecat_process_data_cycle_time_seconds",
        "Time between the starts of consecutive process-data cycles.",
        &timing.cycle_time,
    ));
    out.push(histogram(
        "ecat_process_data_cycle_jitter_seconds",
        "How far each cycle time was from the period, either way.",
        &timing.jitter,
    ));
    out.push(histogram(
        "ecat_process_data_round_trip_seconds",
        "From sending the cyclic frame to its return.",
        &timing.round_trip,
    ));
    out
}

pub(super) fn histogram(
    name: &str,
    help: &str,
    snapshot: &master_core::bus::HistogramSnapshot,
) -> Option<MetricFamily> {
    histogram_series(
        Family::new(name, help, MetricType::HISTOGRAM),
        &[],
        snapshot,
    )
    .done()
}

/// Adds `snapshot` to the histogram `family` as the series of `labels`, in [`BOUNDS`].
pub(super) fn histogram_series(
    family: Family,
    labels: &[(&str, &str)],
    snapshot: &master_core::bus::HistogramSnapshot,
) -> Family {
    let mut cumulative = [0u64; BOUNDS.len()];
    let mut count = 0u64;
    for (_, high, n) in snapshot.buckets() {
        count += n;
        // A fine bucket straddling a bound counts in the next one up: the bounds are upper
        // limits, never understated.
        for (bound, slot) in BOUNDS.iter().zip(cumulative.iter_mut()) {
            if high <= Duration::from_secs_f64(*bound) {
                *slot += n;
            }
        }
    }
    let buckets: Vec<(f64, u64)> = BOUNDS.iter().copied().zip(cumulative).collect();
    family.histogram(labels, &buckets, count, snapshot.sum().as_secs_f64())
}
