//! Slave metrics: how many slaves are in each AL state, one `ecat_slave_info` series per
//! slave with its identity, and per-slave series labelled by `station` only (join them with
//! `ecat_slave_info` for names and positions: a slave's series then stay one series when
//! it moves in the ring or is renamed).

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
        "Slaves that answer, by current AL state (absent ones: ecat_slave_present).",
        MetricType::GAUGE,
    );
    for state in AlState::ALL {
        // An absent slave's last state is not its state now (`ecat_slave_present` counts it).
        let n = slaves
            .iter()
            .filter(|s| s.present && s.al_state == state)
            .count();
        per_state = per_state.gauge(&[("state", &state_name(state))], n as f64);
    }
    let mut info = Family::new(
        "ecat_slave_info",
        "One series per slave with its position, alias, name and identity; always 1.",
        MetricType::GAUGE,
    );
    let mut code = Family::new(
        "ecat_slave_al_status_code",
        "AL status code of each slave (0: no error).",
        MetricType::GAUGE,
    );
    let mut state = Family::new(
        "ecat_slave_al_state",
        "AL state of each slave as the AL status register has it (ETG.1000.4 0x0130 bits \
         0-3): 1 INIT, 2 PREOP, 3 BOOT, 4 SAFEOP, 8 OP; an absent slave's last one.",
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
    let mut wkc = Family::new(
        "ecat_slave_wkc_errors_total",
        "Cyclic exchanges since the last scan whose wrong working counter is put down to this slave.",
        MetricType::COUNTER,
    );
    let wkc_errors = core.master().wkc_errors();
    for s in &slaves {
        let station = s.station.to_string();
        let id = s.identity;
        info = info.gauge(
            &[
                ("station", &station),
                ("position", &s.position.to_string()),
                ("alias", &s.alias.to_string()),
                ("name", &s.name),
                ("vendor_id", &format!("0x{:08x}", id.vendor_id)),
                ("product_code", &format!("0x{:08x}", id.product_code)),
                ("revision", &format!("0x{:08x}", id.revision)),
            ],
            1.0,
        );
        let labels = [("station", station.as_str())];
        code = code.gauge(&labels, f64::from(u16::from(s.al_status_code)));
        state = state.gauge(&labels, f64::from(u8::from(s.al_state)));
        present = present.gauge(&labels, if s.present { 1.0 } else { 0.0 });
        error = error.gauge(&labels, if s.al_error { 1.0 } else { 0.0 });
        // The counts are kept by ring position.
        let errors = wkc_errors
            .get(usize::from(s.position))
            .copied()
            .unwrap_or(0);
        wkc = wkc.counter(&labels, f64::from(errors));
    }
    vec![
        per_state.done(),
        info.done(),
        code.done(),
        state.done(),
        present.done(),
        error.done(),
        wkc.done(),
    ]
}
