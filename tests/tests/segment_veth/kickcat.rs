//! The KickCAT master accepts the simulator: `ecat-sim` in one network namespace, KickCAT
//! (Python bindings, link timeout 20 ms) in another, a veth pair between them. Expected
//! values come from the simulator's built-in topology.
//!
//! Needs root and the venv from `scripts/test` (see tests/README.md).

use ecat_tests::pysoem_session::{hex, plan, u};
use ecat_tests::python::run_script;
use ecat_tests::rig::{MASTER_IFACE, Rig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use sim::topology::{Topology, build};

#[test]
fn kickcat_initialises_the_bus_reads_sdos_and_reaches_op() {
    let topology = Topology::default_segment();
    let coe = plan(&topology).coe;
    let rig = Rig::new();
    let mut sim = SimProcess::start(&rig.sim, SIM_IFACE, &[]);
    // Before its ready line, ecat-sim lists what it emulates: one line per slave.
    let listed: Vec<&String> = sim
        .banner
        .iter()
        .filter(|l| l.trim_start().starts_with("slave "))
        .collect();
    assert_eq!(listed.len(), topology.slaves.len(), "{:?}", sim.banner);
    for (p, (line, spec)) in listed.iter().zip(&topology.slaves).enumerate() {
        assert!(
            line.contains(&format!("slave {p}: {:?}", spec.name))
                && line.contains(&format!("product 0x{:08X}", spec.product_code)),
            "{line}"
        );
    }
    let list: Vec<String> = coe.iter().map(ToString::to_string).collect();
    let r = run_script(
        &rig.master,
        "kickcat_check.py",
        &[MASTER_IFACE, "--sdo", &list.join(",")],
    );
    let status = sim.stop();
    assert!(status.success(), "ecat-sim exit after SIGTERM: {status}");

    let attempts = u(&r["init_attempts"]);
    if attempts > 1 {
        // The simulator's own count says whether it lost a frame or was merely late.
        eprintln!(
            "KickCAT needed {attempts} init attempts (a frame missed its 20 ms timeout); \
             ecat-sim: {}",
            sim.stderr().trim()
        );
    }
    assert_eq!(u(&r["slave_count"]), topology.slaves.len() as u64);
    for &p in &coe {
        let spec = &topology.slaves[p];
        let key = p.to_string();
        let identity = [
            spec.vendor_id,
            spec.product_code,
            spec.revision,
            spec.serial,
        ];
        let entries: Vec<u64> = r["identity"][&key]
            .as_array()
            .unwrap()
            .iter()
            .map(u)
            .collect();
        assert_eq!(
            entries,
            identity.map(u64::from),
            "slave {p} 0x1018, entry by entry"
        );
        // Complete access: SI0 (4 entries) padded to 16 bits, then the four entries.
        let mut complete = vec![4u8, 0];
        for value in identity {
            complete.extend_from_slice(&value.to_le_bytes());
        }
        assert_eq!(
            r["identity_complete"][&key],
            hex(&complete).as_str(),
            "slave {p} 0x1018 complete access"
        );
        assert_eq!(r["name"][&key], spec.name.as_str(), "slave {p} 0x1008");
    }

    // Process data mapped from the SII/PDO assignment, then OP with the cycle running.
    let built = build(&topology).unwrap();
    let sizes = r["pd_sizes"].as_array().unwrap();
    assert_eq!(sizes.len(), topology.slaves.len());
    for (p, seen) in sizes.iter().enumerate() {
        let expected = built.slave(p).unwrap().device().process_data_sizes();
        assert_eq!(
            (u(&seen["outputs"]), u(&seen["inputs"])),
            (u64::from(expected.outputs), u64::from(expected.inputs)),
            "slave {p} outputs/inputs"
        );
    }
    for (p, state) in r["states"].as_array().unwrap().iter().enumerate() {
        assert_eq!(state, "OPERATIONAL", "slave {p}");
    }
}
