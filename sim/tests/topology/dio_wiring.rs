//! Digital outputs wired back to digital inputs (`wired_to`), as on a test bench: the
//! built-in segment's DI8 reads its DO8's outputs through the ESCs' process data, a
//! topology without the wire keeps the DI8 free, and a wire to nowhere is refused.

use crate::segment_support;

use ecat_wire::command::Command;
use ecat_wire::register::fmmu::{Fmmu, FmmuRepr};
use segment_support::*;
use sim::topology::{Application, SlaveHandles, Topology, build, build_with_handles};

/// Positions in the built-in segment.
const DO8: usize = 1;
const DI8: usize = 2;
/// Where the bench maps the output byte and the input byte.
const OUTPUTS_AT: u32 = 0x100;
const INPUTS_AT: u32 = 0x101;

fn fmmu(f: FmmuRepr) -> Vec<u8> {
    let mut bytes = vec![0u8; 16];
    f.emit(&mut Fmmu::new_unchecked(&mut bytes[..])).unwrap();
    bytes
}

/// Builds `topology` and brings its one-byte output slave at `outputs` and one-byte input
/// slave at `inputs` to OP as a master would: SM0 (their process-data SM at 0x1000, as
/// their SII says), FMMU 0 at [`OUTPUTS_AT`] / [`INPUTS_AT`], valid outputs before OP.
fn in_op(topology: &Topology, outputs: usize, inputs: usize) -> (Bench, Vec<SlaveHandles>) {
    let built = build_with_handles(topology).unwrap();
    let mut bench = Bench {
        segment: built.segment,
        time: built.time,
        devices: Vec::new(),
    };
    bench.assign_addresses();
    let terminals = [
        (outputs, 0x64, FmmuRepr::outputs(OUTPUTS_AT, 1, 0x1000)),
        (inputs, 0x20, FmmuRepr::inputs(INPUTS_AT, 1, 0x1000)),
    ];
    for (position, control, mapping) in terminals {
        let s = station(position);
        assert_eq!(bench.request(s, 0x0002), (0x0002, 0), "slave {position}");
        let sm0 = [0x00, 0x10, 0x01, 0x00, control, 0x00, 0x01, 0x00];
        assert_eq!(bench.one(fp(Command::Fpwr, s, 0x0800, &sm0)).wkc, 1);
        assert_eq!(
            bench.one(fp(Command::Fpwr, s, 0x0600, &fmmu(mapping))).wkc,
            1
        );
        assert_eq!(bench.request(s, 0x0004), (0x0004, 0), "slave {position}");
    }
    exchange(&mut bench, 0);
    for position in [outputs, inputs] {
        assert_eq!(bench.request(station(position), 0x0008), (0x0008, 0));
    }
    (bench, built.slaves)
}

/// One LRW writing `outputs` and reading the inputs in the same frame: the inputs.
fn exchange(bench: &mut Bench, outputs: u8) -> u8 {
    let back = bench.one(l(Command::Lrw, OUTPUTS_AT, &[outputs, 0]));
    assert_eq!(back.wkc, 3, "DO written (2) and DI read (1)");
    assert_eq!(back.data[0], outputs);
    back.data[1]
}

fn unwired(mut topology: Topology) -> Topology {
    topology.slaves[DI8].application = Application::DigitalInputs {
        channels: 8,
        wired_to: None,
    };
    topology
}

#[test]
fn the_built_in_di8_reads_the_do8_s_outputs_in_the_same_frame() {
    let topology = Topology::default_segment();
    assert_eq!(
        topology.slaves[DI8].application,
        Application::DigitalInputs {
            channels: 8,
            wired_to: Some(DO8 as u16)
        }
    );
    let (mut bench, handles) = in_op(&topology, DO8, DI8);
    assert_eq!(exchange(&mut bench, 0b1010_0101), 0b1010_0101);
    let probe = handles[DO8].outputs.clone().unwrap();
    let driver = handles[DI8].inputs.clone().unwrap();
    assert_eq!(probe.image(), [0b1010_0101]);
    assert!(driver.is_wired() && driver.input(0) && !driver.input(1));
    assert_eq!(exchange(&mut bench, 0x00), 0x00, "and off again");
    // Written by an LWR, read by a later LRD: the same.
    assert_eq!(bench.one(l(Command::Lwr, OUTPUTS_AT, &[0x3C])).wkc, 1);
    assert_eq!(bench.one(l(Command::Lrd, INPUTS_AT, &[0])).data, [0x3C]);
    // The driver turns inputs on beside the wire; it cannot turn off a wired one.
    driver.set_input(3, true);
    driver.set_input(0, false);
    assert_eq!(exchange(&mut bench, 0x01), 0b0000_1001);
    driver.set_input(3, false);
    assert_eq!(exchange(&mut bench, 0x00), 0x00);
}

/// The default process-data watchdog: 1000 ticks of 100 µs.
const WATCHDOG_NS: u64 = 100_000_000;
/// More than a frame takes from the master to the DO8 (the watchdog restarts at arrival).
const PAST: u64 = 10_000;

#[test]
fn a_do8_behind_a_cut_cable_switches_its_outputs_off_when_its_watchdog_runs_out() {
    let (mut bench, handles) = in_op(&Topology::default_segment(), DO8, DI8);
    let probe = handles[DO8].outputs.clone().unwrap();
    exchange(&mut bench, 0b1100_0011);
    assert_eq!(probe.image(), [0b1100_0011]);
    // The cable into the DO8 is cut: frames still reach the coupler in front of it.
    bench.segment.set_plugged(DO8, false);
    bench.time.advance(WATCHDOG_NS);
    bench.one(b(Command::Brd, 0x0130, &[0, 0]));
    assert_eq!(
        probe.image(),
        [0b1100_0011],
        "exactly the watchdog time: still on"
    );
    bench.time.advance(PAST);
    let back = bench.one(b(Command::Brd, 0x0130, &[0, 0]));
    assert_eq!(back.wkc, 1, "only the coupler answers");
    assert_eq!(
        probe.image(),
        [0],
        "the safe state, with no frame reaching the DO8"
    );
    bench.segment.set_plugged(DO8, true);
    let s = station(DO8);
    assert_eq!(
        bench.one(fp(Command::Fprd, s, 0x0130, &[0, 0])).data,
        [0x14, 0]
    );
    assert_eq!(
        bench.one(fp(Command::Fprd, s, 0x0134, &[0, 0])).data,
        [0x1B, 0]
    );
    assert_eq!(bench.one(fp(Command::Fprd, s, 0x0442, &[0])).data, [1]);
}

#[test]
fn a_silent_wire_lets_every_watchdog_run_out() {
    let (mut bench, handles) = in_op(&Topology::default_segment(), DO8, DI8);
    let probe = handles[DO8].outputs.clone().unwrap();
    exchange(&mut bench, 0xFF);
    bench.time.advance(WATCHDOG_NS);
    bench.segment.idle();
    assert_eq!(probe.image(), [0xFF]);
    bench.time.advance(PAST);
    bench.segment.idle();
    assert_eq!(probe.image(), [0], "off without any frame");
    let s = station(DO8);
    assert_eq!(
        bench.one(fp(Command::Fprd, s, 0x0130, &[0, 0])).data,
        [0x14, 0]
    );
    // Outputs written in SAFEOP are not driven; back in OP they are.
    exchange(&mut bench, 0x0F);
    assert_eq!(probe.image(), [0]);
    assert_eq!(
        bench.request(s, 0x0018),
        (0x0008, 0),
        "acknowledged into OP"
    );
    assert_eq!(probe.image(), [0x0F]);
}

#[test]
fn without_the_wire_the_di8_is_independent_of_the_do8() {
    let topology = unwired(Topology::default_segment());
    let (mut bench, handles) = in_op(&topology, DO8, DI8);
    assert_eq!(exchange(&mut bench, 0xFF), 0x00);
    assert_eq!(handles[DO8].outputs.as_ref().unwrap().image(), [0xFF]);
    let driver = handles[DI8].inputs.clone().unwrap();
    assert!(!driver.is_wired());
    driver.set_input(2, true);
    assert_eq!(exchange(&mut bench, 0xFF), 0b0000_0100);
    driver.set_input(2, false);
    assert_eq!(exchange(&mut bench, 0xFF), 0x00);
}

#[test]
fn outputs_behind_the_inputs_in_the_line_arrive_one_frame_later() {
    // The DI8 first, wired to the DO8 behind it: the frame reads the inputs before it
    // brings the outputs.
    let default = Topology::default_segment();
    let mut inputs = default.slaves[DI8].clone();
    inputs.application = Application::DigitalInputs {
        channels: 8,
        wired_to: Some(1),
    };
    let topology = Topology {
        ring: false,
        slaves: vec![inputs, default.slaves[DO8].clone()],
    };
    let (mut bench, _) = in_op(&topology, 1, 0);
    assert_eq!(exchange(&mut bench, 0x81), 0x00);
    assert_eq!(exchange(&mut bench, 0x00), 0x81);
    assert_eq!(exchange(&mut bench, 0x00), 0x00);
}

#[test]
fn the_wire_is_written_in_the_topology_file() {
    let text = r#"
        [[slave]]
        name = "DO"
        vendor_id = 2
        product_code = 1
        application = { kind = "digital_outputs", channels = 16 }

        [[slave]]
        name = "DI"
        vendor_id = 2
        product_code = 2
        application = { kind = "digital_inputs", channels = 8, wired_to = 0 }

        [[slave]]
        name = "DI free"
        vendor_id = 2
        product_code = 3
        application = { kind = "digital_inputs", channels = 8 }
    "#;
    let topology = Topology::from_toml(text).unwrap();
    assert_eq!(
        topology.slaves[1].application,
        Application::DigitalInputs {
            channels: 8,
            wired_to: Some(0)
        }
    );
    assert_eq!(
        topology.slaves[2].application,
        Application::DigitalInputs {
            channels: 8,
            wired_to: None
        }
    );
    let written = topology.to_toml().unwrap();
    assert_eq!(written.matches("wired_to = 0").count(), 1, "{written}");
    assert_eq!(Topology::from_toml(&written).unwrap(), topology);
    build(&topology).expect("16 outputs cover 8 inputs");
    let misspelt = text.replace("wired_to = 0", "wired = 0");
    assert!(
        Topology::from_toml(&misspelt).is_err(),
        "unknown fields are refused"
    );
}

#[test]
fn a_wire_to_anything_but_enough_digital_outputs_is_refused_by_name() {
    let refused = |wired_to: u16, channels: u16| {
        let mut topology = Topology::default_segment();
        topology.slaves[DI8].application = Application::DigitalInputs {
            channels,
            wired_to: Some(wired_to),
        };
        build(&topology).unwrap_err().to_string()
    };
    assert_eq!(
        refused(9, 8),
        "slave 2 (ECATD-SIM DI8): wired_to = 9: no slave at position 9 (the topology has 5)"
    );
    assert_eq!(
        refused(0, 8),
        "slave 2 (ECATD-SIM DI8): wired_to = 0: slave 0 (ECATD-SIM Drive) has no digital outputs"
    );
    assert_eq!(
        refused(2, 8),
        "slave 2 (ECATD-SIM DI8): wired_to = 2: slave 2 (ECATD-SIM DI8) has no digital outputs",
        "not to itself"
    );
    assert_eq!(
        refused(1, 16),
        "slave 2 (ECATD-SIM DI8): wired_to = 1: slave 1 (ECATD-SIM DO8) has 8 digital outputs, \
         16 inputs need as many"
    );
}

#[test]
fn each_repetition_s_di8_is_wired_to_its_own_do8() {
    let topology = Topology::repeated(13);
    let wires: Vec<_> = topology
        .slaves
        .iter()
        .filter_map(|s| match s.application {
            Application::DigitalInputs { wired_to, .. } => Some(wired_to),
            _ => None,
        })
        .collect();
    assert_eq!(wires, [Some(1), Some(6), Some(11)]);
    let (mut bench, _) = in_op(&topology, 6, 7);
    assert_eq!(exchange(&mut bench, 0x42), 0x42);
}
