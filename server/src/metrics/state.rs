//! Whether ecatd is ready (`ecat_ready`, as `/readyz`) and whether its EtherCAT link has
//! a carrier (`ecat_link_up`): the alerts' first questions, "is it serving" and "is the
//! cable in".

use prometheus::proto::{MetricFamily, MetricType};

use super::family::Family;
use crate::service::Core;

/// The link ecatd's segment runs on.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum Link {
    /// Not known (no segment yet): no `ecat_link_up`.
    #[default]
    Unknown,
    /// The in-process simulator: always up.
    Simulated,
    /// A network interface, by name: up while the kernel reports a carrier.
    Iface(String),
}

impl Link {
    /// 1 while the link carries frames, 0 when not; `None` when unknown.
    fn up(&self) -> Option<bool> {
        match self {
            Link::Unknown => None,
            Link::Simulated => Some(true),
            // The kernel refuses to read `carrier` of an interface that is down; a
            // missing interface is down too.
            Link::Iface(name) => Some(
                std::fs::read_to_string(format!("/sys/class/net/{name}/carrier"))
                    .is_ok_and(|text| text.trim() == "1"),
            ),
        }
    }
}

/// The families.
pub fn collect(core: &Core, link: &Link) -> Vec<Option<MetricFamily>> {
    let ready = Family::new(
        "ecat_ready",
        "1 once the first scan is done and ecatd is not stopping (as /readyz).",
        MetricType::GAUGE,
    )
    .gauge(&[], if core.ready() { 1.0 } else { 0.0 })
    .done();
    let link = link.up().and_then(|up| {
        Family::new(
            "ecat_link_up",
            "1 while the EtherCAT link has a carrier (always 1 on the simulated segment).",
            MetricType::GAUGE,
        )
        .gauge(&[], if up { 1.0 } else { 0.0 })
        .done()
    });
    vec![ready, link]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_has_a_carrier_and_a_missing_interface_none() {
        assert_eq!(Link::Simulated.up(), Some(true));
        assert_eq!(Link::Unknown.up(), None);
        assert_eq!(Link::Iface("ecatd-no-such-if".into()).up(), Some(false));
        // `lo` reports a carrier once up, which it is in any network namespace we run in.
        assert_eq!(Link::Iface("lo".into()).up(), Some(true));
    }
}
