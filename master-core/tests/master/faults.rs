//! Bring-up on a bad cable: with 5% of the frames lost (seeded), every slave still reaches
//! OP, and the bus counts exactly the frames the injector dropped as lost.

use crate::master_support;

use std::time::Duration;

use master_core::bus::BusConfig;
use master_core::link::{FaultConfig, FaultInjector};
use master_core::master::{MasterConfig, SlaveAddress};
use master_core::wire::register::AlState;
use master_support::{SharedLink, block_on, rig_with, wait_until};
use sim::topology::Topology;

#[test]
fn bring_up_survives_five_percent_frame_loss_and_the_loss_is_counted() {
    let faults = FaultConfig {
        drop_tx: 0.025,
        drop_rx: 0.025,
        ..FaultConfig::default()
    };
    let mut shared = None;
    let topology = Topology::default_segment();
    let bus_config = BusConfig {
        // Generous: a frame counts as lost only when it really is, also on a loaded machine.
        response_timeout: Duration::from_millis(50),
        retries: 8,
        ..BusConfig::default()
    };
    let config = MasterConfig {
        cycle_period: Duration::from_millis(20),
        watch_interval: None,
        ..MasterConfig::default()
    };
    let rig = rig_with(topology.clone(), config, bus_config, |link| {
        let link = SharedLink(std::sync::Arc::new(std::sync::Mutex::new(
            FaultInjector::new(link, faults, 0x5EED),
        )));
        shared = Some(link.clone());
        link
    });
    let injector = shared.expect("link made");
    let report = block_on(rig.master().scan()).expect("scan despite the loss");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    for p in 0..topology.slaves.len() {
        let info = rig
            .master()
            .slave(SlaveAddress::Position(p as u16))
            .unwrap();
        assert_eq!(info.al_state, AlState::Op, "{}", info.name);
        assert_eq!(rig.segment().esc(p).unwrap().al_state(), AlState::Op);
    }
    // Stop the loss; every frame dropped so far is then counted once its deadline passes.
    injector.lock().set_config(FaultConfig::default());
    let counts = injector.lock().counts();
    let dropped = counts.tx_dropped + counts.rx_dropped;
    assert!(dropped > 0, "the injector dropped nothing: {counts:?}");
    let bus = rig.master().bus().clone();
    // A frame that times out without being dropped (the machine stalled longer than the
    // response timeout) also comes back later, as a stale frame: lost minus stale is what
    // the cable lost.
    let settled = wait_until(|| {
        let stats = bus.stats();
        stats.frames_lost - stats.frames_stale == dropped
    });
    let stats = bus.stats();
    assert!(
        settled,
        "lost {} stale {} dropped {dropped}",
        stats.frames_lost, stats.frames_stale
    );
    assert!(stats.retries > 0);
}
