//! The process image by named entries: outputs written through the API reach the simulated
//! terminals' physical outputs, physical inputs appear in the image, and a snapshot holds
//! one cycle's image with its working counter.

use crate::master_support;

use master_core::master::{MasterConfig, MasterError, SlaveAddress};
use master_core::wire::coe::DataType;
use master_support::{block_on, rig, wait_until};
use sim::topology::Topology;

#[test]
fn the_output_terminal_follows_entries_written_through_the_api() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let do8 = SlaveAddress::Position(1);
    let entries = rig.master().entries(do8).expect("entries");
    // The topology's eight channels, one bit each, named as in the SII.
    let spec = &rig.topology.slaves[1].pdos[0];
    assert_eq!(entries.len(), spec.entries.len());
    for (entry, spec) in entries.iter().zip(&spec.entries) {
        assert_eq!(
            (entry.index, entry.subindex, entry.bit_length),
            (spec.index, spec.subindex, spec.bits)
        );
        assert_eq!(entry.name, spec.name);
        assert_eq!(entry.data_type, Some(DataType::Boolean));
        assert!(entry.output);
    }
    let ch3 = rig.master().entry(do8, 0x7000, 3).unwrap();
    let ch8 = rig.master().entry(do8, 0x7000, 8).unwrap();
    rig.master()
        .write_entries(&[(&ch3, &[1]), (&ch8, &[1])])
        .expect("write");
    let probe = rig.handles[1].outputs.clone().expect("output probe");
    assert!(
        wait_until(|| probe.image() == [0b1000_0100]),
        "physical outputs {:?}",
        probe.image()
    );
    assert!(probe.output(2) && probe.output(7) && !probe.output(0));
    rig.master().write_entry(&ch3, &[0]).unwrap();
    assert!(wait_until(|| probe.image() == [0b1000_0000]));
    assert_eq!(rig.master().read_entry(&ch8).unwrap(), vec![1]);

    // Inputs cannot be written, and values must cover the entry.
    let di = rig
        .master()
        .entry(SlaveAddress::Position(2), 0x6000, 1)
        .unwrap();
    assert!(matches!(
        rig.master().write_entry(&di, &[1]),
        Err(MasterError::InvalidArgument(_))
    ));
    let controlword = rig
        .master()
        .entry(SlaveAddress::Position(0), 0x6040, 0)
        .unwrap();
    assert!(rig.master().write_entry(&controlword, &[6]).is_err());
    assert!(
        rig.master().entry(do8, 0x6000, 1).is_err(),
        "DO8 maps no inputs"
    );
}

#[test]
fn physical_inputs_appear_in_snapshots() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let di8 = SlaveAddress::Position(2);
    let entries = rig.master().entries(di8).unwrap();
    assert_eq!(entries.len(), 8);
    let driver = rig.handles[2].inputs.clone().expect("input driver");
    driver.set_input(1, true);
    driver.set_input(6, true);
    let on = |snapshot: &master_core::master::ImageSnapshot| -> Vec<bool> {
        entries
            .iter()
            .map(|e| snapshot.get_bool(e).unwrap())
            .collect()
    };
    let expected = vec![false, true, false, false, false, false, true, false];
    assert!(wait_until(|| on(&rig.master().snapshot()) == expected));

    // A snapshot is one cycle's image: its working counter is the full one, and a later
    // snapshot is of a later cycle.
    let mut snapshot = rig.master().snapshot();
    assert!(
        snapshot.complete(),
        "wkc {} of {}",
        snapshot.wkc,
        snapshot.expected_wkc
    );
    let first = snapshot.cycle;
    assert!(wait_until(|| {
        rig.master().snapshot_into(&mut snapshot);
        snapshot.cycle > first
    }));
    assert_eq!(on(&snapshot), expected);
}

#[test]
fn the_drive_answers_its_controlword_through_multi_byte_entries() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let drive = SlaveAddress::Position(0);
    let controlword = rig.master().entry(drive, 0x6040, 0).unwrap();
    let target = rig.master().entry(drive, 0x607A, 0).unwrap();
    let statusword = rig.master().entry(drive, 0x6041, 0).unwrap();
    let actual = rig.master().entry(drive, 0x6064, 0).unwrap();
    assert_eq!((controlword.bit_length, target.bit_length), (16, 32));
    // Inputs sit after the drive's 6 output bytes, at image offset 6.
    assert_eq!(statusword.bit_offset, 6 * 8);
    assert_eq!(actual.bit_offset, 8 * 8);
    let status =
        |rig: &master_support::Rig<_>| rig.master().snapshot().get_u64(&statusword).unwrap();
    // CiA 402: shutdown, switch on, enable operation; each state shows in the statusword.
    for (command, state) in [(0x0006u16, 0x0031u64), (0x0007, 0x0033), (0x000F, 0x0037)] {
        rig.master()
            .write_entry(&controlword, &command.to_le_bytes())
            .unwrap();
        assert!(
            wait_until(|| status(&rig) == state),
            "statusword {:#06x} after {command:#06x}",
            status(&rig)
        );
    }
    // Operation enabled: the ideal axis takes the target position.
    rig.master()
        .write_entry(&target, &(-123_456i32).to_le_bytes())
        .unwrap();
    assert!(wait_until(|| {
        rig.master().snapshot().get(&actual) == Some((-123_456i32).to_le_bytes().to_vec())
    }));
}
