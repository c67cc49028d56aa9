//! Slave groups with their own period: the DO8 terminal in a group of 4 ms while the rest
//! of the default segment stays in the default group at 1 ms. Each group has its own
//! logical range and its own LRW; the outputs of each reach its slaves only, and the
//! frames carry the groups in the ratio of their periods (frames counted, not time).

use crate::master_pd_support;
use crate::master_support;

use std::time::Duration;

use master_core::bus::BusConfig;
use master_core::master::{MasterConfig, SlaveAddress, SlaveGroup};
use master_core::wire::command::{Command, DatagramAddress};
use master_core::wire::register::address as reg;
use master_pd_support::{Recording, Returned, datagrams};
use master_support::{block_on, rig_with, wait_until};
use sim::topology::Topology;

const DRIVE: u16 = 0;
const DO8: u16 = 1;
const DI8: u16 = 2;
/// Group 1's logical base (group *g* at g × 0x1000).
const GROUP_1: u32 = 0x1000;

#[test]
fn two_groups_at_1_and_4_ms_each_with_its_own_range_frames_and_stats() {
    let returned = Returned::default();
    let recorder = returned.clone();
    let rig = rig_with(
        Topology::default_segment(),
        MasterConfig {
            watch_interval: None,
            cycle_period: Duration::from_millis(1),
            ..MasterConfig::default()
        },
        BusConfig::default(),
        move |inner| Recording {
            inner,
            returned: recorder,
        },
    );
    let m = rig.master();
    m.set_groups(vec![SlaveGroup {
        positions: vec![DO8],
        period: Duration::from_millis(4),
    }]);
    let report = block_on(m.scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);

    // The image: the default group (drive, DI8, store, EoE port) first, then DO8's byte.
    let topology = &rig.topology;
    let sizes: Vec<(usize, usize)> = (0..topology.slaves.len())
        .map(|p| {
            let s = rig
                .segment()
                .slave(p)
                .unwrap()
                .device()
                .process_data_sizes();
            (usize::from(s.outputs), usize::from(s.inputs))
        })
        .collect();
    let default_len: usize = sizes
        .iter()
        .enumerate()
        .filter(|(p, _)| *p != usize::from(DO8))
        .map(|(_, (o, i))| o + i)
        .sum();
    let groups = m.group_stats();
    assert_eq!(groups.len(), 2);
    assert_eq!(
        (groups[0].logical, groups[0].image_len, groups[0].period),
        (0, default_len, None)
    );
    assert_eq!(
        (groups[1].logical, groups[1].image_len, groups[1].period),
        (GROUP_1, 1, Some(Duration::from_millis(4)))
    );
    // DO8's FMMU maps its outputs at the group's logical address (FMMU 0: logical start).
    let fmmu =
        block_on(m.read_register(SlaveAddress::Position(DO8), reg::FMMU_BASE, 4)).expect("FMMU 0");
    assert_eq!(u32::from_le_bytes(fmmu.try_into().unwrap()), GROUP_1);
    // Expected working counters: DO8 writes (2); the default group: drive 3, DI8 1.
    assert_eq!(groups[1].expected_wkc, 2);
    assert_eq!(groups[0].expected_wkc, 3 + 1);

    // Outputs of each group reach its slaves only.
    let ch1 = m.entry(SlaveAddress::Position(DO8), 0x7000, 1).unwrap();
    m.write_entry(&ch1, &[1]).unwrap();
    let probe = rig.handles[usize::from(DO8)].outputs.clone().unwrap();
    assert!(wait_until(|| probe.image() == [0x01]));
    let controlword = m.entry(SlaveAddress::Position(DRIVE), 0x6040, 0).unwrap();
    m.write_entry(&controlword, &0x000Fu16.to_le_bytes())
        .unwrap();
    let dict = rig.handles[usize::from(DRIVE)].dictionary.clone().unwrap();
    assert!(wait_until(|| {
        sim::device::coe::lock_dictionary(&dict)
            .get::<u16>(0x6040, 0)
            .is_ok_and(|v| v == 0x000F)
    }));
    assert_eq!(
        probe.image(),
        [0x01],
        "the drive's outputs did not reach DO8"
    );
    let di = rig.handles[usize::from(DI8)].inputs.clone().unwrap();
    di.set_input(4, true);
    let input = m.entry(SlaveAddress::Position(DI8), 0x6000, 5).unwrap();
    assert!(wait_until(|| m.read_entry(&input).unwrap() == [1]));

    // Frames: over a run, the 4 ms group rides in every fourth cycle, counted in frames.
    returned.clear();
    let before = m.group_stats();
    let start = m.cycle_stats().completed;
    assert!(wait_until(|| m.cycle_stats().completed >= start + 200));
    let frames = returned.frames();
    let lrw_at = |logical: u32| {
        datagrams(&frames)
            .into_iter()
            .filter(|(c, a, ..)| {
                *c == Command::Lrw && *a == Some(DatagramAddress::Logical(logical))
            })
            .collect::<Vec<_>>()
    };
    let fast = lrw_at(0);
    let slow = lrw_at(GROUP_1);
    assert!(fast.len() >= 200, "{} cycles", fast.len());
    let quarter = fast.len() / 4;
    assert!(
        (quarter.saturating_sub(1)..=quarter + 1).contains(&slow.len()),
        "{} frames of the 4 ms group against {} of the 1 ms group",
        slow.len(),
        fast.len()
    );
    // Each group's datagram holds its own share only, with its own working counter.
    assert!(
        slow.iter()
            .all(|(_, _, data, wkc)| data == &[0x01] && *wkc == 2)
    );
    assert!(
        fast.iter()
            .all(|(_, _, data, wkc)| data.len() == default_len && *wkc == 4)
    );
    let after = m.group_stats();
    // (Cycles of the bring-up, in SAFEOP, had other counters: counted from here.)
    assert_eq!(after[0].wrong_wkc, before[0].wrong_wkc);
    assert_eq!(after[1].wrong_wkc, before[1].wrong_wkc);
    assert!(after[1].completed > 0 && after[0].completed >= 4 * (after[1].completed - 1));
    let snapshot = m.group_snapshot(1).expect("group 1 snapshot");
    assert_eq!((snapshot.wkc, snapshot.expected_wkc), (2, 2));
    assert_eq!(
        snapshot.cycle,
        m.group_stats()[1].completed.min(snapshot.cycle)
    );
    assert!(m.group_snapshot(2).is_none());
}

#[test]
fn without_groups_the_image_stays_one_lrw_at_logical_0() {
    let rig = master_support::rig(
        Topology::default_segment(),
        MasterConfig {
            watch_interval: None,
            ..MasterConfig::default()
        },
    );
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let groups = rig.master().group_stats();
    assert_eq!(groups.len(), 1);
    let stats = rig.master().cycle_stats();
    assert_eq!(
        (
            groups[0].logical,
            groups[0].image_len,
            groups[0].expected_wkc
        ),
        (0, stats.image_len, stats.expected_wkc)
    );
}
