//! EoE end to end on the veth rig: ecatd `--iface` in one namespace (its EoE interfaces
//! there), `ecat-sim` in another; the device behind the simulated drive is the simulator's
//! TCP host. After Set IP through the API, 100 pings through `eoe0s0` all come back and a
//! 16 MiB HTTP transfer arrives with an equal SHA-256; the slave in INIT takes the interface
//! down, back in PREOP up (and traffic flows again); a rescan makes the interface anew and its configured
//! host address comes back without a command. With 5% of the bus frames lost a 4 MiB transfer
//! still arrives whole (TCP retransmits what EoE loses) and the losses are counted; with the
//! simulator's link cut the interface goes down, and comes back up when the link does.

mod eoe_support;
#[path = "server_support/mod.rs"]
mod server_support;

use ecat_tests::netns::NetNs;
use ecat_tests::rig::{MASTER_IFACE, Rig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use eoe_support::{EcatdInNs, payload};
use sha2::{Digest, Sha256};

const CONFIG: &str = r#"
[eoe]
name_scheme = "position"

[[eoe.slave]]
slave = "0"
host_address = "10.78.0.1/24"
"#;

fn sha256(data: &[u8]) -> Vec<u8> {
    Sha256::digest(data).to_vec()
}

/// The rig with ecatd's `eoe0s0` up and the device behind it at 10.78.0.2 (Set IP done).
/// Fields drop in order: ecatd, then the simulator, then its namespace.
struct EoeRig {
    ecatd: EcatdInNs,
    _sim: SimProcess,
    sim_ns: NetNs,
}

impl EoeRig {
    /// Starts `ecat-sim <sim_args>` and ecatd, waits for `eoe0s0` and sets the device's IP.
    fn start(sim_args: &[&str]) -> EoeRig {
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
            server_support::bin_dir(),
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
            r#"{"mac":"02:00:00:00:bb:01","ip":"10.78.0.2","subnet_mask":"255.255.255.0"}"#,
        ]);
        assert_eq!(status, 200, "{body}");
        EoeRig {
            ecatd,
            _sim: sim,
            sim_ns,
        }
    }
}

/// `GET http://10.78.0.2/<len>` with curl inside ecatd's namespace: the body.
fn http_get(ecatd: &EcatdInNs, len: usize) -> Vec<u8> {
    let out = ecatd.run(
        "curl",
        &[
            "-s",
            "--max-time",
            "600",
            &format!("http://10.78.0.2/{len}"),
        ],
    );
    assert!(
        out.status.success(),
        "curl: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        ecatd.log()
    );
    out.stdout
}

/// The value of the first `/metrics` sample of `name` whose line contains `filter`.
fn metric(ecatd: &EcatdInNs, name: &str, filter: &str) -> u64 {
    let (status, text) = ecatd.curl(&["/metrics"]);
    assert_eq!(status, 200, "{text}");
    text.lines()
        .find(|line| {
            (line.starts_with(&format!("{name}{{")) || line.starts_with(&format!("{name} ")))
                && line.contains(filter)
        })
        .and_then(|line| line.rsplit(' ').next())
        .and_then(|value| value.parse::<f64>().ok())
        .map(|value| value as u64)
        .unwrap_or_else(|| panic!("no {name} ({filter}) in /metrics:\n{text}"))
}

#[test]
fn ping_http_state_changes_and_rescan_through_the_drives_interface() {
    let mut rig = EoeRig::start(&[]);
    let ecatd = &mut rig.ecatd;
    assert_eq!(ecatd.ping("10.78.0.2", 100, 56), 100, "{}", ecatd.log());

    let len = 16 << 20;
    let out = ecatd.run(
        "curl",
        &[
            "-s",
            "--max-time",
            "600",
            &format!("http://10.78.0.2/{len}"),
        ],
    );
    assert!(
        out.status.success(),
        "curl: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(out.stdout.len(), len);
    assert_eq!(sha256(&out.stdout), sha256(&payload(len)));
    let listed = ecatd.interface("eoe0s0").expect("listed");
    assert!(
        listed["bytes_in"].as_u64().unwrap() > len as u64,
        "{listed}"
    );

    // The slave in INIT (no mailbox): the interface goes down; back in PREOP: up again.
    let state = |e: &EcatdInNs, to: &str| {
        let body = format!(r#"{{"state":"{to}"}}"#);
        let (status, answer) = e.curl(&[
            "/api/v1/slaves/0/state",
            "-X",
            "PUT",
            "-H",
            "content-type: application/json",
            "-d",
            &body,
        ]);
        assert_eq!(status, 200, "{answer}");
    };
    state(ecatd, "INIT");
    ecatd.wait_until("eoe0s0 down", |e| {
        !e.carrier("eoe0s0") && e.interface("eoe0s0").is_some_and(|i| i["state"] == "down")
    });
    state(ecatd, "PREOP");
    ecatd.wait_until("eoe0s0 up again", |e| {
        e.carrier("eoe0s0") && e.interface("eoe0s0").is_some_and(|i| i["state"] == "up")
    });
    assert_eq!(ecatd.ping("10.78.0.2", 10, 56), 10, "{}", ecatd.log());

    // A rescan makes the interface anew; its host address comes back by itself.
    let before = ecatd.ifindex("eoe0s0").expect("index");
    let (status, body) = ecatd.curl(&["/api/v1/rescan", "-X", "POST"]);
    assert_eq!(status, 200, "{body}");
    ecatd.wait_until("eoe0s0 made anew, up, with its address", |e| {
        e.ifindex("eoe0s0").is_some_and(|i| i != before)
            && e.carrier("eoe0s0")
            && e.link("eoe0s0")
                .is_some_and(|(_, addr)| addr.contains("10.78.0.1/24"))
    });
    assert_eq!(ecatd.ping("10.78.0.2", 10, 56), 10, "{}", ecatd.log());
}

#[test]
fn a_transfer_survives_five_percent_bus_frame_loss_and_the_losses_are_counted() {
    let rig = EoeRig::start(&["--loss", "0.05", "--loss-seed", "17"]);
    let ecatd = &rig.ecatd;

    let len = 4 << 20;
    let body = http_get(ecatd, len);
    assert_eq!(body.len(), len);
    assert_eq!(sha256(&body), sha256(&payload(len)));

    // The bus lost frames, the mailbox layer asked the slave to repeat what they carried,
    // and so no EoE fragment was missing: nothing dropped in reassembly or before the
    // interface, as the API and /metrics both say.
    let listed = ecatd.interface("eoe0s0").expect("listed");
    eprintln!("5% loss, 4 MiB: {listed}");
    let (_, text) = ecatd.curl(&["/metrics"]);
    for line in text.lines().filter(|l| {
        l.starts_with("ecat_bus_frames_lost")
            || l.starts_with("ecat_mailbox_repeats")
            || l.starts_with("ecat_mailbox_failed")
            || l.starts_with("ecat_eoe_reassembly")
    }) {
        eprintln!("{line}");
    }
    assert!(
        listed["bytes_in"].as_u64().unwrap() > len as u64,
        "{listed}"
    );
    assert!(metric(ecatd, "ecat_bus_frames_lost_total", "") > 0);
    assert!(metric(ecatd, "ecat_mailbox_repeats_total", "") > 0);
    assert_eq!(listed["reassembly_errors"], 0, "{listed}");
    assert_eq!(listed["drops_in"], 0, "{listed}");
    assert_eq!(
        metric(
            ecatd,
            "ecat_eoe_interface_reassembly_errors_total",
            "eoe0s0"
        ),
        0
    );
    assert_eq!(
        metric(ecatd, "ecat_eoe_interface_rx_dropped_total", "eoe0s0"),
        0
    );
}

#[test]
fn the_interface_goes_down_when_the_link_is_cut_and_up_when_it_is_back() {
    let mut rig = EoeRig::start(&[]);
    assert_eq!(
        rig.ecatd.ping("10.78.0.2", 10, 56),
        10,
        "{}",
        rig.ecatd.log()
    );

    rig.sim_ns.ip(&["link", "set", "dev", SIM_IFACE, "down"]);
    rig.ecatd
        .wait_until("eoe0s0 down once the slave is lost", |e| {
            !e.carrier("eoe0s0") && e.interface("eoe0s0").is_none_or(|i| i["state"] == "down")
        });

    rig.sim_ns.ip(&["link", "set", "dev", SIM_IFACE, "up"]);
    rig.ecatd.wait_until("eoe0s0 up again", |e| {
        e.carrier("eoe0s0") && e.interface("eoe0s0").is_some_and(|i| i["state"] == "up")
    });
    assert_eq!(
        rig.ecatd.ping("10.78.0.2", 10, 56),
        10,
        "{}",
        rig.ecatd.log()
    );
}
