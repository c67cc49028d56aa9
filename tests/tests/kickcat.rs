//! The KickCAT master accepts the simulator: `ecat-sim` in one network namespace, KickCAT
//! (Python bindings, link timeout 20 ms) in another, a veth pair between them. Expected
//! values come from the simulator's built-in topology.
//!
//! Needs root and the venv from `scripts/test` (see tests/README.md).

use ecat_tests::pysoem_session::{hex, plan, u};
use ecat_tests::python::run_script;
use ecat_tests::rig::{MASTER_IFACE, Rig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use sim::topology::Topology;

#[test]
fn kickcat_initialises_the_bus_and_reads_sdos() {
    let topology = Topology::default_segment();
    let coe = plan(&topology).coe;
    let rig = Rig::new();
    let mut sim = SimProcess::start(&rig.sim, SIM_IFACE, &[]);
    let list: Vec<String> = coe.iter().map(ToString::to_string).collect();
    let r = run_script(
        &rig.master,
        "kickcat_check.py",
        &[MASTER_IFACE, "--sdo", &list.join(",")],
    );
    let status = sim.stop();
    assert!(status.success(), "ecat-sim exit after SIGTERM: {status}");

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
}
