//! Cable redundancy (docs/redundancy.md): the ring's state, where it broke, how often it
//! broke and healed, and the slaves no port reaches. Read from the ring link's atomics at
//! scrape time; on a single port the state is 0 (off) and the rest reads as a ring that
//! never broke.

use prometheus::proto::{MetricFamily, MetricType};

use super::family::Family;
use crate::service::{Core, RedundancyView};

/// `ecat_bus_redundancy_state`'s value for a state name.
fn state_value(state: &str) -> f64 {
    match state {
        "closed" => 1.0,
        "broken" => 2.0,
        // No frame back yet since the start: nothing known, not "off".
        "unknown" => -1.0,
        _ => 0.0,
    }
}

fn gauge(name: &str, help: &str, value: f64) -> Option<MetricFamily> {
    Family::new(name, help, MetricType::GAUGE)
        .gauge(&[], value)
        .done()
}

fn counter(name: &str, help: &str, value: u64) -> Option<MetricFamily> {
    Family::new(name, help, MetricType::COUNTER)
        .counter(&[], value as f64)
        .done()
}

/// The families.
pub fn collect(core: &Core) -> Vec<Option<MetricFamily>> {
    families(&core.redundancy())
}

fn families(ring: &RedundancyView) -> Vec<Option<MetricFamily>> {
    vec![
        gauge(
            "ecat_bus_redundancy_state",
            "Cable redundancy: 0 off (one port), 1 ring closed, 2 ring broken, -1 not known yet.",
            state_value(&ring.state),
        ),
        gauge(
            "ecat_bus_redundancy_break_after",
            "With the ring broken: the break is after this many slaves from the primary port \
             (0: the primary cable); -1 when not broken.",
            ring.break_after.map_or(-1.0, f64::from),
        ),
        counter(
            "ecat_bus_redundancy_breaks_total",
            "Times the ring went from closed to broken.",
            ring.breaks,
        ),
        counter(
            "ecat_bus_redundancy_heals_total",
            "Times the ring went from broken to closed.",
            ring.heals,
        ),
        gauge(
            "ecat_bus_redundancy_unreachable_slaves",
            "With the ring broken: slaves reached from neither port.",
            f64::from(ring.unreachable),
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The text exposition of `families`.
    fn text(families: Vec<Option<MetricFamily>>) -> String {
        use prometheus::Encoder;
        let families: Vec<MetricFamily> = families.into_iter().flatten().collect();
        let mut out = Vec::new();
        prometheus::TextEncoder::new()
            .encode(&families, &mut out)
            .unwrap();
        String::from_utf8(out).unwrap()
    }

    fn has(text: &str, line: &str) -> bool {
        text.lines().any(|l| l == line)
    }

    #[test]
    fn a_broken_ring_shows_state_2_and_where_and_off_shows_0_and_minus_1() {
        let off = text(families(&RedundancyView::off()));
        assert!(has(&off, "ecat_bus_redundancy_state 0"), "{off}");
        assert!(has(&off, "ecat_bus_redundancy_break_after -1"), "{off}");
        let broken = RedundancyView {
            state: "broken".into(),
            break_after: Some(3),
            unreachable: 1,
            breaks: 2,
            heals: 1,
            ..RedundancyView::off()
        };
        let broken = text(families(&broken));
        for line in [
            "ecat_bus_redundancy_state 2",
            "ecat_bus_redundancy_break_after 3",
            "ecat_bus_redundancy_breaks_total 2",
            "ecat_bus_redundancy_heals_total 1",
            "ecat_bus_redundancy_unreachable_slaves 1",
        ] {
            assert!(has(&broken, line), "{line} in {broken}");
        }
        assert_eq!(state_value("unknown"), -1.0);
        assert_eq!(state_value("closed"), 1.0);
    }
}
