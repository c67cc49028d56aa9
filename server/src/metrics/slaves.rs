//! Slave metrics: how many slaves are in each AL state, and each slave's AL status code.

use master_core::wire::register::AlState;
use prometheus::proto::{MetricFamily, MetricType};

use super::family::Family;
use crate::service::Core;
use crate::service::view::state_name;

/// The slave families.
pub fn collect(core: &Core) -> Vec<Option<MetricFamily>> {
    let slaves = core.master().slaves();
    let mut per_state = Family::new(
        "ecat_slaves",
        "Slaves by current AL state.",
        MetricType::GAUGE,
    );
    for state in [
        AlState::Init,
        AlState::PreOp,
        AlState::Boot,
        AlState::SafeOp,
        AlState::Op,
    ] {
        let n = slaves.iter().filter(|s| s.al_state == state).count();
        per_state = per_state.gauge(&[("state", &state_name(state))], n as f64);
    }
    let mut code = Family::new(
        "ecat_slave_al_status_code",
        "AL status code of each slave (0: no error).",
        MetricType::GAUGE,
    );
    let mut present = Family::new(
        "ecat_slave_present",
        "1 if the slave answered the last look.",
        MetricType::GAUGE,
    );
    let mut error = Family::new(
        "ecat_slave_al_error",
        "1 if the slave's AL status shows an error.",
        MetricType::GAUGE,
    );
    for s in &slaves {
        let position = s.position.to_string();
        let station = s.station.to_string();
        let labels = [
            ("position", position.as_str()),
            ("station", station.as_str()),
            ("name", s.name.as_str()),
        ];
        code = code.gauge(&labels, f64::from(u16::from(s.al_status_code)));
        present = present.gauge(&labels, if s.present { 1.0 } else { 0.0 });
        error = error.gauge(&labels, if s.al_error { 1.0 } else { 0.0 });
    }
    vec![per_state.done(), code.done(), present.done(), error.done()]
}
