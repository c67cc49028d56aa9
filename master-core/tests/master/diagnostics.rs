//! The master's diagnostics: the ESC error counters read back as the simulated ESC
//! counted them, cleared by the master, and the bus counters seen without the bus handle.

use crate::master_support;

use master_core::master::{MasterConfig, SlaveAddress};
use master_support::{block_on, rig};
use sim::esc::ErrorCounter;
use sim::topology::Topology;

#[test]
fn error_counters_read_back_as_counted_and_clear() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    block_on(rig.master().scan()).expect("scan");
    let last = rig.master().slaves().len() - 1;
    {
        let mut segment = rig.segment();
        let esc = segment.esc_mut(last).unwrap();
        for _ in 0..3 {
            esc.count_error(ErrorCounter::InvalidFrame(0));
        }
        esc.count_error(ErrorCounter::RxError(1));
        esc.count_error(ErrorCounter::ForwardedRxError(2));
    }
    let address = SlaveAddress::Position(last as u16);
    let counters = block_on(rig.master().error_counters(address)).expect("read");
    assert_eq!(counters.invalid_frame, [3, 0, 0, 0]);
    assert_eq!(counters.rx_error, [0, 1, 0, 0]);
    assert_eq!(counters.forwarded_rx_error, [0, 0, 1, 0]);

    block_on(rig.master().clear_error_counters(address)).expect("clear");
    let counters = block_on(rig.master().error_counters(address)).expect("read");
    assert_eq!(counters.invalid_frame, [0; 4]);
    assert_eq!(counters.rx_error, [0; 4]);
    assert_eq!(counters.forwarded_rx_error, [0; 4]);
}

#[test]
fn error_counters_of_an_unknown_slave_are_refused() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    block_on(rig.master().scan()).expect("scan");
    let err = block_on(rig.master().error_counters(SlaveAddress::Position(999)))
        .expect_err("no such slave");
    assert!(err.to_string().contains("999"), "{err}");
    assert!(
        block_on(
            rig.master()
                .clear_error_counters(SlaveAddress::Position(999))
        )
        .is_err()
    );
}

#[test]
fn bus_stats_count_the_frames_of_a_register_read() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    block_on(rig.master().scan()).expect("scan");
    let before = rig.master().bus_stats();
    block_on(rig.master().error_counters(SlaveAddress::Position(0))).expect("read");
    let after = rig.master().bus_stats();
    assert!(after.frames_sent > before.frames_sent);
    assert!(after.datagrams_completed > before.datagrams_completed);
}
