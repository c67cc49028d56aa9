//! The pysoem session the end-to-end tests share: `ecat-sim` in one namespace, pysoem
//! (tests/py/pysoem_check.py) in the other. Which slaves to exercise comes from the topology.

use std::process::ExitStatus;

use serde_json::Value;
use sim::topology::{Protocol, SlaveSpec, Topology};

use crate::python::run_script;
use crate::rig::{MASTER_IFACE, Rig, SIM_IFACE};
use crate::sim_process::SimProcess;

/// The name of the file the session writes and reads back with FoE: a new file, because
/// the topology's own files may get BUSY phases, which pysoem's FoE write does not handle.
pub const FOE_FILE: &str = "pysoem-check.txt";

/// The arguments that tell pysoem_check.py which slaves to use, from the topology.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Slaves with CoE (identity and object list).
    pub coe: Vec<usize>,
    /// (slave, index) of the largest sized byte object.
    pub large: (usize, u16),
    /// A slave with FoE.
    pub foe: usize,
}

/// Which slaves of `topology` the session exercises.
///
/// # Panics
/// If the topology has no CoE slave with a sized object, or no FoE slave.
pub fn plan(topology: &Topology) -> Plan {
    let has = |p: Protocol| {
        move |(_, s): &(usize, &SlaveSpec)| s.mailbox.is_some() && s.protocols.contains(&p)
    };
    let coe: Vec<usize> = topology
        .slaves
        .iter()
        .enumerate()
        .filter(has(Protocol::Coe))
        .map(|(p, _)| p)
        .collect();
    let large = coe
        .iter()
        .flat_map(|&p| {
            topology.slaves[p]
                .objects
                .iter()
                .filter_map(move |o| o.size.map(|size| (size, p, o.index)))
        })
        .max()
        .map(|(_, p, index)| (p, index))
        .expect("a CoE slave with a sized object");
    let foe = topology
        .slaves
        .iter()
        .enumerate()
        .find(has(Protocol::Foe))
        .map(|(p, _)| p)
        .expect("a slave with FoE");
    Plan { coe, large, foe }
}

/// Runs the pysoem session against `ecat-sim <extra>` on the built-in topology; returns
/// pysoem's report and the simulator's exit status after SIGTERM.
pub fn pysoem_session(extra: &[&str]) -> (Value, ExitStatus) {
    let topology = Topology::default_segment();
    let plan = plan(&topology);
    let rig = Rig::new();
    let mut sim = SimProcess::start(&rig.sim, SIM_IFACE, extra);
    let coe: Vec<String> = plan.coe.iter().map(ToString::to_string).collect();
    let report = run_script(
        &rig.master,
        "pysoem_check.py",
        &[
            MASTER_IFACE,
            "--large",
            &format!("{}:0x{:04X}", plan.large.0, plan.large.1),
            "--foe",
            &format!("{}:{FOE_FILE}", plan.foe),
            "--od",
            &coe.join(","),
        ],
    );
    let status = sim.stop();
    (report, status)
}

/// The report's number at `v`.
///
/// # Panics
/// If it is not an unsigned number.
pub fn u(v: &Value) -> u64 {
    v.as_u64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// Bytes as lowercase hex, as the scripts report them.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}
