//! The gateway's own answers (docs/gateway.md, spec-notes §gateway.dialect): unknown addresses,
//! protocols a slave does not serve, messages larger than its mailbox, strict mode, clients
//! outside the allowlist, malformed datagrams — each counted under its reason.

use crate::gateway_support;

use std::time::Duration;

use gateway_support::master_support::wait_until;
use gateway_support::{
    COE_STORE, Client, DO8, DRIVE, GwRig, Reply, allowing, datagram, sdo, station, test_config,
};
use master_core::gateway::{GatewayConfig, MailboxGatewayStats};
use master_core::wire::Emit;
use master_core::wire::coe::{AbortCode, SdoRequest, SdoResponse};
use master_core::wire::foe::{FoeError, FoePacket, FoeRepr};
use master_core::wire::mailbox::{ErrorReply, ErrorReplyRepr, MailboxErrorCode, MailboxType};
use master_core::wire::soe::{SoeError, SoePacket, SoeRepr};

fn upload(index: u16, subindex: u8) -> Vec<u8> {
    sdo(SdoRequest::InitiateUpload {
        index,
        subindex,
        complete_access: false,
    })
}

fn abort_of(reply: &Reply) -> (u16, u8, AbortCode) {
    match reply.sdo() {
        SdoResponse::Abort {
            index,
            subindex,
            code,
        } => (index, subindex, code),
        other => panic!("not an abort: {other:?}"),
    }
}

fn mailbox_error_of(reply: &Reply) -> MailboxErrorCode {
    assert_eq!(reply.header.mailbox_type, MailboxType::Error, "{reply:?}");
    let view = ErrorReply::new_checked(&reply.data[..]).unwrap();
    ErrorReplyRepr::parse(&view).unwrap().detail
}

fn foe_error_of(reply: &Reply) -> FoeError {
    assert_eq!(reply.header.mailbox_type, MailboxType::Foe, "{reply:?}");
    match FoeRepr::parse(&FoePacket::new_checked(&reply.data[..]).unwrap()).unwrap() {
        FoeRepr::Error { code, .. } => code,
        other => panic!("not an FoE error: {other:?}"),
    }
}

fn soe_error_of(reply: &Reply) -> SoeError {
    assert_eq!(reply.header.mailbox_type, MailboxType::Soe, "{reply:?}");
    let repr = SoeRepr::parse(&SoePacket::new_checked(&reply.data[..]).unwrap()).unwrap();
    repr.error.expect("SoE error bit")
}

fn foe_read(name: &[u8]) -> Vec<u8> {
    let repr = FoeRepr::ReadRequest {
        password: 0,
        file_name: name,
    };
    repr.to_vec().unwrap()
}

/// SoE read of S-0-0030 (manufacturer version), value element.
const SOE_READ: [u8; 4] = [0x01, 0x40, 0x1E, 0x00];
const VOE: [u8; 8] = [0x64, 0x11, 0, 0, 0x01, 0x00, 0xAA, 0x55];

#[test]
fn unknown_addresses_get_each_protocols_not_found_error() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let nowhere = 0x0999;
    let reply = client.request(nowhere, MailboxType::Coe, &upload(0x1018, 1));
    assert_eq!(reply.header.address, nowhere);
    assert_eq!(abort_of(&reply), (0x1018, 1, AbortCode::ObjectDoesNotExist));
    let reply = client.request(nowhere, MailboxType::Foe, &foe_read(b"x"));
    assert_eq!(foe_error_of(&reply), FoeError::NotFound);
    let reply = client.request(nowhere, MailboxType::Soe, &SOE_READ);
    assert_eq!(soe_error_of(&reply), SoeError::NoIdn);
    let reply = client.request(nowhere, MailboxType::Voe, &VOE);
    assert_eq!(
        mailbox_error_of(&reply),
        MailboxErrorCode::UnsupportedProtocol
    );
    // A position beyond the segment is unknown as well.
    let reply = client.request(0x8000 + 40, MailboxType::Coe, &upload(0x1000, 0));
    assert_eq!(abort_of(&reply).2, AbortCode::ObjectDoesNotExist);

    let stats = rig.gateway().stats();
    assert_eq!(stats.failures.unknown_address, 5);
    assert_eq!(stats.failed_requests, 5);
    assert_eq!(stats.forwarded_requests, 0);
    assert_eq!(
        (
            stats.coe_count,
            stats.foe_count,
            stats.soe_count,
            stats.voe_count
        ),
        (2, 1, 1, 1)
    );
}

#[test]
fn protocols_a_slave_does_not_serve_get_their_own_errors() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    // The DO8 has no mailbox at all; the CoE store serves CoE only.
    let reply = client.request(station(DO8), MailboxType::Coe, &upload(0x1018, 1));
    assert_eq!(abort_of(&reply), (0x1018, 1, AbortCode::UnsupportedAccess));
    let store = station(COE_STORE);
    let reply = client.request(store, MailboxType::Soe, &SOE_READ);
    assert_eq!(soe_error_of(&reply), SoeError::from(0x1009));
    let reply = client.request(store, MailboxType::Foe, &foe_read(b"firmware.bin"));
    assert_eq!(foe_error_of(&reply), FoeError::AccessDenied);
    let reply = client.request(store, MailboxType::Voe, &VOE);
    assert_eq!(
        mailbox_error_of(&reply),
        MailboxErrorCode::UnsupportedProtocol
    );
    // The master's own address serves CoE only.
    let reply = client.request(0, MailboxType::Voe, &VOE);
    assert_eq!(reply.header.address, 0);
    assert_eq!(
        mailbox_error_of(&reply),
        MailboxErrorCode::UnsupportedProtocol
    );
    assert_eq!(rig.gateway().stats().failures.unsupported_protocol, 5);
}

#[test]
fn a_message_larger_than_the_slaves_mailbox_is_refused() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    // The drive's receive mailbox holds 128 bytes: 122 of data.
    let mut voe = VOE.to_vec();
    voe.resize(123, 0xEE);
    let reply = client.request(station(DRIVE), MailboxType::Voe, &voe);
    assert_eq!(mailbox_error_of(&reply), MailboxErrorCode::InvalidSize);
    // One byte less goes through (the drive echoes VoE).
    voe.truncate(122);
    let reply = client.request(station(DRIVE), MailboxType::Voe, &voe);
    assert_eq!(reply.header.mailbox_type, MailboxType::Voe);
    let stats = rig.gateway().stats();
    assert_eq!((stats.failures.oversized, stats.forwarded_requests), (1, 1));
}

#[test]
fn strict_mode_answers_no_errors_but_still_relays_the_slaves() {
    let rig = GwRig::start(GatewayConfig {
        strict: true,
        ..test_config()
    });
    let mut client = rig.client();
    client.send(0x0999, MailboxType::Coe, &upload(0x1018, 1));
    client.send(station(DO8), MailboxType::Coe, &upload(0x1018, 1));
    // The slave's own abort is relayed.
    let reply = client.request(station(COE_STORE), MailboxType::Coe, &upload(0x5555, 0));
    assert_eq!(abort_of(&reply), (0x5555, 0, AbortCode::ObjectDoesNotExist));
    // Loopback keeps order and the failures were handled first: nothing else came.
    assert!(client.recv_within(Duration::from_millis(50)).is_none());
    let stats = rig.gateway().stats();
    assert_eq!((stats.failed_requests, stats.forwarded_requests), (2, 1));
}

fn wait_for(rig: &GwRig, what: &str, check: impl Fn(&MailboxGatewayStats) -> bool) {
    assert!(
        wait_until(|| check(&rig.gateway().stats())),
        "{what}: {:?}",
        rig.gateway().stats()
    );
}

#[test]
fn clients_outside_the_allowlist_are_dropped_and_counted() {
    let rig = GwRig::start(allowing("10.0.0.0/8"));
    let mut client = rig.client();
    client.send(station(COE_STORE), MailboxType::Coe, &upload(0x1018, 1));
    wait_for(&rig, "denied", |s| s.failures.denied == 1);
    assert!(client.recv_within(Duration::from_millis(50)).is_none());
    let stats = rig.gateway().stats();
    assert_eq!((stats.total_requests, stats.failed_requests), (1, 1));
    assert_eq!(stats.coe_count, 0, "a denied datagram is not even parsed");

    // Loopback (the default) lets the same client in.
    let rig = GwRig::start(allowing("127.0.0.0/8"));
    let mut client = Client::new(rig.addr());
    let reply = client.request(station(COE_STORE), MailboxType::Coe, &upload(0x1018, 1));
    assert!(matches!(reply.sdo(), SdoResponse::InitiateUpload { .. }));
}

#[test]
fn malformed_datagrams_are_counted_and_never_answered() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let good = datagram(station(COE_STORE), MailboxType::Coe, 1, &upload(0x1018, 1));
    let mut wrong_type = good.clone();
    wrong_type[1] = 0x10;
    let mut long_mailbox = good.clone();
    long_mailbox[2] = 0x40;
    let mut ecat_mismatch = good.clone();
    ecat_mismatch[0] = 0x11;
    let bad: Vec<Vec<u8>> = vec![
        Vec::new(),
        vec![0x10],
        good[..7].to_vec(),
        wrong_type,
        long_mailbox,
        ecat_mismatch,
        vec![0xFF; 3000],
    ];
    for datagram in &bad {
        client.send_raw(datagram);
    }
    wait_for(&rig, "malformed", |s| {
        s.failures.malformed == bad.len() as u64
    });
    assert!(client.recv_within(Duration::from_millis(50)).is_none());
    let reply = client.request(station(COE_STORE), MailboxType::Coe, &upload(0x1018, 1));
    assert!(matches!(reply.sdo(), SdoResponse::InitiateUpload { .. }));
    let stats = rig.gateway().stats();
    assert_eq!(stats.total_requests, bad.len() as u64 + 1);
    assert_eq!(stats.failed_requests, bad.len() as u64);
}
