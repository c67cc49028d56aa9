//! ecatd's `/metrics`: `promtool check metrics` reports nothing, and the counters and gauges
//! equal what the test did (uploads good and bad, a state change).

mod server_support;

use std::io::Write;
use std::net::{Ipv4Addr, UdpSocket};
use std::process::{Command, Stdio};
use std::time::Duration;

use master_core::wire::coe::sdo_request::SdoRequest;
use master_core::wire::coe::{CoeFrame, CoeRepr};
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
        assert_eq!(status, 409);
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
    assert_eq!(
        sample(&states, r#"ecat_slaves{state="OP"}"#),
        topology.slaves.len() as f64 - 1.0
    );
    assert!(sample(&states, "ecat_bus_frames_sent_total") > 0.0);
    let lost = sample(&states, "ecat_bus_frames_lost_total");
    if server_support::on_veth() {
        // Over veth a loaded machine can hold ecat-sim past the response timeout now and
        // then; such frames are counted lost and sent again, so only the bound is known.
        assert!(lost < sample(&states, "ecat_bus_frames_sent_total"));
    } else {
        assert_eq!(lost, 0.0, "the in-process link loses nothing");
    }
    let name = &topology.slaves[0].name;
    assert_eq!(
        sample(
            &states,
            &format!(r#"ecat_slave_al_status_code{{position="0",station="1001",name="{name}"}}"#)
        ),
        0.0
    );
}

/// An ETG.8200 datagram: the SDO upload request of `index`:`subindex` for `address`.
fn upload_request(address: u16, counter: u8, index: u16, subindex: u8) -> Vec<u8> {
    let coe = CoeRepr::SdoRequest(SdoRequest::InitiateUpload {
        index,
        subindex,
        complete_access: false,
    });
    let mut data = vec![0u8; coe.buffer_len()];
    coe.emit(&mut CoeFrame::new_unchecked(&mut data[..]))
        .expect("emit CoE");
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
    let mut out = vec![0u8; repr.buffer_len()];
    repr.emit(&mut GatewayMessage::new_unchecked(&mut out[..]))
        .expect("emit gateway message");
    out
}

#[test]
fn gateway_counters_equal_the_datagrams_sent() {
    let ecatd = Ecatd::start(&[]);
    let gateway = ecatd.gateway_addr();
    let before = scrape(&ecatd);
    assert_eq!(sample(&before, "ecat_mailbox_gateway_up"), 1.0);
    assert_eq!(
        sample(&before, "ecat_mailbox_gateway_port"),
        f64::from(gateway.port())
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
}
