//! Issue 15, item 2: a UDP request repeated by its client (same bytes, same counter 1-7,
//! nothing in between) within the retry window is answered from the stored reply and not
//! executed again; counted on the simulated slave (how often the object or file was
//! written) and in `retries_answered`.

use crate::gateway_support;

use std::time::{Duration, Instant};

use gateway_support::{Client, DRIVE, GwRig, PATIENCE, datagram, sdo, station, test_config};
use master_core::gateway::GatewayConfig;
use master_core::wire::coe::{SdoPayload, SdoRequest};
use master_core::wire::foe::{FoePacket, FoeRepr};
use master_core::wire::mailbox::MailboxType;

const OBJECT: u16 = 0x6040;

fn config(window: Duration) -> GatewayConfig {
    GatewayConfig {
        retry_window: window,
        ..test_config()
    }
}

fn download(value: u16) -> Vec<u8> {
    sdo(SdoRequest::InitiateDownload {
        index: OBJECT,
        subindex: 0,
        complete_access: false,
        payload: SdoPayload::Expedited(&value.to_le_bytes()),
    })
}

fn writes(rig: &GwRig) -> u32 {
    rig.handles[DRIVE]
        .dictionary
        .as_ref()
        .expect("CoE")
        .lock()
        .unwrap()
        .write_count(OBJECT)
}

/// Sends `bytes` and returns the whole reply datagram's mailbox data.
fn exchange(client: &Client, bytes: &[u8]) -> Vec<u8> {
    client.send_raw(bytes);
    client.recv().data
}

#[test]
fn a_download_sent_two_and_three_times_within_the_window_runs_once() {
    let rig = GwRig::start(config(Duration::from_secs(30)));
    let client = rig.client();
    let before = writes(&rig);
    let message = datagram(station(DRIVE), MailboxType::Coe, 3, &download(6));
    let first = exchange(&client, &message);
    assert_eq!(writes(&rig), before + 1);
    assert_eq!(exchange(&client, &message), first, "the stored reply");
    assert_eq!(writes(&rig), before + 1, "twice: written once");
    assert_eq!(exchange(&client, &message), first);
    assert_eq!(writes(&rig), before + 1, "three times: written once");
    let stats = rig.gateway().stats();
    assert_eq!(stats.retries_answered, 2);
    assert_eq!(stats.forwarded_requests, 1);
}

#[test]
fn a_repeat_after_the_window_runs_again() {
    let window = Duration::from_millis(50);
    let rig = GwRig::start(config(window));
    let client = rig.client();
    let before = writes(&rig);
    let message = datagram(station(DRIVE), MailboxType::Coe, 4, &download(7));
    exchange(&client, &message);
    assert_eq!(writes(&rig), before + 1);
    // Repeat until the window has passed and the request runs again: every repeat within
    // the window is answered from the store, the first one after it is executed.
    let deadline = Instant::now() + PATIENCE;
    let mut repeats = 0u64;
    while writes(&rig) == before + 1 {
        assert!(Instant::now() < deadline, "never executed again");
        exchange(&client, &message);
        repeats += 1;
    }
    assert_eq!(writes(&rig), before + 2, "written twice");
    let stats = rig.gateway().stats();
    assert_eq!(stats.retries_answered, repeats - 1);
    assert_eq!(stats.forwarded_requests, 2);
}

#[test]
fn counter_zero_other_bytes_and_requests_in_between_run_again() {
    let rig = GwRig::start(config(Duration::from_secs(30)));
    let client = rig.client();
    let before = writes(&rig);
    let addr = station(DRIVE);
    // Counter 0: never a repeat.
    let zero = datagram(addr, MailboxType::Coe, 0, &download(1));
    exchange(&client, &zero);
    exchange(&client, &zero);
    assert_eq!(writes(&rig), before + 2);
    // Same counter, other bytes.
    exchange(&client, &datagram(addr, MailboxType::Coe, 1, &download(1)));
    exchange(&client, &datagram(addr, MailboxType::Coe, 1, &download(2)));
    assert_eq!(writes(&rig), before + 4);
    // The same request with another in between.
    let again = datagram(addr, MailboxType::Coe, 2, &download(3));
    exchange(&client, &again);
    let upload = sdo(SdoRequest::InitiateUpload {
        index: OBJECT,
        subindex: 0,
        complete_access: false,
    });
    exchange(&client, &datagram(addr, MailboxType::Coe, 3, &upload));
    exchange(&client, &again);
    assert_eq!(writes(&rig), before + 6);
    // Another client sending the same bytes is another client.
    let other = rig.client();
    exchange(&other, &again);
    assert_eq!(writes(&rig), before + 7);
    assert_eq!(rig.gateway().stats().retries_answered, 0);
}

fn foe(repr: FoeRepr<'_>) -> Vec<u8> {
    let mut out = vec![0u8; repr.buffer_len()];
    repr.emit(&mut FoePacket::new_unchecked(&mut out[..]))
        .expect("emit");
    out
}

#[test]
fn an_foe_write_request_and_its_data_repeated_run_once() {
    let rig = GwRig::start(config(Duration::from_secs(30)));
    let client = rig.client();
    let store = rig.handles[DRIVE].files.as_ref().expect("FoE store");
    let (requests, commits) = (store.write_requests(), store.commits());
    let addr = station(DRIVE);
    let wrq = datagram(
        addr,
        MailboxType::Foe,
        1,
        &foe(FoeRepr::WriteRequest {
            password: 0,
            file_name: b"retry.bin",
        }),
    );
    let ack0 = exchange(&client, &wrq);
    assert_eq!(exchange(&client, &wrq), ack0, "the stored ACK 0");
    assert_eq!(exchange(&client, &wrq), ack0);
    assert_eq!(
        store.write_requests(),
        requests + 1,
        "one write request reached the slave"
    );
    let data = datagram(
        addr,
        MailboxType::Foe,
        2,
        &foe(FoeRepr::Data {
            packet: 1,
            data: b"once",
        }),
    );
    let ack1 = exchange(&client, &data);
    assert_eq!(
        FoeRepr::parse(&FoePacket::new_checked(&ack1[..]).unwrap()).unwrap(),
        FoeRepr::Ack { packet: 1 }
    );
    assert_eq!(
        exchange(&client, &data),
        ack1,
        "the repeat gets the ACK, not an error"
    );
    assert_eq!(store.commits(), commits + 1, "stored once");
    assert_eq!(store.data("retry.bin").as_deref(), Some(&b"once"[..]));
    assert_eq!(rig.gateway().stats().retries_answered, 3);
}

#[test]
fn repeats_are_off_with_a_zero_window() {
    let rig = GwRig::start(config(Duration::ZERO));
    let client = rig.client();
    let before = writes(&rig);
    let message = datagram(station(DRIVE), MailboxType::Coe, 3, &download(6));
    exchange(&client, &message);
    exchange(&client, &message);
    assert_eq!(writes(&rig), before + 2);
}
