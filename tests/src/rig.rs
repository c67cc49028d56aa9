//! Two network namespaces joined by a veth pair: the simulator's and the master's.

use crate::netns::{NetNs, run_ip, wait_link_ready};

/// The simulator's end of the veth pair.
pub const SIM_IFACE: &str = "sim0";
/// The master's end of the veth pair.
pub const MASTER_IFACE: &str = "mst0";
/// The simulator's end of a ring's second veth pair ([`Rig::ring`]): the way back from the
/// last slave.
pub const SIM_BACKUP_IFACE: &str = "sim1";
/// The master's end of a ring's second veth pair: its backup port.
pub const MASTER_BACKUP_IFACE: &str = "mst1";

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

impl Rig {
    /// [`Rig::new`] with a second veth pair, [`SIM_BACKUP_IFACE`] to
    /// [`MASTER_BACKUP_IFACE`], for a segment wired as a ring (`ecat-sim --backup-iface`).
    ///
    /// # Panics
    /// As [`Rig::new`].
    pub fn ring() -> Rig {
        let rig = Rig::new();
        rig.sim.ip(&[
            "link",
            "add",
            "name",
            SIM_BACKUP_IFACE,
            "type",
            "veth",
            "peer",
            "name",
            MASTER_BACKUP_IFACE,
            "netns",
            rig.master.name(),
        ]);
        rig.sim.ip(&["link", "set", "dev", SIM_BACKUP_IFACE, "up"]);
        rig.master
            .ip(&["link", "set", "dev", MASTER_BACKUP_IFACE, "up"]);
        rig.sim.wait_until_ready(SIM_BACKUP_IFACE);
        rig.master.wait_until_ready(MASTER_BACKUP_IFACE);
        rig
    }
}

impl Default for Rig {
    fn default() -> Self {
        Rig::new()
    }
}

/// A namespace for the simulator whose veth pair has its other end here, in the test
/// process's own namespace, for a master that runs as a separate program (`ecatd --iface`)
/// and serves its APIs on this namespace's loopback, where the test's clients are.
///
/// The host end gets a unique name and no IPv6 (so that the kernel sends nothing on it);
/// dropping the rig deletes the namespace, and with it both ends of the pair.
#[derive(Debug)]
pub struct HostRig {
    /// Where `ecat-sim` runs, on [`SIM_IFACE`].
    pub sim: NetNs,
    /// The master's end of the pair, in the caller's namespace.
    pub master_iface: String,
}

impl HostRig {
    /// Creates the namespace and the veth pair, and returns once both ends carry frames.
    ///
    /// # Panics
    /// Without root or `ip`, or if the pair cannot be made.
    pub fn new() -> HostRig {
        use std::sync::atomic::{AtomicU32, Ordering};
        static NEXT: AtomicU32 = AtomicU32::new(0);
        let sim = NetNs::new();
        // At most 15 characters: "em" + the pid and a counter in hex.
        let master_iface = format!(
            "em{:x}x{:x}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        );
        run_ip(&[
            "link",
            "add",
            "name",
            &master_iface,
            "type",
            "veth",
            "peer",
            "name",
            SIM_IFACE,
            "netns",
            sim.name(),
        ]);
        // From here on the namespace's drop deletes the pair too.
        let rig = HostRig { sim, master_iface };
        let ipv6 = format!("/proc/sys/net/ipv6/conf/{}/disable_ipv6", rig.master_iface);
        // Best effort: without IPv6 in the kernel there is nothing to silence.
        let _ = std::fs::write(ipv6, "1");
        rig.sim.ip(&["link", "set", "dev", SIM_IFACE, "up"]);
        run_ip(&["link", "set", "dev", &rig.master_iface, "up"]);
        rig.sim.wait_until_ready(SIM_IFACE);
        wait_link_ready(None, &rig.master_iface);
        rig
    }
}

impl Default for HostRig {
    fn default() -> Self {
        HostRig::new()
    }
}
