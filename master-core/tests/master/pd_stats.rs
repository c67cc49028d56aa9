//! Cycle statistics: a healthy segment keeps the expected working counter, lost frames and
//! a slave that drops out of the exchange are counted, and the timing distributions fill.

use crate::master_support;

use std::sync::{Arc, Mutex};

use master_core::bus::BusConfig;
use master_core::link::{FaultConfig, FaultInjector};
use master_core::master::MasterConfig;
use master_support::{SharedLink, block_on, rig_with, wait_until};
use sim::topology::Topology;

#[test]
fn wrong_working_counters_lost_cycles_and_timing_are_counted() {
    let config = MasterConfig {
        watch_interval: None,
        ..MasterConfig::default()
    };
    let mut shared = None;
    let rig = rig_with(
        Topology::default_segment(),
        config,
        BusConfig::default(),
        |link| {
            let link = SharedLink(Arc::new(Mutex::new(FaultInjector::new(
                link,
                FaultConfig::default(),
                7,
            ))));
            shared = Some(link.clone());
            link
        },
    );
    let injector = shared.expect("link made");
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let master = rig.master();

    // Healthy: every cycle has the expected working counter (drive 3, DO8 2, DI8 1).
    let before = master.cycle_stats();
    assert_eq!(before.expected_wkc, 6);
    assert!(wait_until(
        || master.cycle_stats().completed >= before.completed + 20
    ));
    let healthy = master.cycle_stats();
    assert_eq!(healthy.wrong_wkc, before.wrong_wkc);
    assert_eq!(healthy.last_wkc, healthy.expected_wkc);
    assert_eq!(healthy.lost, before.lost);

    // Frames vanish: the cycles are lost, not completed.
    injector.lock().set_config(FaultConfig {
        drop_rx: 1.0,
        ..FaultConfig::default()
    });
    assert!(wait_until(|| master.cycle_stats().lost >= healthy.lost + 5));
    injector.lock().set_config(FaultConfig::default());
    let resumed = master.cycle_stats().completed;
    assert!(wait_until(|| master.cycle_stats().completed >= resumed + 5));

    // The input terminal loses its configuration: its share of the working counter is
    // missing from then on, and every such cycle counts.
    let wrong = master.cycle_stats().wrong_wkc;
    rig.segment().power_cycle(2);
    assert!(wait_until(|| {
        let s = master.cycle_stats();
        s.wrong_wkc >= wrong + 5 && s.last_wkc == s.expected_wkc - 1
    }));

    let timing = master.cycle_timing();
    assert_eq!(timing.period, config.cycle_period);
    let started = timing.cycle_time.count();
    assert!(started >= 30, "{started} cycle times");
    assert_eq!(timing.jitter.count(), started);
    assert!(timing.round_trip.count() >= 30);
    assert!(timing.start_delay.count() >= started);
}
