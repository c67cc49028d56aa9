//! A PDO assignment given to the master is written in PREOP as spec-notes §coe.pdo says
//! (clear 0x1C1n:00, clear and write the mapping, write the PDOs, write the count)
//! and takes effect: the simulated drive exchanges what was written, and the image follows.

use crate::master_pd_support;
use crate::master_support;

use master_core::bus::BusConfig;
use master_core::master::{MasterConfig, PdoAssignment, PdoEntryInfo, PdoMapping, SlaveAddress};
use master_core::od::standard::{RX_PDO_ASSIGN, TX_PDO_ASSIGN};
use master_core::wire::register::AlState;
use master_pd_support::{Recording, Returned, sdo_downloads};
use master_support::{block_on, rig_with};
use sim::device::coe::lock_dictionary;
use sim::topology::Topology;

fn u32_le(v: u32) -> Vec<u8> {
    v.to_le_bytes().to_vec()
}

#[test]
fn a_configured_assignment_is_written_in_preop_and_takes_effect() {
    let returned = Returned::default();
    let recorder = returned.clone();
    let config = MasterConfig {
        watch_interval: None,
        ..MasterConfig::default()
    };
    let rig = rig_with(
        Topology::default_segment(),
        config,
        BusConfig::default(),
        move |inner| Recording {
            inner,
            returned: recorder,
        },
    );
    let drive = SlaveAddress::Position(0);
    // Outputs: the controlword only; inputs: the statusword only.
    let assignments = vec![
        PdoAssignment {
            sync_manager: 2,
            pdos: vec![PdoMapping {
                index: 0x1600,
                entries: Some(vec![PdoEntryInfo::new(0x6040, 0, 16)]),
            }],
        },
        PdoAssignment {
            sync_manager: 3,
            pdos: vec![PdoMapping {
                index: 0x1A00,
                entries: Some(vec![PdoEntryInfo::new(0x6041, 0, 16)]),
            }],
        },
    ];
    rig.master().set_pdo_assignment(drive, assignments.clone());
    assert_eq!(rig.master().pdo_assignment(drive), Some(assignments));
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);

    // On the wire, in order: the reference sequence for SM2, then for SM3.
    let info = rig.master().slave(drive).unwrap();
    let sm0 = info.mailbox.unwrap().write.start;
    let writes = sdo_downloads(&returned.frames(), info.station, sm0);
    let sequence = |assign: u16, pdo: u16, entry: u32| {
        vec![
            (assign, 0, vec![0]),
            (pdo, 0, vec![0]),
            (pdo, 1, u32_le(entry)),
            (pdo, 0, vec![1]),
            (assign, 1, pdo.to_le_bytes().to_vec()),
            (assign, 0, vec![1]),
        ]
    };
    assert_eq!(
        writes,
        [
            sequence(RX_PDO_ASSIGN, 0x1600, 0x6040_0010),
            sequence(TX_PDO_ASSIGN, 0x1A00, 0x6041_0010),
        ]
        .concat()
    );

    // The drive took it: its dictionary, its process-data sizes, and its state.
    let dict = rig.handles[0].dictionary.clone().unwrap();
    {
        let d = lock_dictionary(&dict);
        assert_eq!(d.assigned_pdos(RX_PDO_ASSIGN), vec![0x1600]);
        assert_eq!(d.mapped_entries(0x1A00).len(), 1);
    }
    let sizes = rig
        .segment()
        .slave(0)
        .unwrap()
        .device()
        .process_data_sizes();
    assert_eq!((sizes.outputs, sizes.inputs), (2, 2));
    assert_eq!(info.al_state, AlState::Op);
    // The image follows: 2 + 2 bytes for the drive, and the next slave right behind.
    assert_eq!(
        (info.process_data.outputs, info.process_data.inputs),
        (2, 2)
    );
    let next = rig.master().slave(SlaveAddress::Position(1)).unwrap();
    assert_eq!(next.process_data.outputs_offset, 4);
    let layout = rig.master().process_data_layout(drive).unwrap();
    assert_eq!(layout.pdos.len(), 2);
    assert_eq!(layout.pdos[1].entries[0].index, 0x6041);

    // The statusword reaches the image through the new mapping.
    let statusword = {
        let d = lock_dictionary(&dict);
        d.get::<u16>(0x6041, 0).unwrap()
    };
    assert!(master_support::wait_until(|| {
        rig.master()
            .read_inputs(drive)
            .is_ok_and(|i| i == statusword.to_le_bytes())
    }));
}

#[test]
fn an_assignment_for_a_slave_without_coe_fails_that_slave_only() {
    let rig = master_support::rig(Topology::default_segment(), MasterConfig::default());
    let do8 = SlaveAddress::Position(1);
    rig.master().set_pdo_assignment(
        do8,
        vec![PdoAssignment {
            sync_manager: 2,
            pdos: Vec::new(),
        }],
    );
    let report = block_on(rig.master().scan()).expect("scan");
    assert_eq!(report.failures.len(), 1, "{:?}", report.failures);
    assert!(matches!(
        report.failures[0],
        master_core::master::MasterError::Mailbox { position: 1, .. }
    ));
    // The others are in OP; DO8 stays in PREOP with no process data.
    for (p, slave) in report.slaves.iter().enumerate() {
        let expected = if p == 1 { AlState::PreOp } else { AlState::Op };
        assert_eq!(slave.al_state, expected, "slave {p}");
    }
}

#[test]
fn a_power_cycled_slave_gets_its_configured_assignment_again() {
    let config = MasterConfig {
        watch_interval: Some(std::time::Duration::from_millis(10)),
        ..MasterConfig::default()
    };
    let rig = master_support::rig(Topology::default_segment(), config);
    let drive = SlaveAddress::Position(0);
    rig.master().set_pdo_assignment(
        drive,
        vec![PdoAssignment {
            sync_manager: 2,
            pdos: vec![PdoMapping {
                index: 0x1600,
                entries: Some(vec![PdoEntryInfo::new(0x6040, 0, 16)]),
            }],
        }],
    );
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let dict = rig.handles[0].dictionary.clone().unwrap();
    // The drive comes back from its power cycle with its own mapping (both entries).
    {
        let mut segment = rig.segment();
        lock_dictionary(&dict)
            .set(0x1600, 1, &0x6040_0010u32)
            .unwrap();
        lock_dictionary(&dict).set(0x1600, 0, &2u8).unwrap();
        segment.power_cycle(0);
    }
    assert_eq!(
        rig.segment()
            .slave(0)
            .unwrap()
            .device()
            .process_data_sizes()
            .outputs,
        6
    );
    // The watch restores it: the configured mapping is written again and OP is reached
    // with the 2-byte SyncManager the image has room for.
    assert!(master_support::wait_until(|| {
        rig.master()
            .slave(drive)
            .is_ok_and(|s| s.present && s.al_state == AlState::Op)
            && rig.segment().esc(0).unwrap().al_state() == AlState::Op
    }));
    assert_eq!(
        lock_dictionary(&dict).mapped_entries(0x1600).len(),
        1,
        "mapping written again"
    );
    assert_eq!(
        rig.segment()
            .slave(0)
            .unwrap()
            .device()
            .process_data_sizes()
            .outputs,
        2
    );
}
