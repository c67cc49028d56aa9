//! The gateway as a service: the port of master number n, the fallback when it is taken,
//! stop and restart, and broadcast requests.

use crate::gateway_support;

use std::collections::BTreeMap;
use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::time::Duration;

use gateway_support::{COE_STORE, Client, GwRig, sdo, station, test_config};
use master_core::gateway::{BROADCAST_ADDRESS, DEFAULT_PORT, GatewayConfig};
use master_core::wire::coe::{SdoPayload, SdoRequest, SdoResponse};
use master_core::wire::mailbox::MailboxType;
use sim::topology::Protocol;

fn upload(index: u16, subindex: u8) -> Vec<u8> {
    sdo(SdoRequest::InitiateUpload {
        index,
        subindex,
        complete_access: false,
    })
}

/// A loopback UDP port above the gateway's default that is free right now.
fn free_port_above_default() -> u16 {
    for _ in 0..1000 {
        let probe = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).expect("probe");
        let port = probe.local_addr().unwrap().port();
        if port > DEFAULT_PORT {
            return port;
        }
    }
    panic!("no free port above {DEFAULT_PORT}");
}

fn serves(addr: SocketAddr) -> bool {
    let mut client = Client::new(addr);
    let reply = client.request(station(COE_STORE), MailboxType::Coe, &upload(0x1018, 1));
    matches!(reply.sdo(), SdoResponse::InitiateUpload { .. })
}

#[test]
fn the_port_follows_the_master_number() {
    let port = free_port_above_default();
    let rig = GwRig::start(GatewayConfig {
        port: None,
        master_number: port - DEFAULT_PORT + 1,
        ..test_config()
    });
    assert_eq!(rig.gateway().port(), port);
    assert_eq!(rig.gateway().stats().port, port);
    assert!(serves(rig.addr()));
}

#[test]
fn a_taken_port_falls_back_to_a_free_one_or_fails_without_fallback() {
    let blocker = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).expect("blocker");
    let taken = blocker.local_addr().unwrap().port();
    let mut rig = GwRig::start(GatewayConfig {
        port: Some(taken),
        ..test_config()
    });
    let bound = rig.gateway().port();
    assert_ne!(bound, taken);
    assert_eq!(rig.addr().port(), bound);
    assert_eq!(rig.gateway().stats().port, bound);
    assert!(serves(rig.addr()));

    let gateway = rig.gateway_mut();
    gateway.stop();
    gateway.config_mut().fallback = false;
    gateway.set_port(taken);
    let err = gateway.start().unwrap_err();
    assert_eq!(err.kind(), std::io::ErrorKind::AddrInUse);
    assert!(!gateway.is_running());
    drop(blocker);
}

#[test]
fn stop_releases_the_port_and_a_restart_serves_again() {
    let mut rig = GwRig::start(test_config());
    let addr = rig.addr();
    assert!(serves(addr));
    assert!(rig.gateway().is_running());

    rig.gateway_mut().stop();
    assert!(!rig.gateway().is_running());
    assert_eq!(rig.gateway().local_addr(), None);
    let stats = rig.gateway().stats();
    assert_eq!((stats.started_at_ms, stats.port), (0, 0));
    assert_eq!(
        stats.total_requests, 1,
        "counters stay readable after a stop"
    );
    // The port is free again.
    drop(UdpSocket::bind(addr).expect("the port was released"));

    rig.gateway_mut().set_port(addr.port());
    let again = rig.gateway_mut().start().expect("restart");
    assert_eq!(again, addr);
    assert!(rig.gateway().is_running());
    assert_eq!(rig.gateway().stats().total_requests, 0, "a start zeroes");
    assert!(serves(addr));
    assert_eq!(rig.gateway().stats().forwarded_requests, 1);
}

#[test]
fn a_broadcast_reaches_every_slave_serving_the_protocol_one_datagram_each() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let coe_slaves: BTreeMap<u16, u32> = rig
        .topology
        .slaves
        .iter()
        .enumerate()
        .filter(|(_, s)| s.protocols.contains(&Protocol::Coe))
        .map(|(p, s)| (station(p), s.product_code))
        .collect();
    assert!(coe_slaves.len() >= 2);
    client.send(BROADCAST_ADDRESS, MailboxType::Coe, &upload(0x1018, 2));
    let mut answers = BTreeMap::new();
    for _ in 0..coe_slaves.len() {
        let reply = client.recv();
        let product = match reply.sdo() {
            SdoResponse::InitiateUpload {
                payload: SdoPayload::Expedited(value),
                ..
            } => u32::from_le_bytes(value.try_into().unwrap()),
            other => panic!("{other:?}"),
        };
        assert!(
            answers.insert(reply.header.address, product).is_none(),
            "one answer per slave"
        );
    }
    assert_eq!(answers, coe_slaves);
    assert!(client.recv_within(Duration::from_millis(50)).is_none());
    let stats = rig.gateway().stats();
    assert_eq!((stats.total_requests, stats.forwarded_requests), (1, 1));
}
