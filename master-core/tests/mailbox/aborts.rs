//! SDO aborts as other slave stacks send them (ETG.1000.6 §5.6.2.7), against simulated
//! slaves with the firmware switches of `sim::topology::EscSpec`: in CoE service 2 (SOES),
//! with the request's low command bits left set, behind a slow firmware. Every refusal
//! must come back as the slave's abort after one request/answer exchange (one message
//! written), never as a timeout; late replies of earlier requests are dropped and counted,
//! never taken for the next request (the API and the raw path the gateway uses).

use crate::mailbox_support;

use std::time::Duration;

use mailbox_support::{COE_STORE, DRIVE, Rig, bus_config};
use master_core::link::FaultConfig;
use master_core::mailbox::{MailboxConfig, MailboxError, SlaveMailbox};
use master_core::wire::coe::sdo::SdoFrame;
use master_core::wire::coe::{AbortCode, SdoRequest, SdoResponse};
use master_core::wire::mailbox::{HEADER_LEN, MailboxType};
use master_core::wire::soe::{ElementFlags, Idn};
use sim::topology::{CoeObject, EscSpec, Topology};

/// An object the store has that only takes writes.
const WRITE_ONLY: u16 = 0x2F00;
/// An object nobody may write.
const READ_ONLY: u16 = 0x2F01;
/// A 32-bit parameter (the default store's).
const PARAMETER: u16 = 0x2001;
/// An object no slave has.
const MISSING: u16 = 0x5555;

/// The default segment, the CoE store with `esc`'s firmware switches and the objects the
/// refusals need.
fn topology(esc: EscSpec) -> Topology {
    let mut topology = Topology::default_segment();
    let store = &mut topology.slaves[COE_STORE];
    store.esc = esc;
    store
        .objects
        .push(CoeObject::unsigned32(WRITE_ONLY, "wo", "Write only"));
    store
        .objects
        .push(CoeObject::unsigned32(READ_ONLY, "ro", "Read only"));
    topology
}

/// A SOES-like stack: wrong lengths are one mismatch code, no complete access.
fn soes_like(in_request: bool, keep_bits: bool, delay_us: u32) -> EscSpec {
    EscSpec {
        sdo_abort_in_request: in_request,
        sdo_abort_keeps_command_bits: keep_bits,
        sdo_abort_length_mismatch: true,
        refuse_complete_access: true,
        response_delay_us: delay_us,
        ..EscSpec::default()
    }
}

fn rig(esc: EscSpec) -> Rig {
    Rig::start(&topology(esc), FaultConfig::default(), 1, bus_config())
}

/// Runs `request` and checks that it failed with the slave's abort `code` for
/// `index:subindex` after exactly one message written and with nothing dropped.
async fn expect_abort<T: std::fmt::Debug>(
    store: &SlaveMailbox,
    what: &str,
    index: u16,
    subindex: u8,
    code: AbortCode,
    request: impl std::future::Future<Output = Result<T, MailboxError>>,
) {
    let before = store.stats();
    let err = request.await.expect_err(what);
    assert_eq!(
        err,
        MailboxError::SdoAbort {
            index,
            subindex,
            code
        },
        "{what}"
    );
    let after = store.stats();
    assert_eq!(
        after.writes - before.writes,
        1,
        "{what}: one request written"
    );
    assert_eq!(
        after.unexpected, before.unexpected,
        "{what}: nothing dropped"
    );
}

async fn every_refusal(store: &SlaveMailbox) {
    expect_abort(
        store,
        "upload of a missing object",
        MISSING,
        0,
        AbortCode::ObjectDoesNotExist,
        store.sdo_upload(MISSING, 0),
    )
    .await;
    expect_abort(
        store,
        "read of a write-only object",
        WRITE_ONLY,
        0,
        AbortCode::WriteOnly,
        store.sdo_upload(WRITE_ONLY, 0),
    )
    .await;
    expect_abort(
        store,
        "write of a read-only object",
        READ_ONLY,
        0,
        AbortCode::ReadOnly,
        store.sdo_download(READ_ONLY, 0, &[1, 2, 3, 4]),
    )
    .await;
    expect_abort(
        store,
        "download of the wrong length",
        PARAMETER,
        0,
        AbortCode::LengthMismatch,
        store.sdo_download(PARAMETER, 0, &[1, 2]),
    )
    .await;
    expect_abort(
        store,
        "complete-access upload",
        0x1018,
        0,
        AbortCode::GeneralError,
        store.sdo_upload_complete(0x1018, 0),
    )
    .await;
    // The same refusals of a normal (not expedited) download and a complete-access one.
    expect_abort(
        store,
        "normal download to a read-only object",
        READ_ONLY,
        0,
        AbortCode::ReadOnly,
        store.sdo_download(READ_ONLY, 0, &[1, 2, 3, 4, 5, 6, 7, 8]),
    )
    .await;
    expect_abort(
        store,
        "complete-access download",
        0x1018,
        1,
        AbortCode::GeneralError,
        store.sdo_download_complete(0x1018, 1, &[0; 16]),
    )
    .await;
    // The slave's SDO server is idle again: a plain request still works.
    assert_eq!(store.sdo_upload(READ_ONLY, 0).await.unwrap(), [0; 4]);
}

#[tokio::test]
async fn aborts_in_service_3_with_0x80() {
    let rig = rig(soes_like(false, false, 0));
    every_refusal(&rig.slave(COE_STORE)).await;
}

#[tokio::test]
async fn aborts_in_service_2_as_soes_sends_them() {
    let rig = rig(soes_like(true, false, 0));
    every_refusal(&rig.slave(COE_STORE)).await;
}

#[tokio::test]
async fn aborts_with_the_request_low_bits_left_set() {
    let rig = rig(soes_like(false, true, 0));
    every_refusal(&rig.slave(COE_STORE)).await;
}

#[tokio::test]
async fn aborts_in_service_2_with_low_bits_from_a_slow_firmware() {
    let rig = rig(soes_like(true, true, 3_000));
    every_refusal(&rig.slave(COE_STORE)).await;
}

#[tokio::test]
async fn the_sim_sends_the_abort_bytes_the_switches_ask_for() {
    let rig = rig(soes_like(true, true, 0));
    let store = rig.slave(COE_STORE);
    // Initiate upload 0x5555:00 (command 0x40) through the raw path: the answer as sent.
    let answer = store
        .raw(MailboxType::Coe, &upload_request(MISSING, 0))
        .await
        .unwrap();
    let data = &answer.message()[HEADER_LEN..];
    assert_eq!(
        data[..3],
        [0x00, 0x20, 0x80],
        "service 2, 0x80 | 0x40 & 0x1f"
    );
    assert_eq!(data[6..10], 0x0602_0000u32.to_le_bytes());
    // A download of 2 bytes (0x2b) keeps its low bits: 0x8b.
    let download = [0x00, 0x20, 0x2b, 0x01, 0x20, 0x00, 1, 2, 0, 0];
    let answer = store.raw(MailboxType::Coe, &download).await.unwrap();
    assert_eq!(answer.message()[HEADER_LEN..][..3], [0x00, 0x20, 0x8b]);
    assert_eq!(
        answer.message()[HEADER_LEN + 6..],
        0x0607_0010u32.to_le_bytes()
    );
}

#[tokio::test]
async fn an_abort_of_a_segment_reaches_the_raw_path() {
    let rig = rig(soes_like(true, true, 0));
    let store = rig.slave(COE_STORE);
    // 0x2000 is long: a normal upload, then segments; the first segment with the wrong
    // toggle bit (set: 0x70) is refused with 0x05030000, in service 2, 0x80 | 0x10.
    let first = store
        .raw(MailboxType::Coe, &upload_request(0x2000, 0))
        .await
        .unwrap();
    assert_eq!(
        first.message()[HEADER_LEN + 2],
        0x41,
        "a normal upload response"
    );
    let wrong_toggle = [0x00, 0x20, 0x70, 0, 0, 0, 0, 0, 0, 0];
    let answer = store.raw(MailboxType::Coe, &wrong_toggle).await.unwrap();
    let frame = SdoFrame::new_checked(&answer.message()[HEADER_LEN..]).unwrap();
    assert_eq!(answer.message()[HEADER_LEN..][..3], [0x00, 0x20, 0x90]);
    assert_eq!(frame.any_abort().map(|a| a.2), Some(AbortCode::ToggleBit));
}

#[tokio::test]
async fn an_sdo_info_error_without_its_code_is_typed_not_internal() {
    let esc = EscSpec {
        sdo_info_short_errors: true,
        ..EscSpec::default()
    };
    let rig = rig(esc);
    let store = rig.slave(COE_STORE);
    let err = store.sdo_info_entry(MISSING, 0, 0).await.unwrap_err();
    assert!(
        matches!(err, MailboxError::SdoInfoAbortMissing { .. }),
        "{err:?}"
    );
    assert!(
        err.to_string()
            .contains("SDO Information error (abort code missing)"),
        "{err}"
    );
    let err = store.sdo_info_object(MISSING).await.unwrap_err();
    assert!(
        matches!(err, MailboxError::SdoInfoAbortMissing { .. }),
        "{err:?}"
    );
    // A plain upload then gets the slave's own abort.
    let err = store.sdo_upload(MISSING, 0).await.unwrap_err();
    assert_eq!(
        err,
        MailboxError::SdoAbort {
            index: MISSING,
            subindex: 0,
            code: AbortCode::ObjectDoesNotExist
        }
    );
}

fn upload_request(index: u16, subindex: u8) -> Vec<u8> {
    let request = SdoRequest::InitiateUpload {
        index,
        subindex,
        complete_access: false,
    };
    let mut data = vec![0u8; request.buffer_len()];
    request
        .emit(&mut SdoFrame::new_unchecked(&mut data[..]))
        .unwrap();
    data
}

/// A slave that answers after 150 ms and a first request that gives up after 20 ms: its
/// answer comes while the next request waits.
fn slow_rig() -> Rig {
    let esc = EscSpec {
        response_delay_us: 150_000,
        ..EscSpec::default()
    };
    let mut topology = topology(esc);
    topology.slaves[DRIVE].esc = esc;
    let mailbox = MailboxConfig {
        timeout: Duration::from_secs(3),
        ..MailboxConfig::default()
    };
    Rig::start_with(
        &topology,
        FaultConfig::default(),
        1,
        bus_config(),
        mailbox,
        |_, _| {},
    )
}

#[tokio::test]
async fn a_late_reply_of_another_index_is_dropped_and_counted_not_taken() {
    let rig = slow_rig();
    let store = rig.slave(COE_STORE);
    let hasty = store.with_timeout(Duration::from_millis(20));
    let err = hasty.sdo_upload(READ_ONLY, 0).await.unwrap_err();
    assert!(matches!(err, MailboxError::Timeout { .. }), "{err:?}");
    let before = store.stats().unexpected;
    // The late answer (0x2F01, value 0) arrives first; the parameter's own comes after it.
    let value = store.sdo_upload(PARAMETER, 0).await.unwrap();
    assert_eq!(value, 0x1234_5678u32.to_le_bytes());
    assert_eq!(
        store.stats().unexpected - before,
        1,
        "the late answer counted"
    );
}

#[tokio::test]
async fn a_late_reply_is_never_the_answer_on_the_raw_path() {
    let rig = slow_rig();
    let store = rig.slave(COE_STORE);
    let hasty = store.with_timeout(Duration::from_millis(20));
    let err = hasty
        .raw(MailboxType::Coe, &upload_request(READ_ONLY, 0))
        .await
        .unwrap_err();
    assert!(matches!(err, MailboxError::Timeout { .. }), "{err:?}");
    let before = store.stats().unexpected;
    let answer = store
        .raw(MailboxType::Coe, &upload_request(PARAMETER, 0))
        .await
        .unwrap();
    let frame = SdoFrame::new_checked(&answer.message()[HEADER_LEN..]).unwrap();
    match SdoResponse::parse(&frame).unwrap() {
        SdoResponse::InitiateUpload {
            index, subindex, ..
        } => assert_eq!((index, subindex), (PARAMETER, 0)),
        other => panic!("not the parameter's answer: {other}"),
    }
    assert_eq!(frame.data_field(), 0x1234_5678u32.to_le_bytes());
    assert_eq!(
        store.stats().unexpected - before,
        1,
        "the late answer counted"
    );
}

#[tokio::test]
async fn a_late_entry_description_of_another_object_is_not_the_answer() {
    let rig = slow_rig();
    let store = rig.slave(COE_STORE);
    let hasty = store.with_timeout(Duration::from_millis(20));
    assert!(matches!(
        hasty.sdo_info_entry(READ_ONLY, 0, 0).await,
        Err(MailboxError::Timeout { .. })
    ));
    let before = store.stats().unexpected;
    let entry = store.sdo_info_entry(PARAMETER, 0, 0).await.unwrap();
    assert_eq!((entry.index, entry.subindex), (PARAMETER, 0));
    assert_eq!(
        store.stats().unexpected - before,
        1,
        "the late answer counted"
    );
}

#[tokio::test]
async fn a_late_soe_answer_of_another_idn_is_not_the_answer() {
    let rig = slow_rig();
    let drive = rig.slave(DRIVE);
    let value = ElementFlags::VALUE;
    // S-0-0024 (configuration list of MDT) as the drive answers it in time.
    let mdt = Idn::from_raw(24);
    let expected = drive.soe_read(0, mdt, value).await.unwrap();
    let hasty = drive.with_timeout(Duration::from_millis(20));
    // S-0-0016 (configuration list of AT) gives up; its answer comes while the next waits.
    let err = hasty
        .soe_read(0, Idn::from_raw(16), value)
        .await
        .unwrap_err();
    assert!(matches!(err, MailboxError::Timeout { .. }), "{err:?}");
    let before = drive.stats().unexpected;
    assert_eq!(drive.soe_read(0, mdt, value).await.unwrap(), expected);
    assert_eq!(
        drive.stats().unexpected - before,
        1,
        "the late answer counted"
    );
}
