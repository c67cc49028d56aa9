//! ecatd's `/metrics`: `promtool check metrics` reports nothing, and the counters and gauges
//! equal what the test did (uploads good and bad, a state change).

use crate::server_support;

use std::io::Write;
use std::net::{Ipv4Addr, UdpSocket};
use std::process::{Command, Stdio};
use std::time::Duration;

use master_core::wire::Emit;
use master_core::wire::coe::CoeRepr;
use master_core::wire::coe::sdo_request::SdoRequest;
use master_core::wire::gateway::{GatewayMessage, GatewayRepr};
use master_core::wire::mailbox::{MailboxHeader, MailboxType};

use server_support::{Ecatd, curl};
use sim::topology::Topology;

fn scrape(ecatd: &Ecatd) -> String {
    let (status, body) = curl(&["-s", &format!("{}/metrics", ecatd.http)]);
    assert_eq!(status, 200);
    body
}

/// The value of the sample `series` (name with labels, exactly as exposed).
fn sample(text: &str, series: &str) -> f64 {
    text.lines()
        .find_map(|line| line.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
        .unwrap_or_else(|| panic!("no sample {series} in:\n{text}"))
}

#[test]
fn promtool_finds_nothing() {
    let ecatd = Ecatd::start(&[]);
    // Some traffic first, so that every family has samples.
    curl(&[
        "-s",
        &format!("{}/api/v1/slaves/0/coe/sdo/0x1018/1", ecatd.http),
    ]);
    let text = scrape(&ecatd);
    let mut promtool = Command::new("promtool")
        .args(["check", "metrics"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("promtool (Debian package prometheus; scripts/test installs it)");
    promtool
        .stdin
        .take()
        .unwrap()
        .write_all(text.as_bytes())
        .unwrap();
    let output = promtool.wait_with_output().unwrap();
    let report = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(
        output.status.success() && report.trim().is_empty(),
        "promtool:\n{report}"
    );
}

#[test]
fn counters_equal_what_was_done() {
    let ecatd = Ecatd::start(&[]);
    let topology = Topology::default_segment();
    let before = scrape(&ecatd);
    let requests = r#"ecat_mailbox_requests_total{station="1004"}"#;
    let failed = r#"ecat_mailbox_failed_requests_total{station="1004"}"#;
    let (r0, f0) = (sample(&before, requests), sample(&before, failed));
    for _ in 0..5 {
        let (status, _) = curl(&[
            "-s",
            &format!("{}/api/v1/slaves/3/coe/sdo/0x2001/0", ecatd.http),
        ]);
        assert_eq!(status, 200);
    }
    for _ in 0..3 {
        let (status, _) = curl(&[
            "-s",
            &format!("{}/api/v1/slaves/3/coe/sdo/0x6000/0", ecatd.http),
        ]);
        assert_eq!(status, 404);
    }
    let after = scrape(&ecatd);
    assert_eq!(sample(&after, requests) - r0, 8.0);
    assert_eq!(sample(&after, failed) - f0, 3.0);
    assert_eq!(
        sample(&after, r#"ecat_slaves{state="OP"}"#),
        topology.slaves.len() as f64
    );
    let url = format!("{}/api/v1/slaves/1/state", ecatd.http);
    let (status, _) = curl(&[
        "-s",
        "-X",
        "PUT",
        "-H",
        "content-type: application/json",
        "-d",
        r#"{"state":"PREOP"}"#,
        &url,
    ]);
    assert_eq!(status, 200);
    let states = scrape(&ecatd);
    assert_eq!(sample(&states, r#"ecat_slaves{state="PREOP"}"#), 1.0);
    // The change is in the log at the default level (info), with the slave and both states.
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    let changed = loop {
        let line = ecatd
            .log()
            .lines()
            .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
            .find(|v| {
                v["fields"]["message"] == "slave state changed"
                    && v["fields"]["position"] == 1
                    && v["fields"]["from"] == "OP"
                    && v["fields"]["to"] == "PREOP"
            });
        if let Some(line) = line {
            break line;
        }
        assert!(std::time::Instant::now() < deadline, "{}", ecatd.log());
        // Poll interval of the log reader; the loop ends on the line or the deadline.
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(changed["level"], "INFO", "{changed}");
    assert_eq!(
        sample(&states, r#"ecat_slaves{state="OP"}"#),
        topology.slaves.len() as f64 - 1.0
    );
    assert!(sample(&states, "ecat_bus_frames_sent_total") > 0.0);
    assert_eq!(
        sample(&states, "ecat_bus_thread_realtime"),
        0.0,
        "no rt_priority configured"
    );
    let slice = sample(&states, "ecat_bus_thread_time_slice_seconds");
    assert!(
        (0.0..=0.1).contains(&slice),
        "a fair-scheduler slice (at most 100 ms) or none: {slice}"
    );
    let lost = sample(&states, "ecat_bus_frames_lost_total");
    if server_support::on_veth() {
        // Over veth a loaded machine can hold ecat-sim past the response timeout now and
        // then; such frames are counted lost and sent again, so only the bound is known.
        assert!(lost < sample(&states, "ecat_bus_frames_sent_total"));
    } else {
        assert_eq!(lost, 0.0, "the in-process link loses nothing");
    }
    assert_eq!(
        sample(&states, r#"ecat_slave_al_status_code{station="1001"}"#),
        0.0
    );
    // The AL state as its register value: position 1 (station 1002) in PREOP (2), the
    // others in OP (8).
    assert_eq!(
        sample(&states, r#"ecat_slave_al_state{station="1002"}"#),
        2.0
    );
    assert_eq!(
        sample(&states, r#"ecat_slave_al_state{station="1001"}"#),
        8.0
    );
    // Per-slave series carry the station only; names and identities join from
    // ecat_slave_info.
    let first = &topology.slaves[0];
    assert_eq!(
        sample(
            &states,
            &format!(
                r#"ecat_slave_info{{station="1001",position="0",alias="{}",name="{}",vendor_id="0x{:08x}",product_code="0x{:08x}",revision="0x{:08x}"}}"#,
                first.alias, first.name, first.vendor_id, first.product_code, first.revision
            )
        ),
        1.0
    );
    assert_eq!(
        states
            .lines()
            .filter(|l| l.starts_with("ecat_slave_info{"))
            .count(),
        topology.slaves.len()
    );
    assert_eq!(sample(&states, "ecat_ready"), 1.0);
    assert_eq!(sample(&states, "ecat_link_up"), 1.0);
}

/// An ETG.8200 datagram: the SDO upload request of `index`:`subindex` for `address`.
fn upload_request(address: u16, counter: u8, index: u16, subindex: u8) -> Vec<u8> {
    let coe = CoeRepr::SdoRequest(SdoRequest::InitiateUpload {
        index,
        subindex,
        complete_access: false,
    });
    let data = coe.to_vec().expect("emit CoE");
    let repr = GatewayRepr {
        header: MailboxHeader {
            length: data.len() as u16,
            address,
            channel: 0,
            priority: 0,
            mailbox_type: MailboxType::Coe,
            counter,
        },
        data: &data,
    };
    repr.to_vec().expect("emit gateway message")
}

#[test]
fn gateway_counters_equal_the_datagrams_sent() {
    let ecatd = Ecatd::start(&[]);
    let gateway = ecatd.gateway_addr();
    let before = scrape(&ecatd);
    assert_eq!(sample(&before, "ecat_mailbox_gateway_up"), 1.0);
    assert_eq!(
        sample(
            &before,
            &format!(r#"ecat_mailbox_gateway_info{{port="{}"}}"#, gateway.port())
        ),
        1.0
    );
    let client = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).expect("client socket");
    client
        .set_read_timeout(Some(Duration::from_secs(10)))
        .expect("timeout");
    // Five uploads of the CoE store's identity (station 1004), each answered.
    let vendor = Topology::default_segment().slaves[3].vendor_id;
    let mut answer = [0u8; 1500];
    for counter in 1..=5u8 {
        client
            .send_to(&upload_request(1004, counter, 0x1018, 1), gateway)
            .expect("send");
        let (len, from) = client.recv_from(&mut answer).expect("an answer");
        assert_eq!(from, gateway);
        let reply = GatewayMessage::new_checked(&answer[..len]).expect("a gateway message");
        let reply = GatewayRepr::parse(&reply).expect("parse");
        assert_eq!(reply.header.address, 1004);
        // Expedited upload response: 2 CoE + 4 SDO header bytes, then the value.
        assert_eq!(reply.data[6..10], vendor.to_le_bytes());
    }
    // Three malformed datagrams: counted as failed, never answered.
    for junk in [&[0x01u8][..], &[0xFF; 7][..], &[0x10, 0x10, 0, 0][..]] {
        client.send_to(junk, gateway).expect("send");
    }
    // Counters move when the gateway has handled the datagrams: wait for that.
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    let after = loop {
        let text = scrape(&ecatd);
        if sample(&text, "ecat_mailbox_gateway_requests_total") >= 8.0
            || std::time::Instant::now() > deadline
        {
            break text;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(sample(&after, "ecat_mailbox_gateway_requests_total"), 8.0);
    assert_eq!(
        sample(&after, "ecat_mailbox_gateway_forwarded_requests_total"),
        5.0
    );
    assert_eq!(
        sample(&after, "ecat_mailbox_gateway_failed_requests_total"),
        3.0
    );
    assert_eq!(
        sample(
            &after,
            r#"ecat_mailbox_gateway_protocol_requests_total{protocol="coe"}"#
        ),
        5.0
    );
    assert_eq!(
        sample(
            &after,
            r#"ecat_mailbox_gateway_failures_total{reason="malformed"}"#
        ),
        3.0
    );
    // Every request is timed: the answered ones and the failed ones apart.
    assert_eq!(
        sample(
            &after,
            r#"ecat_mailbox_gateway_request_duration_seconds_count{outcome="answered"}"#
        ),
        5.0
    );
    assert_eq!(
        sample(
            &after,
            r#"ecat_mailbox_gateway_request_duration_seconds_count{outcome="failed"}"#
        ),
        3.0
    );
    assert_eq!(
        sample(
            &after,
            r#"ecat_mailbox_gateway_request_duration_seconds_bucket{outcome="failed",le="+Inf"}"#
        ),
        3.0
    );
    // Eight datagrams fit the receive queue: the kernel dropped none (read from /proc).
    assert_eq!(
        sample(&after, "ecat_mailbox_gateway_dropped_datagrams_total"),
        0.0
    );
}

fn rest(ecatd: &Ecatd, method: &str, path: &str, body: Option<&str>) -> (u16, String) {
    let url = format!("{}{path}", ecatd.http);
    let mut args = vec!["-s", "-X", method];
    if let Some(body) = body {
        args.extend(["-H", "content-type: application/json", "-d", body]);
    }
    args.push(&url);
    curl(&args)
}

#[test]
fn protocol_counters_equal_the_requests_made() {
    let ecatd = Ecatd::start(&[]);
    let topology = Topology::default_segment();
    let drive = &topology.slaves[0];
    let series = |name: &str, station: &str, protocol: &str| {
        format!(r#"{name}{{station="{station}",protocol="{protocol}"}}"#)
    };
    // The drive (station 1001): CoE 4 good + 2 aborted, SoE 3 good + 1 refused write,
    // FoE 1 read, VoE 2; the EoE port (station 1005): 1 IP read.
    for _ in 0..4 {
        let (status, _) = rest(&ecatd, "GET", "/api/v1/slaves/0/coe/sdo/0x1018/1", None);
        assert_eq!(status, 200);
    }
    for _ in 0..2 {
        let (status, _) = rest(&ecatd, "GET", "/api/v1/slaves/0/coe/sdo/0x5fff/0", None);
        assert_eq!(status, 404);
    }
    for _ in 0..3 {
        let (status, _) = rest(&ecatd, "GET", "/api/v1/slaves/0/soe/0/0x8064", None);
        assert_eq!(status, 200);
    }
    let (status, _) = rest(
        &ecatd,
        "PUT",
        "/api/v1/slaves/0/soe/0/0x8064",
        Some(r#"{"data":"0100"}"#),
    );
    assert_eq!(status, 409, "the motor temperature is read-only");
    let (status, _) = rest(&ecatd, "GET", "/api/v1/slaves/0/foe/firmware.bin", None);
    assert_eq!(status, 200);
    let voe = format!(
        r#"{{"vendor_id":{},"vendor_type":1,"data":"00"}}"#,
        drive.voe_vendor_id.unwrap_or(drive.vendor_id)
    );
    for _ in 0..2 {
        let (status, _) = rest(&ecatd, "POST", "/api/v1/slaves/0/voe", Some(&voe));
        assert_eq!(status, 200);
    }
    let (status, _) = rest(&ecatd, "GET", "/api/v1/slaves/4/eoe/ip", None);
    assert_eq!(status, 200);

    let text = scrape(&ecatd);
    // No Ethernet frame was asked of either EoE slave (only IP parameters), but the host's
    // own stack may send some through an interface that comes up (IPv6 multicast listener
    // reports, router solicitations; how many depends on the machine's sysctls). So: each
    // slave's frame and byte counters are there, what the slaves got all came through the
    // interfaces, and nothing came back (the simulated EoE slaves answer no such frame).
    // The interfaces' side is the kernel's count, read after the scrape: the kernel counts
    // a frame when ecatd reads it from the TAP, before the mailbox sends it and counts it,
    // so the comparison cannot race a frame in flight.
    let through_interfaces: u64 = text
        .lines()
        .filter_map(|l| l.strip_prefix(r#"ecat_eoe_interface_tx_frames_total{interface=""#))
        .filter_map(|l| l.split_once('"').map(|(name, _)| name))
        .map(|name| {
            let path = format!("/sys/class/net/{name}/statistics/tx_packets");
            let count = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
            count.trim().parse::<u64>().expect("a count")
        })
        .sum();
    let mut sent = 0.0;
    for station in ["1001", "1005"] {
        let series = |name: &str| sample(&text, &format!(r#"{name}{{station="{station}"}}"#));
        let frames = series("ecat_eoe_frames_sent_total");
        assert!(
            series("ecat_eoe_sent_bytes_total") >= 14.0 * frames,
            "each frame counted with at least its Ethernet header ({station})"
        );
        sent += frames;
        assert_eq!(series("ecat_eoe_received_bytes_total"), 0.0, "{station}");
    }
    assert!(
        sent <= through_interfaces as f64,
        "{sent} frames reached the EoE slaves, {through_interfaces} left the interfaces"
    );
    let expect = [
        ("1001", "coe", 6.0, 2.0),
        ("1001", "soe", 4.0, 1.0),
        ("1001", "foe", 1.0, 0.0),
        ("1001", "voe", 2.0, 0.0),
        ("1005", "eoe", 1.0, 0.0),
    ];
    for (station, protocol, requests, errors) in expect {
        let got = |name| sample(&text, &series(name, station, protocol));
        assert_eq!(
            got("ecat_mailbox_protocol_requests_total"),
            requests,
            "{station} {protocol}"
        );
        assert_eq!(
            got("ecat_mailbox_protocol_errors_total"),
            errors,
            "{station} {protocol}"
        );
        assert_eq!(got("ecat_mailbox_protocol_timeouts_total"), 0.0);
    }
    // Nothing else was asked of any mailbox through the APIs.
    let total: f64 = text
        .lines()
        .filter(|l| l.starts_with("ecat_mailbox_protocol_requests_total{"))
        .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
        .sum();
    assert_eq!(total, 14.0);
    assert_eq!(
        sample(
            &text,
            r#"ecat_mailbox_protocol_request_duration_seconds_count{protocol="coe"}"#
        ),
        6.0
    );
}

#[test]
fn esc_error_counters_equal_the_registers() {
    let ecatd = Ecatd::start(&[]);
    let (status, body) = rest(&ecatd, "GET", "/api/v1/slaves", None);
    assert_eq!(status, 200);
    let slaves: serde_json::Value = serde_json::from_str(&body).unwrap();
    let slaves = slaves.as_array().expect("a list").clone();
    assert_eq!(slaves.len(), Topology::default_segment().slaves.len());
    // The background reader runs once a second: wait until every slave shows up.
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    let text = loop {
        let text = scrape(&ecatd);
        let seen = text
            .lines()
            .filter(|l| l.starts_with("ecat_slave_esc_pdi_errors{"))
            .count();
        if seen == slaves.len() {
            break text;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "ESC counters missing:\n{text}"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    for slave in &slaves {
        let position = slave["position"].as_u64().unwrap();
        let station = slave["station"].as_u64().unwrap();
        let (status, body) = rest(
            &ecatd,
            "GET",
            &format!("/api/v1/slaves/{position}/registers/0x0300?length=20"),
            None,
        );
        assert_eq!(status, 200, "{body}");
        let data = serde_json::from_str::<serde_json::Value>(&body).unwrap()["data"]
            .as_str()
            .unwrap()
            .to_owned();
        let block: Vec<u8> = (0..data.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&data[i..i + 2], 16).unwrap())
            .collect();
        assert_eq!(block.len(), 20);
        let labels = format!(r#"station="{station}""#);
        for port in 0..4 {
            let port_labels = format!(r#"{{{labels},port="{port}"}}"#);
            let check = |family: &str, value: u8| {
                assert_eq!(
                    sample(&text, &format!("{family}{port_labels}")),
                    f64::from(value),
                    "{family} {port_labels}"
                );
            };
            check("ecat_slave_esc_invalid_frames", block[2 * port]);
            check("ecat_slave_esc_rx_errors", block[2 * port + 1]);
            check("ecat_slave_esc_forwarded_rx_errors", block[8 + port]);
            check("ecat_slave_esc_lost_links", block[0x10 + port]);
        }
        assert_eq!(
            sample(
                &text,
                &format!("ecat_slave_esc_processing_unit_errors{{{labels}}}")
            ),
            f64::from(block[0x0C])
        );
        assert_eq!(
            sample(&text, &format!("ecat_slave_esc_pdi_errors{{{labels}}}")),
            f64::from(block[0x0D])
        );
    }
    assert_eq!(sample(&text, "ecat_slave_esc_read_failures_total"), 0.0);
}
