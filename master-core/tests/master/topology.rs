//! Topology changes and the alias: the watch notices slaves that go and come back, reports
//! them, and restores their state; an alias set through the master keeps the SII valid and
//! addresses the slave, also after a power cycle.

use crate::master_support;

use std::time::Duration;

use master_core::master::{MasterConfig, MasterError, MasterEvent, SlaveAddress};
use master_core::wire::register::AlState;
use master_core::wire::sii::SiiImage;
use master_core::wire::sii::checksum::checksum_ok;
use master_support::{Rig, block_on, next_event, rig, wait_until};
use sim::link::InProcessLink;
use sim::topology::Topology;

fn config() -> MasterConfig {
    MasterConfig {
        watch_interval: Some(Duration::from_millis(10)),
        ..MasterConfig::default()
    }
}

fn scanned() -> Rig<InProcessLink> {
    let rig = rig(Topology::default_segment(), config());
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    rig
}

/// Whether the slave at `position` is in OP, as the master and as the simulator see it.
fn in_op(rig: &Rig<InProcessLink>, position: u16) -> bool {
    let master = rig
        .master()
        .slave(SlaveAddress::Position(position))
        .unwrap();
    let sim = rig.segment().esc(usize::from(position)).unwrap().al_state();
    master.present && master.al_state == AlState::Op && sim == AlState::Op
}

#[test]
fn an_unplugged_slave_is_reported_lost_and_found_and_returns_to_op() {
    let rig = scanned();
    let mut events = rig.master().events();
    let last = rig.topology.slaves.len() as u16 - 1;
    rig.segment().set_plugged(usize::from(last), false);
    let lost = next_event(&mut events, |e| matches!(e, MasterEvent::SlaveLost { .. }));
    assert_eq!(
        lost,
        Some(MasterEvent::SlaveLost {
            position: last,
            station: 1001 + last,
            name: rig.topology.slaves[usize::from(last)].name.clone(),
        })
    );
    assert!(wait_until(|| !rig
        .master()
        .slave(SlaveAddress::Position(last))
        .unwrap()
        .present));
    rig.segment().set_plugged(usize::from(last), true);
    let found = next_event(&mut events, |e| matches!(e, MasterEvent::SlaveFound { .. }));
    assert!(
        matches!(found, Some(MasterEvent::SlaveFound { position, .. }) if position == last),
        "{found:?}"
    );
    assert!(wait_until(|| in_op(&rig, last)));
}

#[test]
fn a_segment_that_stops_answering_loses_every_slave_and_gets_them_back() {
    let rig = scanned();
    let mut events = rig.master().events();
    let slaves = rig.topology.slaves.len();
    // The cable into the first slave: no frame comes back at all, not even a broadcast.
    rig.segment().set_plugged(0, false);
    let mut lost = Vec::new();
    while lost.len() < slaves {
        match next_event(&mut events, |e| matches!(e, MasterEvent::SlaveLost { .. })) {
            Some(MasterEvent::SlaveLost { position, .. }) => lost.push(position),
            other => panic!("expected every slave lost, got {other:?} after {lost:?}"),
        }
    }
    lost.sort_unstable();
    assert_eq!(lost, (0..slaves as u16).collect::<Vec<_>>());
    assert!(rig.master().slaves().iter().all(|s| !s.present));
    rig.segment().set_plugged(0, true);
    assert!(wait_until(|| (0..slaves as u16).all(|p| in_op(&rig, p))));
}

#[test]
fn a_power_cycled_slave_is_configured_again_and_returns_to_op() {
    let rig = scanned();
    let mut events = rig.master().events();
    // The drive: mailbox, process data, everything to configure again.
    {
        let mut segment = rig.segment();
        segment.power_cycle(0);
        assert_eq!(segment.esc(0).unwrap().station_address(), 0);
    }
    let lost = next_event(&mut events, |e| matches!(e, MasterEvent::SlaveLost { .. }));
    assert!(
        matches!(lost, Some(MasterEvent::SlaveLost { position: 0, .. })),
        "{lost:?}"
    );
    let found = next_event(&mut events, |e| matches!(e, MasterEvent::SlaveFound { .. }));
    let spec = &rig.topology.slaves[0];
    match found {
        Some(MasterEvent::SlaveFound {
            position,
            station,
            identity,
            name,
        }) => {
            assert_eq!((position, station), (0, 1001));
            assert_eq!(identity.product_code, spec.product_code);
            assert_eq!(name, spec.name);
        }
        other => panic!("expected the drive found again, got {other:?}"),
    }
    assert!(wait_until(|| in_op(&rig, 0)));
    assert_eq!(rig.segment().esc(0).unwrap().station_address(), 1001);
    // Process data flows again: the LRW's working counter is complete.
    assert!(wait_until(|| {
        let stats = rig.master().cycle_stats();
        stats.last_wkc == stats.expected_wkc
    }));
}

#[test]
fn an_alias_keeps_the_sii_valid_addresses_the_slave_and_survives_a_power_cycle() {
    let rig = scanned();
    let position = 1u16;
    let alias = 0x0777;
    let read_back = block_on(
        rig.master()
            .set_alias(SlaveAddress::Position(position), alias),
    )
    .expect("set alias");
    assert_eq!(read_back, alias);
    {
        let segment = rig.segment();
        let esc = segment.esc(usize::from(position)).unwrap();
        assert!(
            checksum_ok(esc.sii()).unwrap(),
            "the SII checksum stays valid"
        );
        let sii = SiiImage::parse(esc.sii()).unwrap();
        assert!(sii.checksum_ok);
        assert_eq!(sii.fixed.alias, alias);
        assert_eq!(esc.station_alias(), alias, "the alias register follows");
    }
    let by_alias = rig.master().slave(SlaveAddress::Alias(alias)).unwrap();
    assert_eq!(by_alias.position, position);
    // `station` resolves every form of address as `slave` does.
    let station = 1001 + position;
    for address in [
        SlaveAddress::Alias(alias),
        SlaveAddress::Position(position),
        SlaveAddress::Station(station),
    ] {
        assert_eq!(rig.master().station(address), Ok(station), "{address:?}");
    }
    assert_eq!(
        rig.master().station(SlaveAddress::Alias(0x0778)),
        Err(MasterError::UnknownSlave(SlaveAddress::Alias(0x0778)))
    );
    let station = block_on(
        rig.master()
            .read_register(SlaveAddress::Alias(alias), 0x0010, 2),
    )
    .unwrap();
    assert_eq!(station, (1001 + position).to_le_bytes());

    let mut events = rig.master().events();
    rig.segment().power_cycle(usize::from(position));
    let found = next_event(&mut events, |e| matches!(e, MasterEvent::SlaveFound { .. }));
    assert!(
        matches!(found, Some(MasterEvent::SlaveFound { position: p, .. }) if p == position),
        "{found:?}"
    );
    assert!(wait_until(|| in_op(&rig, position)));
    assert_eq!(
        rig.segment()
            .esc(usize::from(position))
            .unwrap()
            .station_alias(),
        alias
    );
    let again = rig.master().slave(SlaveAddress::Alias(alias)).unwrap();
    assert_eq!((again.position, again.alias), (position, alias));
}

#[test]
fn a_slave_with_another_identity_after_a_power_cycle_is_reported_replaced() {
    let rig = scanned();
    let position = 2u16;
    let address = SlaveAddress::Position(position);
    let old = rig.master().slave(address).unwrap().identity;
    // Another product code in the SII (words 0x0A-0x0B, outside the checksummed words):
    // after a power cycle the slave at this position is another device.
    let product = old.product_code ^ 0x00AB_0000;
    let words = [product as u16, (product >> 16) as u16];
    block_on(rig.master().write_sii(address, 0x0A, &words)).expect("write SII");
    let mut events = rig.master().events();
    rig.segment().power_cycle(usize::from(position));
    let replaced = next_event(&mut events, |e| {
        matches!(e, MasterEvent::SlaveReplaced { .. })
    });
    match replaced {
        Some(MasterEvent::SlaveReplaced {
            position: p,
            old: was,
            new,
            ..
        }) => {
            assert_eq!(p, position);
            assert_eq!(was, old);
            assert_eq!(new.product_code, product);
            assert_eq!(new.vendor_id, old.vendor_id);
        }
        other => panic!("expected a replacement, got {other:?}"),
    }
    assert!(wait_until(|| in_op(&rig, position)));
    assert_eq!(
        rig.master().slave(address).unwrap().identity.product_code,
        product
    );
}

#[test]
fn without_the_watch_a_look_on_request_sees_the_change() {
    let config = MasterConfig {
        watch_interval: None,
        ..MasterConfig::default()
    };
    let rig = rig(Topology::default_segment(), config);
    block_on(rig.master().scan()).expect("scan");
    assert!(!rig.master().watching());
    let mut events = rig.master().events();
    rig.segment().set_plugged(3, false);
    block_on(rig.master().check_topology()).expect("look");
    let mut lost = Vec::new();
    while let Ok(event) = events.try_recv() {
        if let MasterEvent::SlaveLost { position, .. } = event {
            lost.push(position);
        }
    }
    // The slave unplugged and every slave behind it.
    assert_eq!(lost, vec![3, 4]);
    rig.segment().set_plugged(3, true);
    block_on(rig.master().check_topology()).expect("look");
    let mut found = Vec::new();
    while let Ok(event) = events.try_recv() {
        if let MasterEvent::SlaveFound { position, .. } = event {
            found.push(position);
        }
    }
    assert_eq!(found, vec![3, 4]);
    assert!(in_op(&rig, 3) && in_op(&rig, 4));
    rig.master().start_watch(Duration::from_millis(10));
    assert!(rig.master().watching());
    rig.master().stop_watch();
    assert!(!rig.master().watching());
}

#[test]
fn a_watchdog_error_is_reported_with_its_code_and_acknowledged_back_to_op() {
    let rig = scanned();
    let mut events = rig.master().events();
    // A second without process data, as the slaves' watchdogs see it: the drive and the
    // output terminal fall back to SAFEOP with AL status code 0x001B.
    rig.time.advance(1_000_000_000);
    let error = next_event(&mut events, |e| matches!(e, MasterEvent::AlError { .. }));
    // The slaves with outputs watch them; whichever the watch looks at first is reported
    // first.
    let watched: Vec<u16> = (0..rig.topology.slaves.len() as u16)
        .filter(|&p| {
            rig.topology.slaves[usize::from(p)]
                .pdos
                .iter()
                .any(|pdo| pdo.is_rx())
        })
        .collect();
    assert_eq!(watched, vec![0, 1]);
    match error {
        Some(MasterEvent::AlError {
            position,
            station,
            name,
            state,
            code,
        }) => {
            assert!(watched.contains(&position), "{position}");
            assert_eq!(station, 1001 + position);
            assert_eq!(name, rig.topology.slaves[usize::from(position)].name);
            assert_eq!(state, AlState::SafeOp);
            assert_eq!(code, master_core::wire::register::AlStatusCode::SmWatchdog);
        }
        other => panic!("expected a watchdog error, got {other:?}"),
    }
    assert!(wait_until(|| (0..5).all(|p| in_op(&rig, p))));
    let drive = rig.master().slave(SlaveAddress::Position(0)).unwrap();
    assert!(!drive.al_error);
}
