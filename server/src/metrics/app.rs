//! The application interface (docs/application.md; present only while it serves).

use prometheus::proto::{MetricFamily, MetricType};

use super::family::Family;
use crate::service::Core;

fn one(name: &str, help: &str, kind: MetricType, value: f64) -> Option<MetricFamily> {
    let family = Family::new(name, help, kind);
    match kind {
        MetricType::COUNTER => family.counter(&[], value),
        _ => family.gauge(&[], value),
    }
    .done()
}

/// The application interface's families.
pub fn collect(core: &Core) -> Vec<Option<MetricFamily>> {
    let Some(status) = core.app_status() else {
        return Vec::new();
    };
    vec![
        one(
            "ecat_process_data_forced_entries",
            "Outputs forced from the APIs (their values go into every frame until released).",
            MetricType::GAUGE,
            core.forced_outputs().len() as f64,
        ),
        one(
            "ecat_app_attached",
            "Control programs attached to the application interface (owner and monitors).",
            MetricType::GAUGE,
            status.attached as f64,
        ),
        one(
            "ecat_app_owner_pid",
            "Process id of the program that owns the outputs; 0 when none does.",
            MetricType::GAUGE,
            f64::from(status.owner.map_or(0, |o| o.pid)),
        ),
        one(
            "ecat_app_layout_generation",
            "Layout generation of the shared process image (grows when a scan changes the image).",
            MetricType::GAUGE,
            f64::from(status.generation),
        ),
        one(
            "ecat_app_watchdog_trips_total",
            "Times the owner committed nothing for the watchdog's cycles and the safe outputs went out.",
            MetricType::COUNTER,
            status.watchdog_trips as f64,
        ),
        one(
            "ecat_app_commits_total",
            "Commits of the owner taken into a frame's outputs.",
            MetricType::COUNTER,
            status.commits as f64,
        ),
        one(
            "ecat_app_cycles_published_total",
            "Cycles published into the shared process image.",
            MetricType::COUNTER,
            status.cycles as f64,
        ),
    ]
}
