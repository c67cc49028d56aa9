//! The optional TCP transport: gateway messages on a byte stream, delimited by the
//! EtherCAT header's length, served by the same request handling as UDP (routing, stats,
//! allowlist), with UDP still served beside it.

use crate::gateway_support;

use std::io::{ErrorKind, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpStream};

use gateway_support::master_support::wait_until;
use gateway_support::{DRIVE, GwRig, PATIENCE, allowing, datagram, sdo, station, test_config};
use master_core::gateway::GatewayConfig;
use master_core::wire::coe::{SdoPayload, SdoRequest, SdoResponse};
use master_core::wire::gateway::{GatewayMessage, GatewayRepr};
use master_core::wire::mailbox::{MailboxHeader, MailboxType};

fn tcp_config() -> GatewayConfig {
    GatewayConfig {
        tcp: true,
        ..test_config()
    }
}

/// A message reading `0x1018:subindex` of the slave at `address`.
fn identity_upload(address: u16, subindex: u8, counter: u8) -> Vec<u8> {
    let request = sdo(SdoRequest::InitiateUpload {
        index: 0x1018,
        subindex,
        complete_access: false,
    });
    datagram(address, MailboxType::Coe, counter, &request)
}

fn connect(addr: SocketAddr) -> TcpStream {
    let stream = TcpStream::connect(addr).expect("TCP connect");
    stream.set_read_timeout(Some(PATIENCE)).expect("timeout");
    stream.set_nodelay(true).expect("nodelay");
    stream
}

/// Reads one message from the stream the way a client must: 2-byte header, then its
/// length.
fn read_message(stream: &mut TcpStream) -> (MailboxHeader, Vec<u8>) {
    let mut header = [0u8; 2];
    stream.read_exact(&mut header).expect("reply header");
    let length = usize::from(u16::from_le_bytes(header) & 0x07FF);
    let mut message = header.to_vec();
    message.resize(2 + length, 0);
    stream.read_exact(&mut message[2..]).expect("reply body");
    let view = GatewayMessage::new_checked(&message[..]).expect("reply parses");
    let repr = GatewayRepr::parse(&view).expect("reply parses");
    (repr.header, repr.data.to_vec())
}

/// The expedited value of an SDO upload reply, with the index and subindex it names.
fn uploaded(data: &[u8]) -> (u16, u8, Vec<u8>) {
    let frame = master_core::wire::coe::SdoFrame::new_checked(data).expect("SDO");
    match SdoResponse::parse(&frame).expect("SDO response") {
        SdoResponse::InitiateUpload {
            index,
            subindex,
            payload: SdoPayload::Expedited(value),
            ..
        } => (index, subindex, value.to_vec()),
        other => panic!("unexpected {other:?}"),
    }
}

/// The simulator's own 0x1018:subindex of the drive.
fn drive_identity(rig: &GwRig, subindex: u8) -> u32 {
    rig.handles[DRIVE]
        .dictionary
        .as_ref()
        .expect("the drive has CoE")
        .lock()
        .unwrap()
        .get::<u32>(0x1018, subindex)
        .expect("identity")
}

/// Whether the server closed the connection (end of stream or reset) before `PATIENCE`.
fn closed_by_server(stream: &mut TcpStream) -> bool {
    let mut buf = [0u8; 64];
    match stream.read(&mut buf) {
        Ok(0) => true,
        Ok(n) => panic!("unexpected {n} bytes"),
        Err(e) => matches!(
            e.kind(),
            ErrorKind::ConnectionReset | ErrorKind::ConnectionAborted | ErrorKind::BrokenPipe
        ),
    }
}

#[test]
fn coe_upload_over_tcp() {
    let rig = GwRig::start(tcp_config());
    let mut stream = connect(rig.addr());
    let address = station(DRIVE);
    stream.write_all(&identity_upload(address, 1, 3)).unwrap();
    let (header, data) = read_message(&mut stream);
    assert_eq!(header.address, address);
    assert_eq!(header.mailbox_type, MailboxType::Coe);
    let (index, subindex, value) = uploaded(&data);
    assert_eq!((index, subindex), (0x1018, 1));
    assert_eq!(
        u32::from_le_bytes(value.try_into().unwrap()),
        drive_identity(&rig, 1)
    );
    // Counted like a UDP request.
    let stats = rig.gateway().stats();
    assert_eq!(
        (stats.total_requests, stats.coe_count, stats.failed_requests),
        (1, 1, 0)
    );
    assert!(wait_until(|| rig.gateway().stats().forwarded_requests == 1));
}

#[test]
fn messages_are_cut_from_the_stream_by_their_length() {
    let rig = GwRig::start(tcp_config());
    let mut stream = connect(rig.addr());
    let address = station(DRIVE);
    // Two messages in one write: both answered, in order.
    let mut both = identity_upload(address, 1, 1);
    both.extend_from_slice(&identity_upload(address, 2, 2));
    stream.write_all(&both).unwrap();
    for subindex in [1u8, 2] {
        let (_, data) = read_message(&mut stream);
        let (index, sub, value) = uploaded(&data);
        assert_eq!((index, sub), (0x1018, subindex));
        assert_eq!(
            u32::from_le_bytes(value.try_into().unwrap()),
            drive_identity(&rig, subindex)
        );
    }
    // One message split inside its header, the next one inside its body.
    let third = identity_upload(address, 3, 3);
    let fourth = identity_upload(address, 4, 4);
    stream.write_all(&third[..1]).unwrap();
    stream.flush().unwrap();
    stream.write_all(&third[1..]).unwrap();
    stream.write_all(&fourth[..9]).unwrap();
    stream.flush().unwrap();
    stream.write_all(&fourth[9..]).unwrap();
    for subindex in [3u8, 4] {
        let (_, data) = read_message(&mut stream);
        let (_, sub, value) = uploaded(&data);
        assert_eq!(sub, subindex);
        assert_eq!(
            u32::from_le_bytes(value.try_into().unwrap()),
            drive_identity(&rig, subindex)
        );
    }
    assert_eq!(rig.gateway().stats().coe_count, 4);
}

#[test]
fn a_malformed_length_closes_the_connection_and_is_counted() {
    let rig = GwRig::start(tcp_config());
    // EtherCAT type 1 (datagrams), not 5.
    let mut wrong_type = connect(rig.addr());
    wrong_type.write_all(&[0x10, 0x10]).unwrap();
    assert!(closed_by_server(&mut wrong_type));
    // Type 5 but shorter than a mailbox header.
    let mut too_short = connect(rig.addr());
    too_short.write_all(&[0x03, 0x50, 1, 2, 3]).unwrap();
    assert!(closed_by_server(&mut too_short));
    // EtherCAT length and mailbox length disagree: the stream is out of step.
    let mut good = identity_upload(station(DRIVE), 1, 1);
    good[2] += 1; // mailbox length one more than the EtherCAT length says
    let mut mismatch = connect(rig.addr());
    mismatch.write_all(&good).unwrap();
    assert!(closed_by_server(&mut mismatch));
    assert!(wait_until(|| rig.gateway().stats().failures.malformed == 3));
    let stats = rig.gateway().stats();
    assert_eq!((stats.total_requests, stats.failed_requests), (3, 3));
    // Other connections are served meanwhile.
    let mut fine = connect(rig.addr());
    fine.write_all(&identity_upload(station(DRIVE), 1, 1))
        .unwrap();
    let (_, data) = read_message(&mut fine);
    assert_eq!(uploaded(&data).1, 1);
}

#[test]
fn clients_outside_the_allowlist_are_refused_over_tcp() {
    let rig = GwRig::start(GatewayConfig {
        tcp: true,
        ..allowing("10.0.0.0/8")
    });
    let mut stream = connect(rig.addr());
    // A request may or may not be written before the server closes; no reply either way.
    let _ = stream.write_all(&identity_upload(station(DRIVE), 1, 1));
    assert!(closed_by_server(&mut stream));
    assert!(wait_until(|| rig.gateway().stats().failures.denied == 1));
    let stats = rig.gateway().stats();
    assert_eq!((stats.coe_count, stats.forwarded_requests), (0, 0));
}

#[test]
fn udp_is_still_served_with_tcp_on() {
    let rig = GwRig::start(tcp_config());
    let mut client = rig.client();
    let value = client
        .upload(station(DRIVE), 0x1018, 1)
        .expect("UDP upload");
    assert_eq!(
        u32::from_le_bytes(value.try_into().unwrap()),
        drive_identity(&rig, 1)
    );
    // Both on one port number; a TCP client that closes its side ends its connection.
    let mut stream = connect(rig.addr());
    stream
        .write_all(&identity_upload(station(DRIVE), 2, 1))
        .unwrap();
    let (_, data) = read_message(&mut stream);
    assert_eq!(uploaded(&data).1, 2);
    stream.shutdown(Shutdown::Write).unwrap();
    assert!(closed_by_server(&mut stream));
    assert_eq!(rig.gateway().stats().coe_count, 2);
}

#[test]
fn tcp_is_off_by_default() {
    let rig = GwRig::start(test_config());
    assert!(TcpStream::connect(rig.addr()).is_err());
}
