//! ecatd's own master against `ecat-sim` over a veth pair: the simulator in one network
//! namespace, the master's raw socket in another. Every expectation comes from the
//! simulator's topology (`Topology::default_segment`).
//!
//! Needs root (namespaces, raw sockets) and `ip`; see tests/README.md.

use ecat_tests::rig::{Rig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use ecat_tests::veth_master::VethMaster;
use master_core::master::MasterConfig;
use master_core::wire::register::{AlState, AlStatusCode};
use sim::topology::Topology;

#[test]
fn the_default_segment_comes_up_over_veth_as_the_topology_describes_it() {
    let topology = Topology::default_segment();
    let rig = Rig::new();
    let _sim = SimProcess::start(&rig.sim, SIM_IFACE, &[]);
    let master = VethMaster::start(&rig, MasterConfig::default());
    let report = master.scan();
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    assert_eq!(report.slaves.len(), topology.slaves.len());
    for (p, (info, spec)) in report.slaves.iter().zip(&topology.slaves).enumerate() {
        assert_eq!(usize::from(info.station), 1001 + p);
        assert_eq!(info.identity.vendor_id, spec.vendor_id, "{}", spec.name);
        assert_eq!(
            info.identity.product_code, spec.product_code,
            "{}",
            spec.name
        );
        assert_eq!(info.identity.revision, spec.revision, "{}", spec.name);
        assert_eq!(info.identity.serial, spec.serial, "{}", spec.name);
        assert_eq!(info.name, spec.name);
        assert_eq!(info.al_state, AlState::Op, "{}", spec.name);
        assert_eq!(
            info.mailbox.is_some(),
            spec.mailbox.is_some(),
            "{}",
            spec.name
        );
    }
}

#[test]
fn a_broken_slave_over_veth_is_reported_by_code_and_name() {
    let mut topology = Topology::default_segment();
    let broken = 3;
    let spec = &mut topology.slaves[broken];
    // The SII announces a mailbox beyond the ESC's RAM: the ESC refuses PREOP.
    let ram_end = 0x1000 + spec.esc.ram_kib * 1024;
    spec.mailbox.as_mut().expect("a mailbox slave").start = Some(ram_end);
    let file = std::env::temp_dir().join(format!("ecatd-broken-{}.toml", std::process::id()));
    std::fs::write(&file, topology.to_toml().expect("toml")).expect("write topology");
    let rig = Rig::new();
    let sim = SimProcess::start(
        &rig.sim,
        SIM_IFACE,
        &["--topology", file.to_str().expect("utf-8 path")],
    );
    let _ = std::fs::remove_file(&file);
    let master = VethMaster::start(&rig, MasterConfig::default());
    let report = master.scan();
    drop(sim);
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
        let expected = if usize::from(info.position) == broken {
            AlState::Init
        } else {
            AlState::Op
        };
        assert_eq!(info.al_state, expected, "{}", info.name);
    }
}
