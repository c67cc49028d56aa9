//! EoE end to end in `ecatd --simulate`: ecatd in a namespace of its own makes `eoe0s0` for
//! the simulated drive, puts the configured host address on it and sends the configured
//! Set IP; ping and an HTTP transfer reach the device behind the slave (sim's TCP host) and
//! come back intact; the counters move in the API and `/metrics`; Set IP through the API
//! moves the device; a rescan makes the interface anew with its address, without a command.
//! Configured into a Linux bridge instead, the interface joins it at every re-creation.

use crate::eoe_support;
use crate::server_support;

use std::io::Write;

use eoe_support::{EcatdInNs, payload};
use sha2::{Digest, Sha256};

const CONFIG: &str = r#"
[eoe]
name_scheme = "position"

[[eoe.slave]]
slave = "0"
slave_mac = "02:00:00:00:aa:01"
ip = "10.77.0.2"
subnet_mask = "255.255.255.0"
host_address = "10.77.0.1/24"
"#;

fn config_file() -> tempfile_path::TempPath {
    tempfile_path::write(CONFIG)
}

/// A configuration file that is removed on drop (the tests crate has no tempfile crate).
mod tempfile_path {
    use std::path::PathBuf;

    pub struct TempPath(pub PathBuf);

    impl Drop for TempPath {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.0);
        }
    }

    pub fn write(text: &str) -> TempPath {
        use std::sync::atomic::{AtomicU32, Ordering};
        static NEXT: AtomicU32 = AtomicU32::new(0);
        let path = std::env::temp_dir().join(format!(
            "ecatd-eoe-{}-{}.toml",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        let mut file = std::fs::File::create(&path).expect("config file");
        super::Write::write_all(&mut file, text.as_bytes()).expect("config written");
        TempPath(path)
    }
}

fn sha256(data: &[u8]) -> String {
    hex(&Sha256::digest(data))
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[test]
fn ping_and_http_reach_the_simulated_device_and_a_rescan_restores_the_interface() {
    let config = config_file();
    let config_path = config.0.to_str().expect("a UTF-8 path");
    let mut ecatd = EcatdInNs::start(
        server_support::bin_dir(),
        &["--simulate", "--config", config_path],
    );
    ecatd.wait_until("eoe0s0 up with its address", |e| {
        e.carrier("eoe0s0")
            && e.link("eoe0s0")
                .is_some_and(|(_, addr)| addr.contains("10.77.0.1/24"))
            && e.interface("eoe0s0").is_some_and(|i| i["state"] == "up")
    });
    let listed = ecatd.interface("eoe0s0").expect("listed");
    assert_eq!(listed["position"], 0);
    assert_eq!(listed["mac"], "02:00:00:01:00:00", "02:NIC:NIC:NIC:RP:RP");
    let (link, _) = ecatd.link("eoe0s0").unwrap();
    assert!(link.contains("02:00:00:01:00:00"), "{link}");

    // The configured Set IP reached the slave: it answers on 10.77.0.2.
    assert_eq!(ecatd.ping("10.77.0.2", 20, 56), 20, "{}", ecatd.log());
    // Frames larger than one mailbox (128 bytes) go in fragments both ways.
    assert_eq!(ecatd.ping("10.77.0.2", 5, 1400), 5);

    let len = 1 << 20;
    let out = ecatd.run(
        "curl",
        &[
            "-s",
            "--max-time",
            "120",
            &format!("http://10.77.0.2/{len}"),
        ],
    );
    assert!(
        out.status.success(),
        "curl failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(out.stdout.len(), len);
    assert_eq!(sha256(&out.stdout), sha256(&payload(len)));

    let listed = ecatd.interface("eoe0s0").unwrap();
    let frames_in = listed["frames_in"].as_u64().unwrap();
    let bytes_in = listed["bytes_in"].as_u64().unwrap();
    assert!(bytes_in > len as u64, "{listed}");
    assert!(listed["frames_out"].as_u64().unwrap() > 25, "{listed}");
    assert_eq!(listed["drops_out"], 0, "{listed}");
    let (status, metrics) = ecatd.curl(&["/metrics"]);
    assert_eq!(status, 200);
    let sample = |series: &str| -> f64 {
        metrics
            .lines()
            .find_map(|l| l.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
            .unwrap_or_else(|| panic!("no {series} in:\n{metrics}"))
    };
    assert!(
        sample(r#"ecat_eoe_interface_rx_frames_total{interface="eoe0s0"}"#) >= frames_in as f64
    );
    assert_eq!(sample(r#"ecat_eoe_interface_up{interface="eoe0s0"}"#), 1.0);

    // Set IP through the API moves the device to another address.
    let (status, body) = ecatd.curl(&[
        "/api/v1/slaves/0/eoe/ip",
        "-X",
        "PUT",
        "-H",
        "content-type: application/json",
        "-d",
        r#"{"ip":"10.77.0.3"}"#,
    ]);
    assert_eq!(status, 200, "{body}");
    assert_eq!(ecatd.ping("10.77.0.3", 10, 56), 10);

    // A rescan makes the interface anew (new index); its address comes back by itself and
    // the configured Set IP is sent again (the device is back on 10.77.0.2).
    ecatd.rescan_and_wait_for("eoe0s0", "10.77.0.1/24");
    assert_eq!(ecatd.ping("10.77.0.2", 10, 56), 10, "{}", ecatd.log());
}

/// The host side as a bridge port: with `bridge = "eoebr0"` the interface joins the bridge
/// (which holds the host's address) when it is made, the device behind the slave answers
/// through the bridge, and after a rescan the interface made anew is a port of the bridge
/// again without a command.
#[test]
fn an_interface_configured_into_a_bridge_joins_it_and_joins_it_again_after_a_rescan() {
    let config = tempfile_path::write(
        r#"
[eoe]
name_scheme = "position"

[[eoe.slave]]
slave = "0"
slave_mac = "02:00:00:00:aa:02"
ip = "10.76.0.2"
subnet_mask = "255.255.255.0"
bridge = "eoebr0"
"#,
    );
    let ns = ecat_tests::netns::NetNs::new();
    ns.ip(&["link", "add", "eoebr0", "type", "bridge"]);
    ns.ip(&["addr", "add", "10.76.0.1/24", "dev", "eoebr0"]);
    ns.ip(&["link", "set", "dev", "eoebr0", "up"]);
    let config_path = config.0.to_str().expect("a UTF-8 path");
    let mut ecatd = EcatdInNs::start_in(
        ns,
        server_support::bin_dir(),
        &["--simulate", "--config", config_path],
    );
    let in_bridge = |e: &EcatdInNs| {
        e.carrier("eoe0s0")
            && e.link("eoe0s0")
                .is_some_and(|(link, addr)| link.contains("master eoebr0") && addr.is_empty())
    };
    ecatd.wait_until("eoe0s0 up as a port of eoebr0", in_bridge);
    assert_eq!(ecatd.ping("10.76.0.2", 10, 56), 10, "{}", ecatd.log());

    let before = ecatd.ifindex("eoe0s0").expect("the interface's index");
    let (status, body) = ecatd.curl(&["/api/v1/rescan", "-X", "POST"]);
    assert_eq!(status, 200, "{body}");
    ecatd.wait_until("eoe0s0 made anew, up, a port of eoebr0 again", |e| {
        e.ifindex("eoe0s0").is_some_and(|i| i != before) && in_bridge(e)
    });
    assert_eq!(ecatd.ping("10.76.0.2", 10, 56), 10, "{}", ecatd.log());
}

/// The simulated device has a factory MAC, as a real one does: `ecat ip` with an address
/// alone (IgH's `ethercat ip` makes the MAC optional) puts it on the network, and ping
/// reaches it through `eoe0s0` on the embedded default segment. The address filter, set
/// through `ecat`, REST and gRPC, decides which frames reach it.
#[test]
fn set_ip_without_a_mac_is_enough_to_ping_the_device_and_the_filter_decides() {
    let config = tempfile_path::write(
        r#"
[eoe]
name_scheme = "position"

[[eoe.slave]]
slave = "0"
host_address = "10.78.0.1/24"
"#,
    );
    let mut ecatd = EcatdInNs::start(
        server_support::bin_dir(),
        &["--simulate", "--config", config.0.to_str().unwrap()],
    );
    ecatd.wait_until("eoe0s0 up with its address", |e| {
        e.carrier("eoe0s0")
            && e.link("eoe0s0")
                .is_some_and(|(_, addr)| addr.contains("10.78.0.1/24"))
    });
    // Nothing set yet: the device is not on the network.
    assert_eq!(ecatd.ping("10.78.0.2", 2, 56), 0);
    // A ping that should be answered starts from a fresh address resolution: after pings
    // that went unanswered the kernel's entry for the device may be failing, and packets
    // queued behind it are dropped with it.
    let answered = |count: u32| {
        ecatd.run("ip", &["neigh", "flush", "dev", "eoe0s0"]);
        ecatd.ping("10.78.0.2", count, 56)
    };
    let ecat = server_support::bin_dir().join("ecat");
    let out = ecatd.run(
        ecat.to_str().unwrap(),
        &["ip", "-p", "0", "--ip", "10.78.0.2/24"],
    );
    assert!(
        out.status.success(),
        "ecat ip: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(answered(5), 5, "{}", ecatd.log());
    // It answered on its factory MAC, 02:45:43:53:00:00 for position 0 (docs/eoe.md).
    let neighbours = ecatd.run("ip", &["neigh", "show", "10.78.0.2", "dev", "eoe0s0"]);
    let neighbours = String::from_utf8_lossy(&neighbours.stdout);
    assert!(neighbours.contains("02:45:43:53:00:00"), "{neighbours}");

    // The address filter (Set address filter), from each API: naming another MAC, the
    // slave no longer passes the device its frames; naming the device's, it does again;
    // empty, every unicast frame passes.
    let out = ecatd.run(
        ecat.to_str().unwrap(),
        &["eoe_filter", "-p", "0", "02:00:00:00:00:99"],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(ecatd.ping("10.78.0.2", 3, 56), 0, "filtered out");
    let (status, body) = put_filter(&ecatd, r#"{"macs":["02:45:43:53:00:00"]}"#);
    assert_eq!(status, 200, "{body}");
    assert_eq!(answered(3), 3, "{}", ecatd.log());
    let out = ecatd.run(
        server_support::grpcurl_path().to_str().unwrap(),
        &[
            "-plaintext",
            "-d",
            r#"{"slave":"0","macs":["02:00:00:00:00:98"]}"#,
            "127.0.0.1:50051",
            "ecat.v1.EoeService/SetAddressFilter",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(ecatd.ping("10.78.0.2", 3, 56), 0, "filtered out again");
    let (status, body) = put_filter(&ecatd, r#"{"macs":["02:45:43"]}"#);
    assert_eq!(status, 400, "{body}");
    assert!(body.contains(r#""field":"macs""#), "{body}");
    assert_eq!(
        ecatd.ping("10.78.0.2", 2, 56),
        0,
        "a refused filter changes nothing"
    );
    let (status, body) = put_filter(&ecatd, "{}");
    assert_eq!(status, 200, "{body}");
    assert_eq!(answered(3), 3);
}

/// `PUT /api/v1/slaves/0/eoe/filter` with `body`.
fn put_filter(ecatd: &EcatdInNs, body: &str) -> (u16, String) {
    ecatd.curl(&[
        "/api/v1/slaves/0/eoe/filter",
        "-X",
        "PUT",
        "-H",
        "content-type: application/json",
        "-d",
        body,
    ])
}
