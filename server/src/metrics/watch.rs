//! The watched values (`[[watch]]`) as `ecat_watch_value` and
//! `ecat_watch_read_errors_total`.

use prometheus::proto::{MetricFamily, MetricType};

use super::family::Family;
use crate::watch::WatchValues;

/// The families (a watch never read successfully has no value sample).
pub fn collect(watches: &WatchValues) -> Vec<Option<MetricFamily>> {
    let mut values = Family::new(
        "ecat_watch_value",
        "Last value read of each watched object or IDN ([[watch]] in the configuration).",
        MetricType::GAUGE,
    );
    let mut errors = Family::new(
        "ecat_watch_read_errors_total",
        "Failed reads of each watched object or IDN (the last value stays).",
        MetricType::COUNTER,
    );
    for sample in watches.samples() {
        let l = &sample.labels;
        let labels = [
            ("slave", l.slave.as_str()),
            ("object", l.object.as_str()),
            ("name", l.name.as_str()),
        ];
        if let Some(value) = sample.value {
            values = values.gauge(&labels, value);
        }
        errors = errors.counter(&labels, sample.errors as f64);
    }
    vec![values.done(), errors.done()]
}
