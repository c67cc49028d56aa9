//! Two network namespaces joined by a veth pair: the simulator's and the master's.

use crate::netns::NetNs;

/// The simulator's end of the veth pair.
pub const SIM_IFACE: &str = "sim0";
/// The master's end of the veth pair.
pub const MASTER_IFACE: &str = "mst0";

/// A namespace for the simulator and one for the master, with a veth pair between them.
/// Dropping it deletes both namespaces (and with them the pair).
#[derive(Debug)]
pub struct Rig {
    /// Where `ecat-sim` runs, on [`SIM_IFACE`].
    pub sim: NetNs,
    /// Where the master runs, on [`MASTER_IFACE`].
    pub master: NetNs,
}

impl Rig {
    /// Creates both namespaces and the veth pair, and returns once both ends carry frames.
    ///
    /// # Panics
    /// Without root or `ip` (see [`NetNs::new`]), or if the pair cannot be made.
    pub fn new() -> Rig {
        let sim = NetNs::new();
        // From here on `sim` deletes its namespace on a panic; `master` too, once made.
        let master = NetNs::new();
        // Always spell out `name` (see `NetNs::add_veth_pair`).
        sim.ip(&[
            "link",
            "add",
            "name",
            SIM_IFACE,
            "type",
            "veth",
            "peer",
            "name",
            MASTER_IFACE,
            "netns",
            master.name(),
        ]);
        sim.ip(&["link", "set", "dev", SIM_IFACE, "up"]);
        master.ip(&["link", "set", "dev", MASTER_IFACE, "up"]);
        sim.wait_until_ready(SIM_IFACE);
        master.wait_until_ready(MASTER_IFACE);
        Rig { sim, master }
    }
}

impl Default for Rig {
    fn default() -> Self {
        Rig::new()
    }
}
