//! The veth rig with EoE: `ecat-sim` in one namespace, ecatd `--iface` in another with its
//! `eoe0s0` (host address 10.78.0.1/24 from its configuration) up, and the device behind
//! the drive at 10.78.0.2 (Set IP done through the API).

use std::path::Path;
use std::time::{Duration, Instant};

use ecat_tests::netns::NetNs;
use ecat_tests::rig::{MASTER_IFACE, Rig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;

use super::{EcatdInNs, PATIENCE};

/// ecatd's configuration: position names, the drive's interface with its host address.
const CONFIG: &str = r#"
[eoe]
name_scheme = "position"

[[eoe.slave]]
slave = "0"
host_address = "10.78.0.1/24"
"#;

/// What Set IP gives the drive (its MAC and address: the device's).
pub const SET_IP: &str =
    r#"{"mac":"02:00:00:00:bb:01","ip":"10.78.0.2","subnet_mask":"255.255.255.0"}"#;

/// The device's address.
pub const DEVICE_IP: &str = "10.78.0.2";

/// The rig with ecatd's `eoe0s0` up and the device behind it at [`DEVICE_IP`] (Set IP
/// done). Fields drop in order: ecatd, then the simulator, then its namespace.
pub struct EoeRig {
    /// ecatd in the master's namespace.
    pub ecatd: EcatdInNs,
    /// The simulator.
    pub sim: SimProcess,
    /// The simulator's namespace.
    pub sim_ns: NetNs,
}

impl EoeRig {
    /// Starts `ecat-sim <sim_args>` and ecatd (from `bin_dir`), waits for `eoe0s0` and sets
    /// the device's IP.
    pub fn start(bin_dir: &Path, sim_args: &[&str]) -> EoeRig {
        let Rig {
            sim: sim_ns,
            master,
        } = Rig::new();
        let sim = SimProcess::start(&sim_ns, SIM_IFACE, sim_args);
        let config = std::env::temp_dir().join(format!(
            "ecatd-eoe-veth-{}-{}.toml",
            std::process::id(),
            master.name()
        ));
        std::fs::write(&config, CONFIG).expect("config written");
        let config_path = config.to_str().expect("a UTF-8 path").to_owned();
        let mut ecatd = EcatdInNs::start_in(
            master,
            bin_dir,
            &["--iface", MASTER_IFACE, "--config", &config_path],
        );
        let _ = std::fs::remove_file(&config);
        ecatd.wait_until("eoe0s0 up with its address", |e| {
            e.carrier("eoe0s0")
                && e.link("eoe0s0")
                    .is_some_and(|(_, addr)| addr.contains("10.78.0.1/24"))
        });
        let (status, body) = ecatd.curl(&[
            "/api/v1/slaves/0/eoe/ip",
            "-X",
            "PUT",
            "-H",
            "content-type: application/json",
            "-d",
            SET_IP,
        ]);
        assert_eq!(status, 200, "{body}");
        EoeRig { ecatd, sim, sim_ns }
    }
}

impl EoeRig {
    /// With `ecat-sim --eoe-tap <tap>`: waits until Set IP reached the device, that is
    /// until the TAP in the simulator's namespace has the slave's MAC and address.
    pub fn wait_for_device_tap(&self, tap: &str) {
        let deadline = Instant::now() + PATIENCE;
        loop {
            let link = self.sim_ns.ip(&["-o", "link", "show", "dev", tap]);
            let addr = self.sim_ns.ip(&["-o", "-4", "addr", "show", "dev", tap]);
            if link.contains("02:00:00:00:bb:01") && addr.contains("10.78.0.2/24") {
                return;
            }
            assert!(
                Instant::now() < deadline,
                "Set IP not on the TAP:\n{link}\n{addr}\n{}",
                self.sim.stderr()
            );
            // The check's poll interval (the loop ends on the condition or the deadline).
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}
