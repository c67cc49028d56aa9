//! EoE end to end on the veth rig: ecatd `--iface` in one namespace (its EoE interfaces
//! there), `ecat-sim` in another; the device behind the simulated drive is the simulator's
//! TCP host. After Set IP through the API, 100 pings through `eoe0s0` all come back and a
//! 16 MiB HTTP transfer arrives with an equal SHA-256; the slave in INIT takes the interface
//! down, back in PREOP up (and traffic flows again); a rescan makes the interface anew and its configured
//! host address comes back without a command. With 5% of the bus frames lost a 4 MiB transfer
//! still arrives whole (TCP retransmits what EoE loses) and the losses are counted; with the
//! simulator's link cut the interface goes down, and comes back up when the link does.
//!
//! With `ecat-sim --eoe-tap`, the device is the Linux stack in the simulator's namespace
//! behind a TAP instead: Set IP through the API gives that TAP the slave's MAC and address,
//! 100 pings all come back, 16 MiB from a TCP server there arrive with an equal SHA-256,
//! and after a rescan the interface comes back with its address and the device answers.

use crate::eoe_support;
use crate::server_support;

use std::io::{Read, Write};
use std::net::TcpListener;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use ecat_tests::netns::NetNs;
use ecat_tests::rig::SIM_IFACE;
use eoe_support::rig::{DEVICE_IP, EoeRig};
use eoe_support::{EcatdInNs, payload};
use sha2::{Digest, Sha256};

fn sha256(data: &[u8]) -> Vec<u8> {
    Sha256::digest(data).to_vec()
}

fn start(sim_args: &[&str]) -> EoeRig {
    EoeRig::start(server_support::bin_dir(), sim_args)
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
    let mut rig = start(&[]);
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
    ecatd.rescan_and_wait_for("eoe0s0", "10.78.0.1/24");
    assert_eq!(ecatd.ping("10.78.0.2", 10, 56), 10, "{}", ecatd.log());
}

#[test]
fn a_transfer_survives_five_percent_bus_frame_loss_and_the_losses_are_counted() {
    let rig = start(&["--loss", "0.05", "--loss-seed", "17"]);
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
    let mut rig = start(&[]);
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

/// The TAP `ecat-sim --eoe-tap` makes for the drive in its namespace.
const DEVICE_TAP: &str = "eoedev0";

/// A TCP server in `ns` on port 8080 that answers one HTTP request with `body`, while
/// `client` runs; returns what `client` returned. The server gives up (and the test fails
/// through `client`) if nobody connects within [`eoe_support::PATIENCE`].
fn with_http_server_in<T>(ns: &NetNs, body: &[u8], client: impl FnOnce() -> T) -> T {
    std::thread::scope(|scope| {
        let (listening_tx, listening) = mpsc::channel();
        let server = scope.spawn(move || {
            ns.enter_current_thread();
            let listener =
                TcpListener::bind("0.0.0.0:8080").expect("bind in the device's namespace");
            listener.set_nonblocking(true).expect("non-blocking accept");
            listening_tx.send(()).expect("the test waits");
            let deadline = Instant::now() + eoe_support::PATIENCE;
            let mut stream = loop {
                match listener.accept() {
                    Ok((stream, _)) => break stream,
                    Err(err) if err.kind() == std::io::ErrorKind::WouldBlock => {
                        if Instant::now() > deadline {
                            return;
                        }
                        // The accept poll's interval (bounded by the deadline above).
                        std::thread::sleep(Duration::from_millis(10));
                    }
                    Err(err) => panic!("accept: {err}"),
                }
            };
            stream.set_nonblocking(false).expect("blocking stream");
            stream
                .set_read_timeout(Some(eoe_support::PATIENCE))
                .expect("timeout");
            let mut request = Vec::new();
            let mut buf = [0u8; 512];
            while !request.windows(4).any(|w| w == b"\r\n\r\n") && request.len() < 8192 {
                match stream.read(&mut buf) {
                    Ok(0) | Err(_) => return,
                    Ok(n) => request.extend_from_slice(&buf[..n]),
                }
            }
            let header = format!("HTTP/1.0 200 OK\r\nContent-Length: {}\r\n\r\n", body.len());
            let _ = stream.write_all(header.as_bytes());
            let _ = stream.write_all(body);
        });
        listening.recv().expect("the server listens");
        let result = client();
        server.join().expect("the server thread");
        result
    })
}

/// `ip <args>` inside the simulator's namespace: its stdout.
fn sim_ip(rig: &EoeRig, args: &[&str]) -> String {
    rig.sim_ns.ip(args)
}

#[test]
fn the_linux_stack_behind_a_bridged_slave_answers_ping_serves_16_mib_and_survives_a_rescan() {
    let mut rig = start(&["--eoe-tap", DEVICE_TAP]);
    assert!(
        rig.sim
            .banner
            .iter()
            .any(|l| l.contains("EoE of slave 0 bridged to TAP eoedev0")),
        "{:?}",
        rig.sim.banner
    );
    // Set IP went through the slave to the device: the TAP has the MAC and the address.
    rig.wait_for_device_tap(DEVICE_TAP);

    let ecatd = &mut rig.ecatd;
    assert_eq!(ecatd.ping(DEVICE_IP, 100, 56), 100, "{}", ecatd.log());

    let len = 16 << 20;
    let body = payload(len);
    let url = format!("http://{DEVICE_IP}:8080/");
    let out = with_http_server_in(&rig.sim_ns, &body, || {
        rig.ecatd.run("curl", &["-s", "--max-time", "600", &url])
    });
    assert!(
        out.status.success(),
        "curl: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        rig.ecatd.log()
    );
    assert_eq!(out.stdout.len(), len);
    assert_eq!(sha256(&out.stdout), sha256(&body));
    // The frames reached the Linux stack: the kernel counts what ecat-sim wrote into the TAP.
    let stats = sim_ip(&rig, &["-s", "-o", "link", "show", "dev", DEVICE_TAP]);
    let rx_packets: u64 = stats
        .split("RX:")
        .nth(1)
        .and_then(|rx| rx.split_whitespace().nth(8))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no RX packets in {stats}"));
    assert!(rx_packets > 100 + (len / 1500) as u64 / 4, "{stats}");

    // A rescan makes ecatd's interface anew; its host address comes back by itself, and
    // the device behind the slave answers again.
    let ecatd = &mut rig.ecatd;
    ecatd.rescan_and_wait_for("eoe0s0", "10.78.0.1/24");
    assert_eq!(ecatd.ping(DEVICE_IP, 10, 56), 10, "{}", ecatd.log());
}
