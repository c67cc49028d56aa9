//! Issue 15, item 3, in process: a client whose network has the `read` role can read
//! everything (uploads, SDO Information, SoE and FoE reads, the master's dictionary) and is
//! refused every kind of write with its protocol's access error, counted `denied`, in both
//! layouts; nothing reaches the slave. (The audit lines and ecatd's configuration are
//! checked through the ecatd process in `tests/tests/server/gateway_roles.rs`.)

use crate::gateway_support;

use crate::compat_client;

use std::time::Duration;

use compat_client::CompatClient;
use gateway_support::{DRIVE, EOE_PORT, GwRig, Reply, allowing_as, sdo, station};
use master_core::gateway::GatewayRole;
use master_core::wire::coe::info::SdoInfoService;
use master_core::wire::coe::{AbortCode, SdoPayload, SdoRequest, SdoResponse};
use master_core::wire::foe::{FoeError, FoePacket, FoeRepr};
use master_core::wire::mailbox::{ErrorReply, ErrorReplyRepr, MailboxErrorCode, MailboxType};
use master_core::wire::soe::{SoeError, SoePacket, SoeRepr};

fn foe(repr: FoeRepr<'_>) -> Vec<u8> {
    let mut out = vec![0u8; repr.buffer_len()];
    repr.emit(&mut FoePacket::new_unchecked(&mut out[..]))
        .expect("emit");
    out
}

fn download(index: u16, subindex: u8, value: &[u8]) -> Vec<u8> {
    sdo(SdoRequest::InitiateDownload {
        index,
        subindex,
        complete_access: false,
        payload: SdoPayload::Expedited(value),
    })
}

fn abort_code(reply: &Reply) -> (u16, u8, AbortCode) {
    match reply.sdo() {
        SdoResponse::Abort {
            index,
            subindex,
            code,
        } => (index, subindex, code),
        other => panic!("not an abort: {other:?}"),
    }
}

fn mailbox_error(reply: &Reply) -> MailboxErrorCode {
    assert_eq!(reply.header.mailbox_type, MailboxType::Error, "{reply:?}");
    ErrorReplyRepr::parse(&ErrorReply::new_checked(&reply.data[..]).unwrap())
        .unwrap()
        .detail
}

#[test]
fn a_read_client_reads_everything_and_is_refused_every_write() {
    let rig = GwRig::start(allowing_as("127.0.0.0/8", GatewayRole::Read));
    let mut client = rig.client();
    let drive = station(DRIVE);
    let dict = rig.handles[DRIVE].dictionary.as_ref().expect("CoE");
    let writes = || dict.lock().unwrap().write_count(0x6040);
    let before = writes();
    // Reads.
    assert_eq!(client.upload(drive, 0x6040, 0).expect("upload").len(), 2);
    assert!(
        client.upload(0, 0x1018, 1).is_ok(),
        "master dictionary read"
    );
    let list = client.request(
        drive,
        MailboxType::Coe,
        &gateway_support::info(SdoInfoService::OdListRequest {
            list_type: master_core::wire::coe::info::od_list::OdListType::All,
        }),
    );
    assert_eq!(list.header.mailbox_type, MailboxType::Coe);
    let soe = client.request(drive, MailboxType::Soe, &[0x01, 0x40, 0x20, 0x00]);
    let repr = SoeRepr::parse(&SoePacket::new_checked(&soe.data[..]).unwrap()).unwrap();
    assert_eq!((repr.error, repr.data.len()), (None, 4));
    let rrq = foe(FoeRepr::ReadRequest {
        password: 0,
        file_name: b"firmware.bin",
    });
    let data = client.request(drive, MailboxType::Foe, &rrq);
    assert!(matches!(
        FoeRepr::parse(&FoePacket::new_checked(&data.data[..]).unwrap()).unwrap(),
        FoeRepr::Data { packet: 1, .. }
    ));
    // Ending the read (an ERROR from the client) is allowed: it is the client's own read.
    client.send(
        drive,
        MailboxType::Foe,
        &foe(FoeRepr::Error {
            code: FoeError::NotDefined,
            text: b"",
        }),
    );
    // Writes, each refused with its protocol's access error.
    let r = client.request(drive, MailboxType::Coe, &download(0x6040, 0, &[6, 0]));
    assert_eq!(abort_code(&r), (0x6040, 0, AbortCode::ReadOnly));
    let r = client.request(0, MailboxType::Coe, &download(0xF002, 1, &[1, 0]));
    assert_eq!(
        abort_code(&r),
        (0xF002, 1, AbortCode::ReadOnly),
        "no rescan"
    );
    let r = client.request(
        drive,
        MailboxType::Soe,
        &[0x03, 0x40, 0x20, 0x00, 7, 0, 0, 0],
    );
    let repr = SoeRepr::parse(&SoePacket::new_checked(&r.data[..]).unwrap()).unwrap();
    assert_eq!(repr.error, Some(SoeError::DataReadOnly));
    let wrq = foe(FoeRepr::WriteRequest {
        password: 0,
        file_name: b"x.bin",
    });
    let r = client.request(drive, MailboxType::Foe, &wrq);
    assert!(matches!(
        FoeRepr::parse(&FoePacket::new_checked(&r.data[..]).unwrap()).unwrap(),
        FoeRepr::Error {
            code: FoeError::AccessDenied,
            ..
        }
    ));
    let r = client.request(drive, MailboxType::Voe, &[0x64, 0x11, 0, 0, 1, 0, 1]);
    assert_eq!(mailbox_error(&r), MailboxErrorCode::ServiceNotSupported);
    let r = client.request(station(EOE_PORT), MailboxType::Eoe, &[0x03, 0x00, 0, 0]);
    assert_eq!(mailbox_error(&r), MailboxErrorCode::ServiceNotSupported);
    assert_eq!(writes(), before, "nothing written");
    let files = rig.handles[DRIVE].files.as_ref().unwrap();
    assert_eq!(files.write_requests(), 0);
    assert_eq!(rig.gateway().stats().failures.denied, 6);
}

#[test]
fn in_the_manuals_layout_a_read_client_gets_the_manuals_access_codes() {
    let rig = GwRig::start(allowing_as("127.0.0.0/8", GatewayRole::Read));
    let client = CompatClient::new(rig.addr(), Duration::from_secs(10));
    let drive = station(DRIVE);
    let r = client.coe_sdo_read(drive, 0x6040, 0).expect("read");
    assert_eq!(r.data[2] & 0xE0, 0x40, "upload response");
    let r = client
        .coe_sdo_write(drive, 0x6040, 0, &[6, 0])
        .expect("answer");
    assert_eq!(r.data[2], 0x80);
    assert_eq!(r.data[6..10], 0x0601_0002u32.to_le_bytes());
    let r = client
        .soe_write(drive, 32, &1000u32.to_le_bytes(), 0, 5)
        .expect("answer");
    assert_eq!(r.data, [0x12, 0x05, 0x20, 0x00, 0x02, 0x70]);
    let r = client.foe_write(drive, "x.bin").expect("answer");
    assert_eq!(r.data[..5], [0x05, 0x02, 0x80, 0, 0]);
    let r = client.voe_send(drive, 0x1164, 1, &[1]).expect("answer");
    assert_eq!((r.code, r.data), (0, vec![0x01, 0x00, 0x01, 0x00]));
    assert_eq!(rig.gateway().stats().failures.denied, 4);
}

#[test]
fn a_write_client_writes() {
    let rig = GwRig::start(allowing_as("127.0.0.0/8", GatewayRole::Write));
    let mut client = rig.client();
    let r = client.request(
        station(DRIVE),
        MailboxType::Coe,
        &download(0x6040, 0, &[6, 0]),
    );
    assert!(
        matches!(r.sdo(), SdoResponse::InitiateDownload { .. }),
        "{r:?}"
    );
    assert_eq!(rig.gateway().stats().failures.denied, 0);
}
