//! SoE, FoE and VoE through the gateway: SoE values read and written in fragments (every
//! read fragment its own datagram), a 1 MiB FoE file written and read back packet by
//! packet by the client with the same SHA-256, the VoE echo.

use crate::gateway_support;

use gateway_support::{Client, DRIVE, GwRig, station, test_config};
use master_core::master::SlaveAddress;
use master_core::wire::Emit;
use master_core::wire::foe::{self, FoePacket, FoeRepr};
use master_core::wire::mailbox::MailboxType;
use master_core::wire::register::AlState;
use master_core::wire::soe::{
    ElementFlags, Idn, IdnOrFragments, SoeOpcode, SoePacket, SoeRepr, fragment_capacity,
};
use master_core::wire::voe::{VoePacket, VoeRepr};
use sha2::{Digest, Sha256};
use sim::device::soe::defaults::{MANUFACTURER_VERSION, MANUFACTURER_VERSION_TEXT};
use sim::device::voe::VoeEcho;
use sim::topology::Topology;

const MIB: usize = 1 << 20;

fn soe(repr: &SoeRepr<'_>) -> Vec<u8> {
    repr.to_vec().unwrap()
}

fn foe_msg(repr: FoeRepr<'_>) -> Vec<u8> {
    repr.to_vec().unwrap()
}

/// A list element: current length, maximum length, contents.
fn list(contents: &[u8], max: u16) -> Vec<u8> {
    let mut out = (contents.len() as u16).to_le_bytes().to_vec();
    out.extend_from_slice(&max.to_le_bytes());
    out.extend_from_slice(contents);
    out
}

/// Reads an IDN's value; returns it and the number of datagrams it came in.
fn soe_read(client: &mut Client, address: u16, idn: u16) -> (Vec<u8>, usize) {
    let request = soe(&SoeRepr {
        opcode: SoeOpcode::ReadRequest,
        drive: 0,
        elements: ElementFlags::VALUE,
        idn_or_fragments: IdnOrFragments::Idn(Idn::from_raw(idn)),
        error: None,
        data: &[],
    });
    client.send(address, MailboxType::Soe, &request);
    let mut value = Vec::new();
    let mut datagrams = 0;
    loop {
        let reply = client.recv();
        datagrams += 1;
        let repr = SoeRepr::parse(&SoePacket::new_checked(&reply.data[..]).unwrap()).unwrap();
        assert_eq!(repr.opcode, SoeOpcode::ReadResponse);
        assert_eq!(repr.error, None);
        value.extend_from_slice(repr.data);
        if let IdnOrFragments::Idn(_) = repr.idn_or_fragments {
            return (value, datagrams);
        }
    }
}

fn small_mailbox_drive() -> GwRig {
    let mut topology = Topology::default_segment();
    let mailbox = topology.slaves[DRIVE].mailbox.as_mut().unwrap();
    mailbox.rx_size = 32;
    mailbox.tx_size = 32;
    GwRig::with_topology(topology, test_config())
}

#[test]
fn soe_values_are_read_and_written_in_fragments() {
    let rig = small_mailbox_drive();
    let mut client = rig.client();
    let address = station(DRIVE);
    // S-0-0030: a 58-character text, 62 bytes, 22 a fragment: three datagrams.
    let (value, datagrams) = soe_read(&mut client, address, MANUFACTURER_VERSION);
    assert_eq!(value, list(MANUFACTURER_VERSION_TEXT.as_bytes(), 64));
    assert_eq!(datagrams, value.len().div_ceil(fragment_capacity(32)));
    assert_eq!(datagrams, 3);

    // S-0-0024 (MDT list, writable in PREOP), 36 bytes: the client sends two fragments,
    // only the last is answered.
    let drive = SlaveAddress::Position(DRIVE as u16);
    gateway_support::block_on(rig.master().request_state(drive, AlState::PreOp)).unwrap();
    let idns: Vec<u8> = (1..=16u16)
        .flat_map(|i| (0x0100 + i).to_le_bytes())
        .collect();
    let written = list(&idns, 32);
    let cut = fragment_capacity(32);
    let first = soe(&SoeRepr {
        opcode: SoeOpcode::WriteRequest,
        drive: 0,
        elements: ElementFlags::VALUE,
        idn_or_fragments: IdnOrFragments::FragmentsLeft(1),
        error: None,
        data: &written[..cut],
    });
    let last = soe(&SoeRepr {
        opcode: SoeOpcode::WriteRequest,
        drive: 0,
        elements: ElementFlags::VALUE,
        idn_or_fragments: IdnOrFragments::Idn(Idn::from_raw(24)),
        error: None,
        data: &written[cut..],
    });
    client.send(address, MailboxType::Soe, &first);
    let reply = client.request(address, MailboxType::Soe, &last);
    let repr = SoeRepr::parse(&SoePacket::new_checked(&reply.data[..]).unwrap()).unwrap();
    assert_eq!((repr.opcode, repr.error), (SoeOpcode::WriteResponse, None));
    assert_eq!(soe_read(&mut client, address, 24).0, written);
    assert_eq!(rig.gateway().stats().soe_count, 4);
}

#[test]
fn the_topologys_idn_is_read_through_the_gateway() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let spec = &rig.topology.slaves[DRIVE].idns[0];
    let (value, datagrams) = soe_read(&mut client, station(DRIVE), spec.idn);
    assert_eq!(Some(value), spec.value.clone());
    assert_eq!(datagrams, 1);
}

fn file(len: usize) -> Vec<u8> {
    let mut state = 0x9E37_79B9u32;
    (0..len)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as u8
        })
        .collect()
}

/// Writes `content` to `name` the way an FoE client does, one datagram per packet; a
/// packet shorter than the slave's mailbox holds (empty if need be) is the last.
fn foe_write(client: &mut Client, address: u16, name: &str, content: &[u8], mailbox: usize) {
    let ack_of = |reply: &gateway_support::Reply| match FoeRepr::parse(
        &FoePacket::new_checked(&reply.data[..]).unwrap(),
    )
    .unwrap()
    {
        FoeRepr::Ack { packet } => packet,
        other => panic!("{other:?}"),
    };
    let wrq = foe_msg(FoeRepr::WriteRequest {
        password: 0,
        file_name: name.as_bytes(),
    });
    assert_eq!(ack_of(&client.request(address, MailboxType::Foe, &wrq)), 0);
    let step = foe::max_data(mailbox);
    let mut packet = 1u32;
    let mut sent = 0usize;
    loop {
        let end = (sent + step).min(content.len());
        let data = foe_msg(FoeRepr::Data {
            packet,
            data: &content[sent..end],
        });
        let reply = client.request(address, MailboxType::Foe, &data);
        assert_eq!(ack_of(&reply), packet);
        if end - sent < step {
            return;
        }
        sent = end;
        packet += 1;
    }
}

/// Reads `name` packet by packet; the last ACK gets no answer.
fn foe_read(client: &mut Client, address: u16, name: &str, mailbox: usize) -> Vec<u8> {
    let rrq = foe_msg(FoeRepr::ReadRequest {
        password: 0,
        file_name: name.as_bytes(),
    });
    let mut reply = client.request(address, MailboxType::Foe, &rrq);
    let full = foe::max_data(mailbox);
    let mut content = Vec::new();
    loop {
        let (packet, data) =
            match FoeRepr::parse(&FoePacket::new_checked(&reply.data[..]).unwrap()).unwrap() {
                FoeRepr::Data { packet, data } => (packet, data.to_vec()),
                other => panic!("{other:?}"),
            };
        content.extend_from_slice(&data);
        let ack = foe_msg(FoeRepr::Ack { packet });
        if data.len() < full {
            client.send(address, MailboxType::Foe, &ack);
            return content;
        }
        reply = client.request(address, MailboxType::Foe, &ack);
    }
}

#[test]
fn a_1_mib_file_goes_both_ways_with_the_same_sha256() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let address = station(DRIVE);
    let content = file(MIB);
    foe_write(&mut client, address, "firmware.bin", &content, 128);
    let store = rig.handles[DRIVE].files.as_ref().expect("FoE store");
    assert_eq!(
        Sha256::digest(store.data("firmware.bin").unwrap()),
        Sha256::digest(&content),
        "the slave stored the file"
    );
    let back = foe_read(&mut client, address, "firmware.bin", 128);
    assert_eq!(back.len(), MIB);
    assert_eq!(Sha256::digest(&back), Sha256::digest(&content));
    // Another read right after: the final ACK left the slave and the session clean.
    let again = foe_read(&mut client, address, "firmware.bin", 128);
    assert_eq!(Sha256::digest(&again), Sha256::digest(&content));
    let stats = rig.gateway().stats();
    assert_eq!(stats.failed_requests, 0);
    assert_eq!(stats.foe_count, stats.total_requests);
}

#[test]
fn voe_is_echoed_through_the_gateway() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let data: Vec<u8> = (0..100u8).collect();
    let repr = VoeRepr {
        vendor_id: 0x1164,
        vendor_type: 0x0042,
        data: &data,
    };
    let request = repr.to_vec().unwrap();
    let reply = client.request(station(DRIVE), MailboxType::Voe, &request);
    assert_eq!(reply.header.mailbox_type, MailboxType::Voe);
    let answer = VoeRepr::parse(&VoePacket::new_checked(&reply.data[..]).unwrap()).unwrap();
    assert_eq!((answer.vendor_id, answer.vendor_type), (0x1164, 0x0042));
    assert_eq!(answer.data, VoeEcho::transform(&data));
    assert_eq!(rig.gateway().stats().voe_count, 1);
}
