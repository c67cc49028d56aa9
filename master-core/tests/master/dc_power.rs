//! A DC slave power-cycled after the scan loses its clock (it restarts from zero, offset
//! and delay cleared); when the watch brings it back, the master measures its delay again
//! and gives it the offset that puts it back on the reference's time.

use crate::master_support;

use std::time::Duration;

use master_core::master::{MasterConfig, MasterEvent, SlaveAddress};
use master_core::wire::register::AlState;
use master_core::wire::register::address as reg;
use master_support::{block_on, next_event, rig_on, wait_until};
use sim::esc::DcConfig;
use sim::topology::{Topology, build_with_handles};

/// Per-hop delays given to the five slaves (ns).
const HOPS: [u32; 5] = [150, 200, 300, 120, 500];
/// The slave power-cycled: the DI8 terminal (DC, process data).
const CYCLED: usize = 2;
/// How far apart the clocks may be (the same bound as master_dc's, clocks not drifting).
const BOUND_NS: i64 = 200;

#[test]
fn a_power_cycled_slave_gets_its_delay_and_offset_again() {
    let mut topology = Topology::default_segment();
    for (slave, hop) in topology.slaves.iter_mut().zip(HOPS) {
        slave.esc.hop_delay_ns = hop;
    }
    let built = build_with_handles(&topology).expect("builds");
    let mut segment = built.segment;
    for (p, hop) in HOPS.iter().enumerate() {
        segment.esc_mut(p).unwrap().set_dc_config(DcConfig {
            hop_delay_ns: *hop,
            clock_start_ns: 7_000_000_000 * p as u64 + 123_457,
            drift_ppb: 0,
        });
    }
    let rig = rig_on(
        segment,
        built.time,
        topology,
        MasterConfig {
            watch_interval: Some(Duration::from_millis(20)),
            ..MasterConfig::default()
        },
    );
    let m = rig.master();
    let report = block_on(m.scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    // Subscribed after the scan: its own SlaveFound events are not the watch's.
    let mut events = m.events();
    let expected_delay: u32 = HOPS[1..=CYCLED].iter().sum();
    let system_time = |p: usize| {
        let segment = rig.segment();
        segment.esc(p).unwrap().system_time(segment.now_ns())
    };
    let apart = |p: usize| (system_time(p) as i64 - system_time(0) as i64).abs();
    assert!(apart(CYCLED) <= BOUND_NS);

    rig.time.advance(1_000_000_000);
    rig.segment().power_cycle(CYCLED);
    assert_eq!(
        rig.segment()
            .esc(CYCLED)
            .unwrap()
            .read_u32(reg::DC_SYSTEM_TIME_DELAY),
        0,
        "the power cycle cleared the delay"
    );
    assert!(apart(CYCLED) > 1_000_000, "the restarted clock is far off");

    let found = next_event(
        &mut events,
        |e| matches!(e, MasterEvent::SlaveFound { position, .. } if usize::from(*position) == CYCLED),
    );
    assert!(found.is_some(), "the watch found the slave again");
    // Found is announced before the slave is configured again: wait for the end of that.
    let cycled = SlaveAddress::Position(CYCLED as u16);
    assert!(
        wait_until(|| rig
            .segment()
            .esc(CYCLED)
            .unwrap()
            .read_u32(reg::DC_SYSTEM_TIME_DELAY)
            == expected_delay),
        "the delay was not measured again"
    );
    assert!(wait_until(|| m
        .slave(cycled)
        .is_ok_and(|s| s.al_state == AlState::Op)));
    let delay = rig
        .segment()
        .esc(CYCLED)
        .unwrap()
        .read_u32(reg::DC_SYSTEM_TIME_DELAY);
    assert_eq!(delay, expected_delay, "0x0928 measured again");
    assert!(
        apart(CYCLED) <= BOUND_NS,
        "{} ns from the reference after the restore",
        apart(CYCLED)
    );
    let dc = m.dc_slaves();
    assert_eq!(dc[CYCLED].delay_ns, expected_delay);
    // The others kept their settings.
    for p in [1, 3, 4] {
        assert!(apart(p) <= BOUND_NS, "slave {p}");
    }
}
