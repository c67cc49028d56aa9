//! The simulated EoE slave: IP parameters, frames in and out in fragments, its endpoint
//! answering ping and ARP (checked with etherparse), and its Ethernet side handed to the
//! host (the host port behind ecat-sim's `--eoe-tap`).

use crate::mailbox_support;

use std::net::Ipv4Addr;

use ecat_wire::Emit;
use ecat_wire::eoe::{
    EoeFrameType, EoePacket, EoeRepr, EoeResult, FragmentRepr, Fragmenter, IpParameters,
    Reassembler,
};
use ecat_wire::mailbox::{MailboxErrorCode, MailboxType};
use etherparse::{
    ArpEthIpv4Packet, ArpOperation, Icmpv4Type, LinkSlice, NetSlice, PacketBuilder, SlicedPacket,
    TransportSlice,
};
use std::time::Duration;

use sim::device::eoe::{EoeService, HostEvent, HostPort, IpConfig};
use sim::device::{Device, MailboxStack, Outbox};

use mailbox_support::{Bench, Reply};

const SLAVE_MAC: [u8; 6] = [0x02, 0x00, 0x00, 0x00, 0x00, 0x10];
const MASTER_MAC: [u8; 6] = [0x02, 0xAA, 0xBB, 0xCC, 0x00, 0x01];
const SLAVE_IP: Ipv4Addr = Ipv4Addr::new(192, 168, 100, 2);
const MASTER_IP: Ipv4Addr = Ipv4Addr::new(192, 168, 100, 1);

fn eoe(repr: &EoeRepr<'_>) -> Vec<u8> {
    repr.to_vec().unwrap()
}

fn parse(reply: &Reply) -> EoeRepr<'_> {
    assert_eq!(reply.header.mailbox_type, MailboxType::Eoe, "{reply:?}");
    EoeRepr::parse(&EoePacket::new_checked(&reply.data[..]).unwrap()).unwrap()
}

fn bench() -> Bench {
    Bench::new(MailboxStack::new().with(EoeService::default()), 128, 128)
}

fn full_params(name: &[u8]) -> IpParameters<'_> {
    IpParameters {
        mac: Some(SLAVE_MAC),
        ip: Some(SLAVE_IP),
        subnet_mask: Some(Ipv4Addr::new(255, 255, 255, 0)),
        default_gateway: Some(MASTER_IP),
        dns_server: Some(Ipv4Addr::new(192, 168, 100, 53)),
        dns_name: Some(name),
    }
}

/// Sets the slave's IP parameters through the mailbox, as `ethercat ip` does.
fn configure(bench: &mut Bench) {
    let set = eoe(&EoeRepr::SetIpRequest {
        port: 0,
        params: full_params(b"drive1"),
    });
    let reply = bench.one(MailboxType::Eoe, &set);
    assert_eq!(
        parse(&reply),
        EoeRepr::SetIpResponse {
            port: 0,
            result: EoeResult::Success
        }
    );
}

/// Sends an Ethernet frame in fragments for SM0; returns every fragment message's replies.
fn send_frame(bench: &mut Bench, frame: &[u8], frame_number: u8) -> (usize, Vec<Reply>) {
    let sm0 = usize::from(bench.ctx.rx_mailbox_size);
    let fragments: Vec<FragmentRepr<'_>> =
        Fragmenter::new(frame, sm0, frame_number).unwrap().collect();
    let mut replies = Vec::new();
    for fragment in &fragments {
        let before = replies.len();
        replies.extend(bench.request(MailboxType::Eoe, &eoe(&EoeRepr::Fragment(*fragment))));
        if !fragment.last {
            assert_eq!(
                replies.len(),
                before,
                "no answer before the frame is complete"
            );
        }
    }
    (fragments.len(), replies)
}

/// Puts the slave's fragments back together into frames.
fn reassemble(replies: &[Reply]) -> Vec<(u8, Vec<u8>)> {
    let mut reassembler = Reassembler::default();
    let mut frames = Vec::new();
    for reply in replies {
        let EoeRepr::Fragment(fragment) = parse(reply) else {
            panic!("fragment expected, got {reply:?}");
        };
        assert!(reply.data.len() <= 128 - 6);
        if let Some(frame) = reassembler.push(&fragment).unwrap() {
            frames.push((frame.frame_number, frame.frame.to_vec()));
        }
    }
    frames
}

#[test]
fn set_ip_then_get_ip_round_trip() {
    let mut bench = bench();
    configure(&mut bench);
    let get = eoe(&EoeRepr::GetIpRequest { port: 0 });
    let reply = bench.one(MailboxType::Eoe, &get);
    assert_eq!(
        parse(&reply),
        EoeRepr::GetIpResponse {
            port: 0,
            result: EoeResult::Success,
            params: full_params(b"drive1"),
        }
    );
    // A later request with only the IP changes only the IP.
    let set = eoe(&EoeRepr::SetIpRequest {
        port: 0,
        params: IpParameters {
            ip: Some(Ipv4Addr::new(10, 0, 0, 9)),
            ..IpParameters::default()
        },
    });
    bench.one(MailboxType::Eoe, &set);
    let config = bench
        .stack
        .service::<EoeService>()
        .unwrap()
        .config()
        .clone();
    assert_eq!(config.ip, Some(Ipv4Addr::new(10, 0, 0, 9)));
    assert_eq!(config.mac, Some(SLAVE_MAC));
    assert_eq!(config.dns_name.as_deref(), Some(&b"drive1"[..]));
}

#[test]
fn get_ip_of_an_unconfigured_slave_is_empty() {
    let mut bench = bench();
    let reply = bench.one(MailboxType::Eoe, &eoe(&EoeRepr::GetIpRequest { port: 0 }));
    assert_eq!(
        parse(&reply),
        EoeRepr::GetIpResponse {
            port: 0,
            result: EoeResult::Success,
            params: IpParameters::default(),
        }
    );
}

#[test]
fn fragmented_ping_gets_an_echo_reply() {
    let mut bench = bench();
    configure(&mut bench);
    let payload = echo_payload(300);
    let request = echo_request(300);
    let (sent, replies) = send_frame(&mut bench, &request, 5);
    assert!(sent >= 3, "the request needs several mailboxes ({sent})");
    assert!(replies.len() >= 3, "so does the reply");
    let frames = reassemble(&replies);
    assert_eq!(frames.len(), 1);
    let (frame_number, frame) = &frames[0];
    assert_eq!(*frame_number, 0, "the slave's first frame");

    let packet = SlicedPacket::from_ethernet(frame).unwrap();
    let Some(LinkSlice::Ethernet2(ethernet)) = &packet.link else {
        panic!("ethernet")
    };
    assert_eq!(
        (ethernet.source(), ethernet.destination()),
        (SLAVE_MAC, MASTER_MAC)
    );
    let Some(NetSlice::Ipv4(ipv4)) = &packet.net else {
        panic!("ipv4")
    };
    let header = ipv4.header();
    assert_eq!(header.source_addr(), SLAVE_IP);
    assert_eq!(header.destination_addr(), MASTER_IP);
    assert_eq!(
        header.header_checksum(),
        header.to_header().calc_header_checksum(),
        "IPv4 checksum"
    );
    let Some(TransportSlice::Icmpv4(icmp)) = &packet.transport else {
        panic!("icmp")
    };
    let Icmpv4Type::EchoReply(echo) = icmp.icmp_type() else {
        panic!("echo reply expected")
    };
    assert_eq!((echo.id, echo.seq), (0x1234, 7));
    assert_eq!(icmp.payload(), &payload[..]);
    assert_eq!(
        icmp.checksum(),
        icmp.icmp_type().calc_checksum(icmp.payload()),
        "ICMP checksum"
    );

    let counters = bench.stack.service::<EoeService>().unwrap().counters();
    assert_eq!(
        (
            counters.frames_in,
            counters.frames_out,
            counters.icmp_replies
        ),
        (1, 1, 1)
    );
}

#[test]
fn arp_request_gets_an_arp_reply() {
    let mut bench = bench();
    configure(&mut bench);
    let request = ArpEthIpv4Packet {
        operation: ArpOperation::REQUEST,
        sender_mac: MASTER_MAC,
        sender_ipv4: MASTER_IP.octets(),
        target_mac: [0; 6],
        target_ipv4: SLAVE_IP.octets(),
    };
    let mut frame = Vec::new();
    PacketBuilder::ethernet2(MASTER_MAC, [0xFF; 6])
        .arp(request.to_arp_packet())
        .write(&mut frame)
        .unwrap();
    let (_, replies) = send_frame(&mut bench, &frame, 0);
    let frames = reassemble(&replies);
    assert_eq!(frames.len(), 1);
    let packet = SlicedPacket::from_ethernet(&frames[0].1).unwrap();
    let Some(LinkSlice::Ethernet2(ethernet)) = &packet.link else {
        panic!("ethernet")
    };
    assert_eq!(
        (ethernet.source(), ethernet.destination()),
        (SLAVE_MAC, MASTER_MAC)
    );
    let Some(NetSlice::Arp(arp)) = &packet.net else {
        panic!("arp")
    };
    let reply = arp.to_packet().try_eth_ipv4().unwrap();
    assert_eq!(
        reply,
        ArpEthIpv4Packet {
            operation: ArpOperation::REPLY,
            sender_mac: SLAVE_MAC,
            sender_ipv4: SLAVE_IP.octets(),
            target_mac: MASTER_MAC,
            target_ipv4: MASTER_IP.octets(),
        }
    );
    // An ARP request for another address is not answered, but still received.
    let other = ArpEthIpv4Packet {
        target_ipv4: [192, 168, 100, 77],
        ..request
    };
    let mut frame = Vec::new();
    PacketBuilder::ethernet2(MASTER_MAC, [0xFF; 6])
        .arp(other.to_arp_packet())
        .write(&mut frame)
        .unwrap();
    let (_, replies) = send_frame(&mut bench, &frame, 1);
    assert!(replies.is_empty());
    let service = bench.stack.service_mut::<EoeService>().unwrap();
    assert_eq!(service.take_received().len(), 2);
    assert_eq!(service.counters().arp_replies, 1);
}

#[test]
fn unconfigured_slave_does_not_answer_ping() {
    let mut bench = bench();
    let mut request = Vec::new();
    PacketBuilder::ethernet2(MASTER_MAC, SLAVE_MAC)
        .ipv4(MASTER_IP.octets(), SLAVE_IP.octets(), 64)
        .icmpv4_echo_request(1, 1)
        .write(&mut request, b"ping")
        .unwrap();
    let (_, replies) = send_frame(&mut bench, &request, 0);
    assert!(replies.is_empty());
}

#[test]
fn queued_frames_go_out_with_increasing_frame_numbers() {
    let mut bench = Bench::new(
        MailboxStack::new().with(EoeService::new(IpConfig::default()).with_endpoint(false)),
        128,
        128,
    );
    let frames: Vec<Vec<u8>> = (0..17u8)
        .map(|i| {
            let mut f = vec![0xFF; 6];
            f.extend_from_slice(&SLAVE_MAC);
            f.extend_from_slice(&[0x88, 0xB5]);
            f.extend((0..200).map(|j| i.wrapping_add(j as u8)));
            f
        })
        .collect();
    let service = bench.stack.service_mut::<EoeService>().unwrap();
    for frame in &frames {
        service.queue_frame(frame.clone()).unwrap();
    }
    let replies = bench.drain();
    let received = reassemble(&replies);
    let numbers: Vec<u8> = received.iter().map(|(n, _)| *n).collect();
    let expected: Vec<u8> = (0..17).map(|n| n % 16).collect();
    assert_eq!(numbers, expected, "frame numbers count mod 16");
    let bodies: Vec<Vec<u8>> = received.into_iter().map(|(_, f)| f).collect();
    assert_eq!(bodies, frames);
}

#[test]
fn filters_unknown_types_and_broken_fragments() {
    // The fixed-layout filter request is 126 bytes: SM0 must hold it.
    let mut bench = Bench::new(MailboxStack::new().with(EoeService::default()), 256, 128);
    let filter = eoe(&EoeRepr::SetAddressFilterRequest {
        port: 0,
        filter: Default::default(),
    });
    assert_eq!(
        parse(&bench.one(MailboxType::Eoe, &filter)),
        EoeRepr::SetAddressFilterResponse {
            port: 0,
            result: EoeResult::NoFilterSupport
        }
    );
    let get_filter = [0x08, 0x00, 0x00, 0x00];
    let reply = bench.one(MailboxType::Eoe, &get_filter);
    let EoeRepr::Other {
        frame_type, info, ..
    } = parse(&reply)
    else {
        panic!("type 9 expected")
    };
    assert_eq!(frame_type, EoeFrameType::GetAddressFilterResponse);
    assert_eq!(info, 0x0401);
    // A master does not send responses.
    let response = eoe(&EoeRepr::SetIpResponse {
        port: 0,
        result: EoeResult::Success,
    });
    assert_eq!(
        bench.one(MailboxType::Eoe, &response).error_code(),
        Some(MailboxErrorCode::ServiceNotSupported)
    );
    // A second fragment without a first one is dropped and counted.
    let stray = FragmentRepr {
        port: 0,
        last: true,
        time_request: false,
        fragment_number: 1,
        offset_field: 3,
        frame_number: 2,
        data: &[0; 10],
        timestamp: None,
    };
    assert!(
        bench
            .request(MailboxType::Eoe, &eoe(&EoeRepr::Fragment(stray)))
            .is_empty()
    );
    let counters = bench.stack.service::<EoeService>().unwrap().counters();
    assert_eq!((counters.reassembly_errors, counters.frames_in), (1, 0));
}

fn echo_payload(len: usize) -> Vec<u8> {
    (0..len).map(|i| (i % 251) as u8).collect()
}

/// An echo request (id 0x1234, sequence 7) for the slave's address, `len` bytes of payload.
fn echo_request(len: usize) -> Vec<u8> {
    let mut request = Vec::new();
    PacketBuilder::ethernet2(MASTER_MAC, SLAVE_MAC)
        .ipv4(MASTER_IP.octets(), SLAVE_IP.octets(), 64)
        .icmpv4_echo_request(0x1234, 7)
        .write(&mut request, &echo_payload(len))
        .unwrap();
    request
}

fn bridged_bench() -> (Bench, HostPort) {
    let port = HostPort::default();
    port.attach();
    let service = EoeService::default()
        .with_tcp_host(true)
        .with_host_port(port.clone());
    (
        Bench::new(MailboxStack::new().with(service), 128, 128),
        port,
    )
}

#[test]
fn an_attached_host_port_gets_the_masters_frames_and_set_ip_instead_of_the_endpoint() {
    let (mut bench, port) = bridged_bench();
    configure(&mut bench);
    match port.next_event(Duration::ZERO) {
        Some(HostEvent::IpConfig(config)) => {
            assert_eq!(config.mac, Some(SLAVE_MAC));
            assert_eq!(config.ip, Some(SLAVE_IP));
            assert_eq!(config.subnet_mask, Some(Ipv4Addr::new(255, 255, 255, 0)));
        }
        other => panic!("Set IP expected, got {other:?}"),
    }
    // A ping to the slave's own address: the host gets it, the slave does not answer it.
    let request = echo_request(300);
    let (sent, replies) = send_frame(&mut bench, &request, 3);
    assert!(sent >= 3, "{sent} fragments");
    assert!(replies.is_empty(), "{replies:?}");
    assert_eq!(
        port.next_event(Duration::ZERO),
        Some(HostEvent::Frame(request))
    );
    assert_eq!(port.next_event(Duration::ZERO), None);
    let counters = bench.stack.service::<EoeService>().unwrap().counters();
    assert_eq!((counters.frames_in, counters.icmp_replies), (1, 0));
    assert_eq!(port.drops().to_host, 0);
}

#[test]
fn a_port_never_attached_leaves_the_frames_to_the_endpoint() {
    let port = HostPort::default();
    let service = EoeService::default().with_host_port(port.clone());
    let mut bench = Bench::new(MailboxStack::new().with(service), 128, 128);
    configure(&mut bench);
    let (_, replies) = send_frame(&mut bench, &echo_request(40), 0);
    assert_eq!(reassemble(&replies).len(), 1, "the endpoint's echo reply");
    assert_eq!(port.next_event(Duration::ZERO), None);
}

#[test]
fn host_frames_go_to_the_master_one_frame_at_a_time_and_whole() {
    let (mut bench, port) = bridged_bench();
    let frames: Vec<Vec<u8>> = (0..3u8)
        .map(|i| {
            let mut f = MASTER_MAC.to_vec();
            f.extend_from_slice(&SLAVE_MAC);
            f.extend_from_slice(&[0x08, 0x00]);
            f.extend((0..300).map(|j| i.wrapping_mul(7).wrapping_add(j as u8)));
            f
        })
        .collect();
    for frame in &frames {
        assert!(port.send_to_master(frame.clone()));
    }
    // Polled while nothing is read: the first frame's fragments only, so an answer to the
    // next request would wait behind those and no more.
    let mut outbox = Outbox::new(64);
    for _ in 0..5 {
        bench.stack.poll(&bench.ctx, &mut outbox);
    }
    let first = outbox.len();
    let per_frame = Fragmenter::new(&frames[0], 128, 0).unwrap().count();
    assert_eq!(first, per_frame);
    let mut replies = Vec::new();
    while let Some(message) = outbox.pop() {
        replies.push(mailbox_support::parse_reply(&message));
    }
    // Read as a master reads: everything, in order, whole.
    replies.extend(bench.drain());
    let received = reassemble(&replies);
    let numbers: Vec<u8> = received.iter().map(|(n, _)| *n).collect();
    assert_eq!(numbers, [0, 1, 2]);
    let bodies: Vec<Vec<u8>> = received.into_iter().map(|(_, f)| f).collect();
    assert_eq!(bodies, frames);
    assert_eq!(port.drops().to_master, 0);
}
