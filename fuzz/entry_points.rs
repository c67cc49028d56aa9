//! Every fuzz entry point of master-core (the parsers of `master_core::wire`, the gateway's
//! UDP and TCP parsing, the frame matcher, the master dictionary), driven with arbitrary
//! bytes.
//!
//! Shared by the cargo-fuzz targets (`fuzz_targets/*.rs`) and by master-core's corpus replay
//! test (`master-core/tests/checks/fuzz_corpus.rs`), so the seed corpus is exercised in every CI run
//! and a crash found by the fuzzer stays a regression test once its input is added there.
//! Each function must return normally for any input: an `Err` is fine, a panic is the bug.
//! The targets of the simulator and the server call `sim::fuzzing` and `server::fuzzing`
//! directly (replayed by `sim/tests/checks/fuzz_corpus.rs` and `server/tests/checks/fuzz_corpus.rs`).

// Each fuzz target uses one of these functions; the replay test uses them all.
#![allow(dead_code)]

use master_core::wire::datagram::{Datagrams, DatagramsMut};
use master_core::wire::eoe::{EoePacket, EoeRepr, Reassembler};
use master_core::wire::frame::EthercatFrame;
use master_core::wire::gateway::{GatewayMessage, GatewayRepr};
use master_core::wire::mailbox::MailboxMessage;
use master_core::wire::register::{
    al::AlStatusBlock, eeprom::EepromRequest, error_counters::ErrorCounters, fmmu::Fmmu,
    info::EscInfo, sync_manager::SyncManager,
};
use master_core::wire::register::{
    al::AlStatusBlockRepr, eeprom::EepromRequestRepr, error_counters::ErrorCountersRepr,
    fmmu::FmmuRepr, info::EscInfoRepr, sync_manager::SyncManagerRepr,
};
use master_core::wire::sii::image::SiiImage;
use master_core::wire::soe::Idn;

/// An entry point: takes any bytes, must not panic.
pub type EntryPoint = fn(&[u8]);

/// The names of the entry points, as used for corpus folders and fuzz target names.
pub const ALL: &[(&str, EntryPoint)] = &[
    ("frame", frame),
    ("datagrams", datagrams),
    ("mailbox", mailbox),
    ("gateway", gateway),
    ("gateway_service", gateway_service),
    ("sii", sii),
    ("registers", registers),
    ("eoe_reassembly", eoe_reassembly),
    ("idn", idn),
    ("gateway_tcp", gateway_tcp),
    ("frame_matcher", frame_matcher),
    ("master_od", master_od),
];

/// A whole Ethernet frame: parse, walk the datagrams, print everything.
pub fn frame(data: &[u8]) {
    if let Ok(frame) = EthercatFrame::parse(data) {
        if let Ok(datagrams) = frame.datagrams() {
            for datagram in datagrams.flatten() {
                let _ = datagram.to_string();
            }
        }
        let _ = frame.to_string();
    }
}

/// An EtherCAT payload walked as a datagram chain, read-only and in place (as the simulator
/// does).
pub fn datagrams(data: &[u8]) {
    for datagram in Datagrams::new(data) {
        if datagram.is_err() {
            break;
        }
    }
    let mut copy = data.to_vec();
    for datagram in DatagramsMut::new(&mut copy) {
        match datagram {
            Ok(mut d) => {
                let wkc = d.wkc().wrapping_add(1);
                d.set_wkc(wkc);
            }
            Err(_) => break,
        }
    }
}

/// A mailbox message of any type, as read from SM1; what parses must re-emit.
pub fn mailbox(data: &[u8]) {
    if let Ok(message) = MailboxMessage::parse(data) {
        let _ = message.to_string();
        let mut out = vec![0u8; message.buffer_len()];
        message
            .emit(&mut out)
            .expect("a parsed mailbox message re-emits");
    }
}

/// An ETG.8200 gateway UDP payload through every parsing step of the gateway service
/// (tolerance rewrites, transfer tracking, error answers, reply datagrams).
pub fn gateway_service(data: &[u8]) {
    let _ = master_core::gateway::fuzzing::request(data);
}

/// A byte stream on a gateway TCP connection: split into messages by the connection's own
/// reader, each through the service's parsing.
pub fn gateway_tcp(data: &[u8]) {
    let _ = master_core::gateway::fuzzing::tcp_stream(data);
}

/// A frame put in flight, then a returned frame matched against it.
pub fn frame_matcher(data: &[u8]) {
    master_core::bus::fuzzing::reply(data);
}

/// CoE requests (SDO downloads and uploads, SDO Information) served by the master's
/// ETG.1510 dictionary.
pub fn master_od(data: &[u8]) {
    master_core::master_od::fuzzing::requests(data);
}

/// An ETG.8200 gateway UDP payload, then its mailbox.
pub fn gateway(data: &[u8]) {
    if let Ok(message) = GatewayMessage::new_checked(data)
        && let Ok(repr) = GatewayRepr::parse(&message)
    {
        let _ = repr.to_string();
        mailbox(message.mailbox_bytes());
    }
}

/// A whole SII (EEPROM) image: fixed area and every category.
pub fn sii(data: &[u8]) {
    if let Ok(image) = SiiImage::parse(data) {
        let _ = format!("{image:?}");
    }
}

/// Register blocks a master reads from a slave.
pub fn registers(data: &[u8]) {
    if let Ok(v) = AlStatusBlock::new_checked(data) {
        let _ = AlStatusBlockRepr::parse(&v);
    }
    if let Ok(v) = SyncManager::new_checked(data) {
        let _ = SyncManagerRepr::parse(&v);
    }
    if let Ok(v) = Fmmu::new_checked(data) {
        let _ = FmmuRepr::parse(&v);
    }
    if let Ok(v) = EepromRequest::new_checked(data) {
        let _ = EepromRequestRepr::parse(&v);
    }
    if let Ok(v) = EscInfo::new_checked(data) {
        let _ = EscInfoRepr::parse(&v);
    }
    if let Ok(v) = ErrorCounters::new_checked(data) {
        let _ = ErrorCountersRepr::parse(&v);
    }
}

/// A stream of EoE messages (length-prefixed chunks) fed to one reassembler.
pub fn eoe_reassembly(data: &[u8]) {
    let mut reassembler = Reassembler::new(1600);
    let mut rest = data;
    while let Some((&len, tail)) = rest.split_first() {
        let len = usize::from(len).min(tail.len());
        let (chunk, next) = tail.split_at(len);
        rest = next;
        if let Ok(packet) = EoePacket::new_checked(chunk)
            && let Ok(EoeRepr::Fragment(fragment)) = EoeRepr::parse(&packet)
        {
            let _ = reassembler.push(&fragment);
        }
    }
}

/// IDN text as a person types it (`S-0-0024`).
pub fn idn(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(idn) = text.parse::<Idn>()
    {
        assert_eq!(idn.to_string().parse::<Idn>().ok(), Some(idn));
    }
}
