//! The master's own start-up mailbox traffic against a drive whose firmware answers like
//! SOES (aborts in CoE service 2, the request's low command bits left set, no complete
//! access): the layout is read subindex by subindex once complete access is refused, and a
//! start-up write the drive refuses fails with the drive's abort, not a timeout.

use crate::master_support;

use master_core::mailbox::MailboxError;
use master_core::master::SlaveAddress;
use master_core::master::{MasterConfig, MasterError, PdoAssignment, PdoMapping};
use master_core::wire::coe::AbortCode;
use master_core::wire::register::AlState;
use master_support::{block_on, rig};
use sim::topology::{EscSpec, Topology};

const DRIVE: SlaveAddress = SlaveAddress::Position(0);

fn soes_like_drive() -> Topology {
    let mut topology = Topology::default_segment();
    topology.slaves[0].esc = EscSpec {
        sdo_abort_in_request: true,
        sdo_abort_keeps_command_bits: true,
        refuse_complete_access: true,
        ..EscSpec::default()
    };
    topology
}

#[test]
fn the_layout_is_read_by_subindex_when_complete_access_is_refused_in_service_2() {
    let plain = rig(Topology::default_segment(), MasterConfig::default());
    let report = block_on(plain.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let expected = plain.master().process_data_layout(DRIVE).unwrap();
    assert!(
        !expected.sync_managers.is_empty(),
        "the drive has process data"
    );

    let soes = rig(soes_like_drive(), MasterConfig::default());
    let report = block_on(soes.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    assert_eq!(report.slaves[0].al_state, AlState::Op);
    assert_eq!(soes.master().process_data_layout(DRIVE).unwrap(), expected);
}

#[test]
fn a_refused_start_up_write_fails_with_the_drive_abort() {
    let rig = rig(soes_like_drive(), MasterConfig::default());
    // The drive has no SyncManager 5, so no assignment object 0x1C15 either.
    rig.master().set_pdo_assignment(
        DRIVE,
        vec![PdoAssignment {
            sync_manager: 5,
            pdos: vec![PdoMapping {
                index: 0x1600,
                entries: None,
            }],
        }],
    );
    let report = block_on(rig.master().scan()).expect("scan");
    assert_eq!(report.failures.len(), 1, "{:?}", report.failures);
    match &report.failures[0] {
        MasterError::Mailbox {
            position: 0,
            source:
                MailboxError::SdoAbort {
                    index: 0x1C15,
                    subindex: 0,
                    code: AbortCode::ObjectDoesNotExist,
                },
            ..
        } => {}
        other => panic!("not the drive's abort: {other:?}"),
    }
}
