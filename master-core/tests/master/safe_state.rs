//! The shutdown's safe state: `Master::all_to_safe` brings the whole segment down at once
//! and confirms it, leaves a slave below SAFEOP where it is, and refuses a state that is
//! not a safe one.

use crate::master_support;

use std::time::Duration;

use master_core::master::{MasterConfig, MasterError, SlaveAddress};
use master_core::wire::register::AlState;
use master_support::{Rig, block_on, rig};
use sim::link::InProcessLink;
use sim::topology::Topology;

fn deadline() -> tokio::time::Instant {
    tokio::time::Instant::now() + Duration::from_secs(5)
}

/// Every slave's AL state as the simulator holds it.
fn sim_states(rig: &Rig<InProcessLink>) -> Vec<AlState> {
    (0..rig.topology.slaves.len())
        .map(|i| rig.segment().esc(i).unwrap().al_state())
        .collect()
}

#[test]
fn the_segment_goes_to_safeop_then_init_and_a_preop_slave_is_not_raised() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let count = rig.topology.slaves.len();
    assert_eq!(sim_states(&rig), vec![AlState::Op; count]);
    block_on(
        rig.master()
            .request_state(SlaveAddress::Position(1), AlState::PreOp),
    )
    .expect("slave 1 to PREOP");

    let safeop = block_on(rig.master().all_to_safe(AlState::SafeOp, deadline())).unwrap();
    assert!(safeop.confirmed, "{safeop:?}");
    assert_eq!(usize::from(safeop.slaves), count);
    let mut expected = vec![AlState::SafeOp; count];
    expected[1] = AlState::PreOp;
    assert_eq!(sim_states(&rig), expected);

    let init = block_on(rig.master().all_to_safe(AlState::Init, deadline())).unwrap();
    assert!(init.confirmed, "{init:?}");
    assert_eq!(usize::from(init.slaves), count);
    assert_eq!(sim_states(&rig), vec![AlState::Init; count]);
    // The records follow, so that nothing brings the slaves back up.
    for slave in rig.master().slaves() {
        assert_eq!(slave.requested_state, AlState::Init, "{}", slave.position);
    }
}

#[test]
fn only_init_and_safeop_are_safe_states() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    for state in [AlState::Op, AlState::PreOp, AlState::Boot] {
        let refused = block_on(rig.master().all_to_safe(state, deadline()));
        assert!(
            matches!(refused, Err(MasterError::InvalidState(s)) if s == state),
            "{state}: {refused:?}"
        );
    }
}
