//! The per-slave configuration on the in-process segment: start-up commands run in order
//! per transition and a refused one stops that slave with the abort code in the event;
//! a slave not the one expected is held in PREOP (or the whole segment, or the scan stops
//! before any slave leaves INIT); SYNC1 is set from the slave's DC settings.

use crate::master_support;

use std::time::Duration;

use master_core::mailbox::MailboxError;
use master_core::master::{
    ExpectedIdentity, MasterConfig, MasterError, MasterEvent, MismatchPolicy, SlaveAddress,
    SlaveConfig, SlaveConfigs, SlaveDc, StartupAction, StartupCommand, SyncSignal, TopologyProblem,
    Transition,
};
use master_core::wire::coe::AbortCode;
use master_core::wire::register::AlState;
use master_support::{block_on, next_event, rig};
use sim::topology::Topology;

const STORE: u16 = 3;
const DI8: u16 = 2;

fn sdo(transition: Transition, index: u16, data: &[u8]) -> StartupCommand {
    StartupCommand {
        transition,
        action: StartupAction::Sdo {
            index,
            subindex: 0,
            data: data.to_vec(),
            complete_access: false,
        },
    }
}

fn at(position: u16) -> Option<SlaveAddress> {
    Some(SlaveAddress::Position(position))
}

#[test]
fn start_up_commands_run_per_transition_and_a_refused_one_stops_that_slave() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    let mut events = rig.master().events();
    rig.master().set_slave_configs(SlaveConfigs {
        slaves: vec![
            SlaveConfig {
                address: at(STORE),
                // IP runs once in PREOP (a normal transfer, 8 bytes), PS before SAFEOP.
                startup: vec![
                    sdo(
                        Transition::PREOP_SAFEOP,
                        0x2001,
                        &0x2222_2222u32.to_le_bytes(),
                    ),
                    sdo(Transition::INIT_PREOP, 0x2000, b"ecatd-IP"),
                ],
                ..SlaveConfig::default()
            },
            SlaveConfig {
                address: at(0),
                // The drive has no object 0x6000.
                startup: vec![sdo(Transition::SAFEOP_OP, 0x6000, &[1])],
                ..SlaveConfig::default()
            },
        ],
        ..SlaveConfigs::default()
    });
    let report = block_on(rig.master().scan()).expect("scan");
    assert_eq!(report.slaves[STORE as usize].al_state, AlState::Op);
    let mailbox = rig.master().mailbox(SlaveAddress::Position(STORE)).unwrap();
    let value = block_on(mailbox.sdo_upload(0x2001, 0)).unwrap();
    assert_eq!(value, 0x2222_2222u32.to_le_bytes());
    let large = block_on(mailbox.sdo_upload(0x2000, 0)).unwrap();
    assert_eq!(&large[..8], b"ecatd-IP");
    // The drive stopped before OP, with the abort in the error and in the event.
    assert_eq!(report.slaves[0].al_state, AlState::SafeOp);
    assert!(
        report.failures.iter().any(|f| matches!(
            f,
            MasterError::Startup {
                position: 0,
                source: MailboxError::SdoAbort { index: 0x6000, .. },
                ..
            }
        )),
        "{:?}",
        report.failures
    );
    let event = next_event(&mut events, |e| {
        matches!(e, MasterEvent::StartupFailed { .. })
    })
    .expect("a startup_failed event");
    let MasterEvent::StartupFailed {
        position,
        transition,
        command,
        abort_code,
        ..
    } = event
    else {
        unreachable!()
    };
    assert_eq!((position, transition.as_str()), (0, "SAFEOP -> OP"));
    assert_eq!(command, "SDO 0x6000:00");
    assert_eq!(abort_code, Some(u32::from(AbortCode::ObjectDoesNotExist)));
}

fn expect_product(position: u16, product_code: u32) -> SlaveConfig {
    SlaveConfig {
        address: at(position),
        expected: Some(ExpectedIdentity {
            product_code: Some(product_code),
            ..ExpectedIdentity::default()
        }),
        ..SlaveConfig::default()
    }
}

#[test]
fn a_slave_not_the_one_expected_is_held_in_preop_or_holds_the_segment_or_stops_the_scan() {
    for policy in [
        MismatchPolicy::Slave,
        MismatchPolicy::Segment,
        MismatchPolicy::Stop,
    ] {
        let rig = rig(Topology::default_segment(), MasterConfig::default());
        let mut events = rig.master().events();
        rig.master().set_slave_configs(SlaveConfigs {
            slaves: vec![expect_product(0, 1), expect_product(DI8, 99)],
            policy,
            report_extra: false,
            watchdog: None,
        });
        let result = block_on(rig.master().scan());
        let event = next_event(&mut events, |e| {
            matches!(e, MasterEvent::TopologyMismatch { .. })
        })
        .expect("a topology_mismatch event");
        assert!(matches!(
            event,
            MasterEvent::TopologyMismatch {
                position: DI8,
                station: 1003,
                problem: TopologyProblem::Mismatch { .. },
            }
        ));
        let states: Vec<AlState> = match (policy, result) {
            (MismatchPolicy::Stop, Err(MasterError::Configuration { position, reason })) => {
                assert_eq!(position, DI8);
                assert!(
                    reason.contains("product code 0x00000063 expected"),
                    "{reason}"
                );
                // Nothing was brought up: every slave is still in INIT.
                let slaves = rig.master().slaves();
                assert!(slaves.is_empty() || slaves.iter().all(|s| s.al_state == AlState::Init));
                continue;
            }
            (_, Ok(report)) => report.slaves.iter().map(|s| s.al_state).collect(),
            (policy, other) => panic!("{policy:?}: {other:?}"),
        };
        let expected = match policy {
            MismatchPolicy::Slave => {
                vec![
                    AlState::Op,
                    AlState::Op,
                    AlState::PreOp,
                    AlState::Op,
                    AlState::Op,
                ]
            }
            _ => vec![AlState::PreOp; 5],
        };
        assert_eq!(states, expected, "{policy:?}");
    }
}

#[test]
fn a_slave_s_own_dc_settings_start_sync0_and_sync1() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    rig.master().set_slave_configs(SlaveConfigs {
        slaves: vec![SlaveConfig {
            address: at(0),
            dc: Some(SlaveDc::Sync {
                sync0: SyncSignal {
                    cycle: Duration::from_micros(500),
                    shift: Duration::ZERO,
                },
                sync1: Some(SyncSignal {
                    cycle: Duration::from_micros(100),
                    shift: Duration::from_micros(20),
                }),
            }),
            ..SlaveConfig::default()
        }],
        ..SlaveConfigs::default()
    });
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let read = |address: u16, len: usize| {
        block_on(
            rig.master()
                .read_register(SlaveAddress::Position(0), address, len),
        )
        .unwrap()
    };
    assert_eq!(read(0x0981, 1)[0] & 0x07, 0x07, "cyclic, SYNC0, SYNC1");
    assert_eq!(read(0x09A0, 4), 500_000u32.to_le_bytes());
    assert_eq!(read(0x09A4, 4), 120_000u32.to_le_bytes());
}
