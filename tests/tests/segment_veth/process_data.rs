//! The process-data acceptance checks of issue 6 against `ecat-sim` over veth (the
//! in-process versions are master-core's `master_pd_*` and `master_dc` tests): the output
//! terminal follows the API, the input terminal's inputs appear, the drive's PDO mapping
//! read through CoE is the topology's, a configured PDO assignment is written and taken,
//! an emergency is noticed through the mailbox-status bit instead of polling, the DC
//! delays are the simulated hops, and a silent wire leaves the outputs in their safe state.
//! Expected values come from `Topology::default_segment`.
//!
//! The simulator runs with `--control`: it reports its digital outputs and takes input
//! and emergency commands on its standard streams. Needs root; see tests/README.md.

use crate::master_pd_support;

use std::time::{Duration, Instant};

use ecat_tests::rig::{Rig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use ecat_tests::veth_master::{VethMaster, open_socket};
use master_core::bus::BusConfig;
use master_core::master::{MasterConfig, PdoAssignment, PdoEntryInfo, PdoMapping, SlaveAddress};
use master_core::od::standard::{RX_PDO_ASSIGN, TX_PDO_ASSIGN};
use master_core::wire::command::{Command, DatagramAddress};
use master_core::wire::register::AlState;
use master_core::wire::register::address as reg;
use master_pd_support::{Recording, Returned, count_node, datagrams, sdo_downloads};
use sim::topology::Topology;

/// How long anything may take before the test fails.
const PATIENCE: Duration = Duration::from_secs(20);
/// Positions in the default segment.
const DRIVE: u16 = 0;
const DO8: u16 = 1;
const DI8: u16 = 2;
const STORE: u16 = 3;
/// Logical address of the mailbox-status bits (0x40000 as in spec-notes §capture).
const STATUS_BASE: u32 = 0x0004_0000;

fn config() -> MasterConfig {
    MasterConfig {
        watch_interval: None,
        ..MasterConfig::default()
    }
}

/// A master over veth whose link keeps every returned frame.
fn recorded(rig: &Rig) -> (VethMaster, Returned) {
    let returned = Returned::default();
    let link = Recording {
        inner: open_socket(rig),
        returned: returned.clone(),
    };
    let master = VethMaster::on_link(Box::new(link), BusConfig::default(), config());
    (master, returned)
}

fn scanned(master: &VethMaster) {
    let report = master.scan();
    assert!(report.failures.is_empty(), "{:?}", report.failures);
}

/// Polls `condition` until it holds or `PATIENCE` runs out.
fn wait_until(mut condition: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + PATIENCE;
    while Instant::now() < deadline {
        if condition() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    condition()
}

/// Lets `cycles` more cycles complete.
fn run_cycles(master: &VethMaster, cycles: u64) {
    let start = master.master().cycle_stats().completed;
    assert!(wait_until(
        || master.master().cycle_stats().completed >= start + cycles
    ));
}

#[test]
fn the_output_terminal_follows_the_api_and_the_input_terminal_s_inputs_appear() {
    let rig = Rig::new();
    let mut sim = SimProcess::start_controlled(&rig.sim, SIM_IFACE, &[]);
    let master = VethMaster::start(&rig, config());
    scanned(&master);
    let m = master.master();
    let do8 = SlaveAddress::Position(DO8);
    let ch3 = m.entry(do8, 0x7000, 3).expect("DO8 channel 3");
    let ch8 = m.entry(do8, 0x7000, 8).expect("DO8 channel 8");
    m.write_entries(&[(&ch3, &[1]), (&ch8, &[1])])
        .expect("write");
    // Channel n is bit n-1: channels 3 and 8 are 0x84 on the terminal's pins.
    let line = format!("ecat-sim: outputs {DO8} 84");
    assert!(
        sim.wait_line(PATIENCE, |l| l == line).is_some(),
        "the simulator never reported DO8 = 0x84"
    );
    m.write_entry(&ch3, &[0]).unwrap();
    let line = format!("ecat-sim: outputs {DO8} 80");
    assert!(sim.wait_line(PATIENCE, |l| l == line).is_some());

    let di8 = SlaveAddress::Position(DI8);
    let entries = m.entries(di8).expect("DI8 entries");
    assert_eq!(entries.len(), 8);
    let on = || -> Vec<bool> {
        entries
            .iter()
            .map(|e| m.read_entry(e).expect("read") == [1])
            .collect()
    };
    // The built-in DI8 is wired to the DO8 (`wired_to`): output 8, still on, is input 8,
    // and the simulator's input commands add inputs beside the wire.
    let wired: Vec<bool> = (0..8).map(|c| c == 7).collect();
    assert!(wait_until(|| on() == wired), "inputs {:?}", on());
    sim.command(&format!("input {DI8} 1 1"));
    sim.command(&format!("input {DI8} 6 1"));
    let expected: Vec<bool> = (0..8).map(|c| c == 1 || c == 6 || c == 7).collect();
    assert!(wait_until(|| on() == expected), "inputs {:?}", on());
    let snapshot = m.snapshot();
    assert_eq!(snapshot.wkc, snapshot.expected_wkc);

    // The master stops without a word (a crash, a cut cable): no frame reaches the DO8
    // any more, its SyncManager watchdog runs out anyway and the outputs go to their safe
    // state, as a real terminal's do.
    drop(master);
    let line = format!("ecat-sim: outputs {DO8} 00");
    assert!(
        sim.wait_line(PATIENCE, |l| l == line).is_some(),
        "the DO8 kept its outputs on a silent wire"
    );
}

#[test]
fn the_drive_s_pdo_mapping_read_through_coe_is_the_topology_s() {
    let topology = Topology::default_segment();
    let rig = Rig::new();
    let _sim = SimProcess::start(&rig.sim, SIM_IFACE, &[]);
    let master = VethMaster::start(&rig, config());
    scanned(&master);
    let drive = SlaveAddress::Position(DRIVE);
    let layout = master.master().process_data_layout(drive).expect("layout");
    let spec = &topology.slaves[usize::from(DRIVE)].pdos;
    let read: Vec<_> = layout
        .pdos
        .iter()
        .map(|p| {
            let entries: Vec<_> = p
                .entries
                .iter()
                .map(|e| (e.index, e.subindex, e.bit_length))
                .collect();
            (p.index, entries)
        })
        .collect();
    let expected: Vec<_> = spec
        .iter()
        .map(|p| {
            let entries: Vec<_> = p
                .entries
                .iter()
                .map(|e| (e.index, e.subindex, e.bits))
                .collect();
            (p.index, entries)
        })
        .collect();
    assert_eq!(read, expected);
    // And the drive's own dictionary says the same, asked through the mailbox.
    let mailbox = master.master().mailbox(drive).expect("mailbox");
    let first = &spec[0];
    let count = master
        .within(PATIENCE, mailbox.sdo_upload(first.index, 0))
        .expect("upload");
    assert_eq!(usize::from(count[0]), first.entries.len());
    let entry = master
        .within(PATIENCE, mailbox.sdo_upload(first.index, 1))
        .expect("upload");
    let e = &first.entries[0];
    let packed = u32::from(e.index) << 16 | u32::from(e.subindex) << 8 | u32::from(e.bits);
    assert_eq!(entry, packed.to_le_bytes());
}

#[test]
fn a_configured_pdo_assignment_is_written_and_takes_effect() {
    let rig = Rig::new();
    let _sim = SimProcess::start(&rig.sim, SIM_IFACE, &[]);
    let (master, returned) = recorded(&rig);
    let drive = SlaveAddress::Position(DRIVE);
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
    master.master().set_pdo_assignment(drive, assignments);
    scanned(&master);
    let info = master.master().slave(drive).unwrap();
    let sm0 = info.mailbox.unwrap().write.start;
    let writes = sdo_downloads(&returned.frames(), info.station, sm0);
    let sequence = |assign: u16, pdo: u16, entry: u32| {
        vec![
            (assign, 0, vec![0]),
            (pdo, 0, vec![0]),
            (pdo, 1, entry.to_le_bytes().to_vec()),
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
    // The drive took it: it is in OP with 2 + 2 bytes, and its statusword, asked through
    // the mailbox, is what the cycle brings in.
    assert_eq!(info.al_state, AlState::Op);
    assert_eq!(
        (info.process_data.outputs, info.process_data.inputs),
        (2, 2)
    );
    let mailbox = master.master().mailbox(drive).unwrap();
    let statusword = master
        .within(PATIENCE, mailbox.sdo_upload(0x6041, 0))
        .expect("statusword");
    assert!(wait_until(|| master
        .master()
        .read_inputs(drive)
        .is_ok_and(|i| i == statusword)));
}

#[test]
fn an_emergency_is_noticed_through_the_status_bit_not_by_polling() {
    let rig = Rig::new();
    let mut sim = SimProcess::start_controlled(&rig.sim, SIM_IFACE, &[]);
    let (master, returned) = recorded(&rig);
    scanned(&master);
    let m = master.master();
    // Drive, CoE store and EoE port have mailboxes: three bits mapped.
    assert_eq!(m.cycle_stats().mailbox_status_slaves, 3);
    let store = m.slave(SlaveAddress::Position(STORE)).unwrap();
    let sm1 = store.mailbox.unwrap().read.start;
    let mut emergencies = m
        .mailbox(SlaveAddress::Position(STORE))
        .unwrap()
        .subscribe_emergencies();

    run_cycles(&master, 2);
    returned.clear();
    run_cycles(&master, 50);
    let quiet = returned.frames();
    assert_eq!(
        count_node(&quiet, Command::Fprd, store.station, sm1),
        0,
        "idle mailboxes are not polled"
    );
    let status_reads = datagrams(&quiet)
        .into_iter()
        .filter(|(c, a, data, wkc)| {
            *c == Command::Lrd
                && *a == Some(DatagramAddress::Logical(STATUS_BASE))
                && *wkc == 3
                && data == &[0]
        })
        .count();
    assert!(status_reads >= 50, "{status_reads} status reads");

    returned.clear();
    sim.command(&format!("emergency {STORE} 8110"));
    let mut got = None;
    assert!(wait_until(|| {
        got = emergencies.try_recv().ok();
        got.is_some()
    }));
    assert_eq!(got.unwrap().error_code, 0x8110);
    let frames = returned.frames();
    let bit = 1u8 << STORE;
    // Cyclic frames that came back with the store's "mailbox full" bit set: each is one
    // notice to the mailbox owner. Until the owner's read of SM1 has passed the slave, every
    // cycle still sees the bit, so a loaded machine gives several.
    let notices = datagrams(&frames)
        .iter()
        .filter(|(c, a, data, _)| {
            *c == Command::Lrd
                && *a == Some(DatagramAddress::Logical(STATUS_BASE))
                && data.first().is_some_and(|b| b & bit != 0)
        })
        .count();
    assert!(
        notices >= 1,
        "the cyclic frame saw the store's mailbox full"
    );
    // With idle polling off, the owner polls SM1 only for a notice (which wakes it, or is
    // kept for it while it polls: one at most) and once more after a poll that found a
    // message (the slave may have another). A poll reads until SM1 is empty: with one
    // message waiting, two reads. So at most two reads per notice and two after the
    // emergency.
    let reads = count_node(&frames, Command::Fprd, store.station, sm1);
    assert!(
        (1..=2 * (notices + 1)).contains(&reads),
        "{reads} reads of SM1 for {notices} notices: two polls of two reads at most for one"
    );
}

#[test]
fn dc_delays_are_the_simulated_hops_and_the_clocks_agree() {
    let topology = Topology::default_segment();
    let rig = Rig::new();
    let _sim = SimProcess::start(&rig.sim, SIM_IFACE, &[]);
    let master = VethMaster::start(&rig, config());
    scanned(&master);
    let dc = master.master().dc_slaves();
    assert_eq!(
        dc.len(),
        topology.slaves.len(),
        "every simulated ESC has DC"
    );
    let mut expected = 0;
    for (p, slave) in dc.iter().enumerate() {
        if p > 0 {
            expected += topology.slaves[p].esc.hop_delay_ns;
        }
        assert_eq!(slave.delay_ns, expected, "slave {p}");
    }
    // The slaves' own difference to the distributed reference time (0x092C: magnitude
    // and sign bit) after some cycles: the simulated clocks do not drift, so only the
    // offsets' accuracy shows.
    run_cycles(&master, 20);
    for p in 1..dc.len() {
        let raw = master
            .within(
                PATIENCE,
                master.master().read_register(
                    SlaveAddress::Position(p as u16),
                    reg::DC_SYSTEM_TIME_DIFFERENCE,
                    4,
                ),
            )
            .expect("0x092C");
        let raw = u32::from_le_bytes(raw.try_into().expect("4 bytes"));
        let magnitude = raw & 0x7FFF_FFFF;
        assert!(magnitude <= 1_000, "0x092C of slave {p}: {magnitude} ns");
    }
}
