//! EoE interface metrics (interface label): frames, bytes and drops each way, reassembly
//! errors, and whether the interface is up.

use prometheus::proto::{MetricFamily, MetricType};

use super::family::Family;
use crate::eoe::InterfaceView;
use crate::service::Core;

type Field = fn(&InterfaceView) -> u64;

const COUNTERS: [(&str, &str, Field); 7] = [
    (
        "ecat_eoe_interface_tx_frames_total",
        "Frames the host sent through the interface to the slave.",
        |i| i.frames_out,
    ),
    (
        "ecat_eoe_interface_tx_bytes_total",
        "Bytes of those frames.",
        |i| i.bytes_out,
    ),
    (
        "ecat_eoe_interface_tx_dropped_total",
        "Frames from the host the slave's mailbox could not take (error, slave gone).",
        |i| i.drops_out,
    ),
    (
        "ecat_eoe_interface_rx_frames_total",
        "Frames from the slave written to the interface.",
        |i| i.frames_in,
    ),
    (
        "ecat_eoe_interface_rx_bytes_total",
        "Bytes of those frames.",
        |i| i.bytes_in,
    ),
    (
        "ecat_eoe_interface_rx_dropped_total",
        "Frames from the slave lost before the interface.",
        |i| i.drops_in,
    ),
    (
        "ecat_eoe_interface_reassembly_errors_total",
        "Frames from the slave dropped in reassembly (lost or late fragment).",
        |i| i.reassembly_errors,
    ),
];

/// The EoE interface families.
pub fn collect(core: &Core) -> Vec<Option<MetricFamily>> {
    let interfaces = core.eoe_interfaces();
    let mut families: Vec<Option<MetricFamily>> = COUNTERS
        .iter()
        .map(|(name, help, field)| {
            interfaces
                .iter()
                .fold(Family::new(name, help, MetricType::COUNTER), |f, i| {
                    f.counter(&labels(i), field(i) as f64)
                })
                .done()
        })
        .collect();
    families.push(
        interfaces
            .iter()
            .fold(
                Family::new(
                    "ecat_eoe_interface_up",
                    "1 while the interface's carrier is on (slave present, PREOP or higher).",
                    MetricType::GAUGE,
                ),
                |f, i| f.gauge(&labels(i), if i.state == "up" { 1.0 } else { 0.0 }),
            )
            .done(),
    );
    families
}

fn labels(i: &InterfaceView) -> [(&str, &str); 1] {
    [("interface", i.name.as_str())]
}
