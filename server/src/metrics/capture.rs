//! The rolling capture's counters (present only while it runs, `[capture] rolling`).

use std::sync::atomic::Ordering;

use prometheus::proto::{MetricFamily, MetricType};

use super::family::Family;
use crate::service::Core;

fn counter(name: &str, help: &str, value: u64) -> Option<MetricFamily> {
    Family::new(name, help, MetricType::COUNTER)
        .counter(&[], value as f64)
        .done()
}

/// The rolling capture's families.
pub fn collect(core: &Core) -> Vec<Option<MetricFamily>> {
    let Some(stats) = core.rolling_stats() else {
        return Vec::new();
    };
    vec![
        counter(
            "ecat_capture_rolling_frames_total",
            "Frames the rolling capture wrote to its ring.",
            stats.frames.load(Ordering::Relaxed),
        ),
        counter(
            "ecat_capture_rolling_dropped_frames_total",
            "Frames the rolling capture could not queue (its writer fell behind the bus).",
            stats.dropped.load(Ordering::Relaxed),
        ),
        counter(
            "ecat_capture_rolling_rotations_total",
            "Files of the rolling capture closed for a new one.",
            stats.rotations.load(Ordering::Relaxed),
        ),
        counter(
            "ecat_capture_rolling_errors_total",
            "Writes of the rolling capture that failed (disk full, say).",
            stats.errors.load(Ordering::Relaxed),
        ),
    ]
}
