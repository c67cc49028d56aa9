//! Bring-up of the simulated default segment: what the master learns equals what the
//! topology describes, every slave reaches OP, and process data flows.

use crate::master_support;

use master_core::master::{MasterConfig, MasterEvent, SlaveAddress};
use master_core::wire::register::{AlState, AlStatusCode};
use master_core::wire::sii::MailboxProtocols;
use master_support::{block_on, rig, wait_until};
use sim::topology::{Protocol, Topology};

/// The SII protocol bits a topology slave announces.
fn protocol_bits(protocols: &[Protocol]) -> u16 {
    protocols
        .iter()
        .map(|p| match p {
            Protocol::Coe => MailboxProtocols::COE,
            Protocol::Eoe => MailboxProtocols::EOE,
            Protocol::Foe => MailboxProtocols::FOE,
            Protocol::Soe => MailboxProtocols::SOE,
            Protocol::Voe => MailboxProtocols::VOE,
        })
        .fold(0, |a, b| a | b)
}

#[test]
fn the_default_segment_comes_up_as_the_topology_describes_it() {
    let topology = Topology::default_segment();
    let rig = rig(topology.clone(), MasterConfig::default());
    let mut events = rig.master().events();
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    assert_eq!(report.slaves.len(), topology.slaves.len());
    for (p, (info, spec)) in report.slaves.iter().zip(&topology.slaves).enumerate() {
        assert_eq!(usize::from(info.position), p);
        assert_eq!(usize::from(info.station), 1001 + p);
        assert_eq!(info.identity.vendor_id, spec.vendor_id);
        assert_eq!(info.identity.product_code, spec.product_code);
        assert_eq!(info.identity.revision, spec.revision);
        assert_eq!(info.identity.serial, spec.serial);
        assert_eq!(info.name, spec.name);
        assert_eq!(info.alias, spec.alias);
        assert_eq!(info.al_state, AlState::Op, "{}", spec.name);
        assert!(!info.al_error);
        match spec.mailbox {
            Some(m) => {
                let layout = info.mailbox.expect("mailbox");
                // The simulator puts SM0 at 0x1000 and SM1 right behind it.
                assert_eq!(layout.station, info.station);
                assert_eq!((layout.write.start, layout.write.len), (0x1000, m.rx_size));
                assert_eq!(
                    (layout.read.start, layout.read.len),
                    (0x1000 + m.rx_size, m.tx_size)
                );
                assert_eq!(layout.protocols.0, protocol_bits(&spec.protocols));
            }
            None => assert_eq!(info.mailbox, None),
        }
        let cached = rig
            .master()
            .sii_image(SlaveAddress::Position(p as u16))
            .unwrap();
        assert_eq!(
            &rig.segment().esc(p).unwrap().sii()[..cached.len()],
            &cached[..]
        );
        let layout = rig
            .master()
            .process_data_layout(SlaveAddress::Position(p as u16))
            .unwrap();
        assert_eq!(layout.outputs_len(), usize::from(info.process_data.outputs));
        let bits = |rx: bool| -> u32 {
            spec.pdos
                .iter()
                .filter(|pdo| pdo.is_rx() == rx)
                .map(|pdo| pdo.bits())
                .sum()
        };
        assert_eq!(u32::from(info.process_data.outputs), bits(true).div_ceil(8));
        assert_eq!(u32::from(info.process_data.inputs), bits(false).div_ceil(8));
        // Line topology: every slave but the last has two active ports.
        let expected_ports = if p + 1 == topology.slaves.len() { 1 } else { 2 };
        assert_eq!(info.active_ports(), expected_ports, "{}", spec.name);
        // The simulator agrees.
        let segment = rig.segment();
        let esc = segment.esc(p).unwrap();
        assert_eq!(esc.station_address(), info.station);
        assert_eq!(esc.al_state(), AlState::Op);
    }
    assert_eq!(rig.master().mailbox_layouts().len(), 3);
    // Every slave was reported found, and reached OP through the events too.
    let mut found = 0;
    let mut op = 0;
    while let Ok(event) = events.try_recv() {
        match event {
            MasterEvent::SlaveFound { .. } => found += 1,
            MasterEvent::StateChanged {
                to: AlState::Op, ..
            } => op += 1,
            _ => {}
        }
    }
    assert_eq!((found, op), (topology.slaves.len(), topology.slaves.len()));
}

#[test]
fn outputs_written_in_the_image_reach_the_digital_output_slave() {
    let topology = Topology::default_segment();
    let rig = rig(topology.clone(), MasterConfig::default());
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let do8 = topology
        .slaves
        .iter()
        .position(|s| s.name == "ECATD-SIM DO8")
        .unwrap();
    let probe = rig.handles[do8].outputs.clone().expect("output probe");
    let address = SlaveAddress::Position(do8 as u16);
    rig.master()
        .write_outputs(address, 0, &[0b1010_0101])
        .unwrap();
    assert!(
        wait_until(|| probe.image() == vec![0b1010_0101]),
        "outputs never arrived: {:?}",
        probe.image()
    );
    assert!(probe.output(0) && !probe.output(1) && probe.output(7));
    let di8 = topology
        .slaves
        .iter()
        .position(|s| s.name == "ECATD-SIM DI8")
        .unwrap();
    let driver = rig.handles[di8].inputs.clone().expect("input driver");
    driver.set_input(3, true);
    let inputs = SlaveAddress::Station(1001 + di8 as u16);
    // The built-in DI8 is wired to the DO8 (`wired_to`): its inputs show the DO8's outputs,
    // with the driven input 3 on top.
    assert!(wait_until(
        || rig.master().read_inputs(inputs).unwrap() == vec![0b1010_0101 | 0b0000_1000]
    ));
    let stats = rig.master().cycle_stats();
    assert_eq!(stats.last_wkc, stats.expected_wkc);
    // Drive: 2 (outputs) + 1 (inputs), DO8: 2, DI8: 1.
    assert_eq!(stats.expected_wkc, 6);
}

#[test]
fn unknown_addresses_are_refused_by_name() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    block_on(rig.master().scan()).expect("scan");
    let err = block_on(
        rig.master()
            .read_register(SlaveAddress::Position(9), 0x0130, 2),
    )
    .unwrap_err();
    assert_eq!(err.to_string(), "no slave at position 9");
    let err = rig.master().slave(SlaveAddress::Alias(0)).unwrap_err();
    assert!(matches!(
        err,
        master_core::master::MasterError::UnknownSlave(_)
    ));
    // A register read goes to the right slave: its station address register.
    let read = block_on(
        rig.master()
            .read_register(SlaveAddress::Position(2), 0x0010, 2),
    )
    .unwrap();
    assert_eq!(read, 1003u16.to_le_bytes());
}

#[test]
fn a_slave_with_a_bad_mailbox_is_reported_by_code_and_name_and_the_others_reach_op() {
    let mut topology = Topology::default_segment();
    let broken = 3;
    let spec = &mut topology.slaves[broken];
    // The SII announces a mailbox beyond the ESC's RAM: the ESC refuses it.
    let ram_end = 0x1000 + spec.esc.ram_kib * 1024;
    spec.mailbox.as_mut().unwrap().start = Some(ram_end);
    let rig = rig(topology.clone(), MasterConfig::default());
    let mut events = rig.master().events();
    let report = block_on(rig.master().scan()).expect("scan");
    assert_eq!(report.failures.len(), 1, "{:?}", report.failures);
    let failure = &report.failures[0];
    assert_eq!(
        failure.al_status_code(),
        Some(AlStatusCode::InvalidMailboxConfigPreop)
    );
    let text = failure.to_string();
    assert!(
        text.contains("0x0016 Invalid mailbox configuration (PREOP)"),
        "{text}"
    );
    assert!(text.contains(&topology.slaves[broken].name), "{text}");
    for info in &report.slaves {
        if usize::from(info.position) == broken {
            assert_eq!(info.al_state, AlState::Init);
            assert_eq!(info.al_status_code, AlStatusCode::InvalidMailboxConfigPreop);
        } else {
            assert_eq!(info.al_state, AlState::Op, "{}", info.name);
        }
    }
    let event =
        master_support::next_event(&mut events, |e| matches!(e, MasterEvent::AlError { .. }));
    assert_eq!(
        event,
        Some(MasterEvent::AlError {
            position: broken as u16,
            station: 1001 + broken as u16,
            name: topology.slaves[broken].name.clone(),
            state: AlState::Init,
            code: AlStatusCode::InvalidMailboxConfigPreop,
        })
    );
}

#[test]
fn the_sii_read_through_the_master_is_the_simulator_s() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    block_on(rig.master().scan()).expect("scan");
    for position in 0..5u16 {
        let read = block_on(rig.master().read_sii(SlaveAddress::Position(position))).unwrap();
        let segment = rig.segment();
        let image = segment.esc(usize::from(position)).unwrap().sii();
        // Read up to and including the END marker: the simulator's image up to there.
        assert!(read.len() > 128, "more than the fixed area");
        assert_eq!(&image[..read.len()], &read[..], "slave {position}");
        assert_eq!(&read[read.len() - 2..], &[0xFF, 0xFF], "ends with END");
    }
}

#[test]
fn a_slave_goes_to_boot_with_the_bootstrap_mailbox_and_back_to_op() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    block_on(rig.master().scan()).expect("scan");
    let drive = SlaveAddress::Position(0);
    block_on(rig.master().request_state(drive, AlState::Boot)).expect("BOOT");
    assert_eq!(rig.segment().esc(0).unwrap().al_state(), AlState::Boot);
    let info = rig.master().slave(drive).unwrap();
    assert_eq!(info.al_state, AlState::Boot);
    assert_eq!(info.requested_state, AlState::Boot);
    // SM0/SM1 hold the bootstrap mailbox the SII announces.
    let boot = info.boot_mailbox.expect("bootstrap mailbox");
    let sm0 = block_on(rig.master().read_register(drive, 0x0800, 4)).unwrap();
    assert_eq!(sm0[..2], boot.write.start.to_le_bytes());
    assert_eq!(sm0[2..], boot.write.len.to_le_bytes());
    block_on(rig.master().request_state(drive, AlState::Op)).expect("back to OP");
    assert_eq!(rig.segment().esc(0).unwrap().al_state(), AlState::Op);
    // The cyclic exchange serves the drive again.
    assert!(wait_until(|| {
        let stats = rig.master().cycle_stats();
        stats.last_wkc == stats.expected_wkc
    }));
}

#[test]
fn a_second_scan_starts_over_and_ends_in_the_same_place() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    let first = block_on(rig.master().scan()).expect("first scan");
    // A tokio runtime of the caller's works as well as no runtime at all.
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .build()
        .unwrap();
    let second = runtime.block_on(rig.master().scan()).expect("second scan");
    assert!(second.failures.is_empty(), "{:?}", second.failures);
    assert_eq!(first.slaves, second.slaves);
    let stats = rig.master().cycle_stats();
    assert!(wait_until(|| {
        let now = rig.master().cycle_stats();
        now.completed > stats.completed && now.last_wkc == now.expected_wkc
    }));
}

/// A rig of the default segment's slaves at `picked`, on ESCs that return 8 bytes per
/// EEPROM read or 4 (`eight`), with its topology.
fn eeprom_rig(
    picked: &[usize],
    eight: bool,
    config: MasterConfig,
) -> (master_support::Rig<sim::link::InProcessLink>, Topology) {
    use sim::device::SlaveDevice;
    use sim::esc::{Esc, EscConfig, ManualTime};
    use sim::segment::Segment;
    let default = Topology::default_segment();
    let built = sim::topology::build(&default).unwrap();
    let time = ManualTime::new(0);
    let mut segment = Segment::new(Box::new(time.clone()));
    for &p in picked {
        let esc = EscConfig {
            eeprom_read_8_bytes: eight,
            ..EscConfig::default()
        };
        let sii = built.esc(p).unwrap().sii().to_vec();
        segment.push(Esc::new(esc, sii), Box::new(SlaveDevice::new()));
    }
    let topology = Topology {
        ring: false,
        slaves: picked.iter().map(|&p| default.slaves[p].clone()).collect(),
    };
    let rig = master_support::rig_on(segment, time, topology.clone(), config);
    (rig, topology)
}

#[test]
fn slaves_that_return_four_bytes_per_eeprom_read_are_read_whole() {
    // The CoE store and the EoE port (no process data) on ESCs with 4-byte EEPROM reads.
    let (rig, topology) = eeprom_rig(&[3, 4], false, MasterConfig::default());
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    for (info, spec) in report.slaves.iter().zip(&topology.slaves) {
        assert_eq!(info.name, spec.name);
        assert_eq!(info.identity.serial, spec.serial);
        assert_eq!(info.al_state, AlState::Op);
        let address = SlaveAddress::Position(info.position);
        let control = block_on(rig.master().read_register(address, 0x0502, 2)).unwrap();
        assert_eq!(control[0] & 0x40, 0, "the ESC reports 4-byte reads");
        let read = block_on(rig.master().read_sii(address)).unwrap();
        let segment = rig.segment();
        let image = segment.esc(usize::from(info.position)).unwrap().sii();
        assert_eq!(&image[..read.len()], &read[..]);
    }
}

#[test]
fn an_eeprom_read_is_a_command_and_one_read_of_status_and_data() {
    use master_core::mailbox::MailboxConfig;
    let every: Vec<usize> = (0..Topology::default_segment().slaves.len()).collect();
    for eight in [true, false] {
        // In INIT, with no watch and no idle mailbox reads: every datagram counted is one
        // the SII read sent.
        let config = MasterConfig {
            target_state: AlState::Init,
            watch_interval: None,
            mailbox: MailboxConfig {
                idle_poll: None,
                ..MailboxConfig::default()
            },
            ..MasterConfig::default()
        };
        let (rig, _) = eeprom_rig(&every, eight, config);
        let report = block_on(rig.master().scan()).expect("scan");
        assert!(report.failures.is_empty(), "{:?}", report.failures);
        let chunk = if eight { 8 } else { 4 };
        for info in &report.slaves {
            let address = SlaveAddress::Position(info.position);
            let before = rig.master().bus_stats().datagrams_sent;
            let read = block_on(rig.master().read_sii(address)).unwrap();
            let sent = rig.master().bus_stats().datagrams_sent - before;
            let image = rig
                .segment()
                .esc(usize::from(info.position))
                .unwrap()
                .sii()
                .to_vec();
            assert_eq!(&image[..read.len()], &read[..]);
            // Two owner writes and one check of the idle interface, then two datagrams per
            // read command: the command, and status with data in one read. The image ends
            // after its END marker, and the read that found it may have gone one chunk
            // further.
            let reads = read.len().div_ceil(chunk) as u64;
            assert!(
                (3 + 2 * reads..=3 + 2 * (reads + 1)).contains(&sent),
                "position {}, {chunk}-byte reads: {sent} datagrams for {} bytes",
                info.position,
                read.len()
            );
        }
    }
}

#[test]
fn a_slave_with_a_malformed_sii_is_reported_and_the_others_come_up() {
    use master_core::master::MasterError;
    use sim::device::SlaveDevice;
    use sim::esc::{Esc, EscConfig, ManualTime};
    use sim::segment::Segment;
    let default = Topology::default_segment();
    let built = sim::topology::build(&default).unwrap();
    let picked = [3usize, 4];
    let time = ManualTime::new(0);
    let mut segment = Segment::new(Box::new(time.clone()));
    for (i, &p) in picked.iter().enumerate() {
        let mut sii = built.esc(p).unwrap().sii().to_vec();
        if i == 0 {
            // The first category (word 0x40) claims more words than the EEPROM holds.
            sii[0x82..0x84].copy_from_slice(&0x7FFFu16.to_le_bytes());
        }
        segment.push(
            Esc::new(EscConfig::default(), sii),
            Box::new(SlaveDevice::new()),
        );
    }
    let topology = Topology {
        ring: false,
        slaves: picked.iter().map(|&p| default.slaves[p].clone()).collect(),
    };
    let rig = master_support::rig_on(segment, time, topology.clone(), MasterConfig::default());
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(
        matches!(
            report.failures.as_slice(),
            [MasterError::Malformed {
                position: 0,
                what: "SII",
                ..
            }]
        ),
        "{:?}",
        report.failures
    );
    assert!(!report.slaves[0].present);
    assert_eq!(report.slaves[1].name, topology.slaves[1].name);
    assert_eq!(report.slaves[1].al_state, AlState::Op);
    assert_eq!(rig.segment().esc(0).unwrap().al_state(), AlState::Init);
}
