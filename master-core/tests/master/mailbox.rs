//! The master hands each slave's mailbox to the mailbox engine: served from PREOP on, by
//! position, station address or alias, refused for slaves without one, and taken over
//! again (with a fresh counter) when a power-cycled slave comes back.

use crate::master_support;

use std::time::Duration;

use master_core::master::{MasterConfig, MasterError, SlaveAddress};
use master_core::wire::register::AlState;
use master_support::{block_on, rig, wait_until};
use sim::topology::Topology;

fn identity(rig: &master_support::Rig<sim::link::InProcessLink>, address: SlaveAddress) -> u32 {
    let mailbox = rig.master().mailbox(address).expect("mailbox");
    let bytes = block_on(mailbox.sdo_upload(0x1018, 1)).expect("0x1018:01");
    u32::from_le_bytes(bytes.try_into().expect("four bytes"))
}

#[test]
fn every_mailbox_slave_is_served_after_the_scan_and_others_are_refused() {
    let topology = Topology::default_segment();
    let rig = rig(topology.clone(), MasterConfig::default());
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    for (p, spec) in topology.slaves.iter().enumerate() {
        let address = SlaveAddress::Position(p as u16);
        match spec.mailbox {
            Some(_) => {
                let mailbox = rig.master().mailbox(address).expect("mailbox");
                assert_eq!(mailbox.station(), 1001 + p as u16);
                assert_eq!(
                    mailbox.config().protocols,
                    report.slaves[p].mailbox.unwrap().protocols
                );
            }
            None => assert_eq!(
                rig.master().mailbox(address).unwrap_err(),
                MasterError::NoMailbox {
                    position: p as u16,
                    state: AlState::Op
                }
            ),
        }
    }
    // The CoE store (position 3) answers with its identity, by position and by station.
    let vendor = topology.slaves[3].vendor_id;
    assert_eq!(identity(&rig, SlaveAddress::Position(3)), vendor);
    assert_eq!(identity(&rig, SlaveAddress::Station(1004)), vendor);
    assert_eq!(
        rig.master()
            .mailbox(SlaveAddress::Position(99))
            .unwrap_err(),
        MasterError::UnknownSlave(SlaveAddress::Position(99))
    );
}

#[test]
fn a_slave_back_in_init_has_no_mailbox_until_preop() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    block_on(rig.master().scan()).expect("scan");
    let drive = SlaveAddress::Position(0);
    block_on(rig.master().request_state(drive, AlState::Init)).expect("INIT");
    assert!(matches!(
        rig.master().mailbox(drive),
        Err(MasterError::NoMailbox {
            state: AlState::Init,
            ..
        })
    ));
    block_on(rig.master().request_state(drive, AlState::PreOp)).expect("PREOP");
    let vendor = rig.topology.slaves[0].vendor_id;
    assert_eq!(identity(&rig, drive), vendor);
}

#[test]
fn a_power_cycled_slave_gets_its_mailbox_back() {
    let config = MasterConfig {
        watch_interval: Some(Duration::from_millis(10)),
        ..MasterConfig::default()
    };
    let rig = rig(Topology::default_segment(), config);
    block_on(rig.master().scan()).expect("scan");
    let drive = SlaveAddress::Position(0);
    let vendor = rig.topology.slaves[0].vendor_id;
    // Several exchanges, so the master's counter is well past the slave's first one.
    for _ in 0..3 {
        assert_eq!(identity(&rig, drive), vendor);
    }
    rig.segment().power_cycle(0);
    assert!(wait_until(|| {
        rig.master()
            .slave(drive)
            .is_ok_and(|s| s.present && s.al_state == AlState::Op)
            && rig.segment().esc(0).unwrap().al_state() == AlState::Op
    }));
    assert_eq!(identity(&rig, drive), vendor);
    // That exchange was the new owner's first: counter 1. A second power cycle gives the
    // master another fresh owner, whose first request is counter 1 again; only a slave
    // that forgot its counter with the power cycle takes it (not as a repetition).
    rig.segment().power_cycle(0);
    assert!(wait_until(|| {
        rig.master()
            .slave(drive)
            .is_ok_and(|s| s.present && s.al_state == AlState::Op)
            && rig.segment().esc(0).unwrap().al_state() == AlState::Op
    }));
    assert_eq!(identity(&rig, drive), vendor);
}
