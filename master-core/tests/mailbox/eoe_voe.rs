//! EoE and VoE through the mailbox engine against the simulator in-process: IP parameters
//! round trip, ICMP echo through EoE (small and fragmented frames), the address filter, and
//! the VoE echo.

use crate::mailbox_support;

use std::net::Ipv4Addr;
use std::time::Duration;

use etherparse::{Icmpv4Type, NetSlice, PacketBuilder, SlicedPacket, TransportSlice};
use mailbox_support::{DRIVE, EOE_PORT, Rig, station};
use master_core::mailbox::{IpSettings, MailboxConfig, MailboxError, SlaveMailbox};
use master_core::wire::eoe::{AddressFilter, Fragmenter};

/// Fragments per turn of the mailbox's owner (master-core's `mailbox::eoe::tx::CHAIN`).
const CHAIN: usize = 4;
use master_core::wire::mailbox::MailboxErrorCode;
use sim::device::voe::VoeEcho;
use sim::topology::{MailboxSpec, Topology};

const MASTER_MAC: [u8; 6] = [0x02, 0x00, 0x00, 0x00, 0x00, 0x01];
const MASTER_IP: Ipv4Addr = Ipv4Addr::new(192, 168, 100, 1);

fn settings(last: u8) -> IpSettings {
    IpSettings {
        mac: Some([0x02, 0xEC, 0xAD, 0x00, 0x00, last]),
        ip: Some(Ipv4Addr::new(192, 168, 100, last)),
        subnet_mask: Some(Ipv4Addr::new(255, 255, 255, 0)),
        default_gateway: Some(MASTER_IP),
        dns_server: Some(Ipv4Addr::new(192, 168, 100, 53)),
        dns_name: Some(format!("slave-{last}")),
    }
}

fn echo_request(to: &IpSettings, id: u16, seq: u16, payload: &[u8]) -> Vec<u8> {
    let mut frame = Vec::new();
    PacketBuilder::ethernet2(MASTER_MAC, to.mac.unwrap())
        .ipv4(MASTER_IP.octets(), to.ip.unwrap().octets(), 64)
        .icmpv4_echo_request(id, seq)
        .write(&mut frame, payload)
        .unwrap();
    frame
}

/// Sends an ICMP echo request through EoE and returns the payload of the matching reply,
/// with the lengths of the frame sent and of the reply's frame.
async fn ping(
    slave: &SlaveMailbox,
    to: &IpSettings,
    seq: u16,
    payload: &[u8],
) -> (Vec<u8>, usize, usize) {
    let mut frames = slave.subscribe_eoe();
    let request = echo_request(to, 0x4242, seq, payload);
    slave.eoe_send(&request).await.unwrap();
    loop {
        let frame = tokio::time::timeout(Duration::from_secs(5), frames.recv())
            .await
            .expect("an answer through EoE")
            .unwrap();
        assert_eq!(frame.station, slave.station());
        let packet = SlicedPacket::from_ethernet(&frame.frame).unwrap();
        let (Some(NetSlice::Ipv4(ip)), Some(TransportSlice::Icmpv4(icmp))) =
            (&packet.net, &packet.transport)
        else {
            continue;
        };
        if let Icmpv4Type::EchoReply(echo) = icmp.icmp_type()
            && echo.id == 0x4242
            && echo.seq == seq
        {
            assert_eq!(ip.header().source_addr(), to.ip.unwrap());
            assert_eq!(ip.header().destination_addr(), MASTER_IP);
            return (icmp.payload().to_vec(), request.len(), frame.frame.len());
        }
    }
}

#[tokio::test]
async fn set_ip_then_get_ip_round_trip() {
    let rig = Rig::default_segment();
    for position in [DRIVE, EOE_PORT] {
        let slave = rig.slave(position);
        let wanted = settings(10 + position as u8);
        slave.eoe_set_ip(&wanted).await.unwrap();
        assert_eq!(slave.eoe_get_ip().await.unwrap(), wanted);
        // Only the fields sent change.
        let partial = IpSettings {
            ip: Some(Ipv4Addr::new(10, 0, 0, position as u8)),
            ..IpSettings::default()
        };
        slave.eoe_set_ip(&partial).await.unwrap();
        let now = slave.eoe_get_ip().await.unwrap();
        assert_eq!(now.ip, partial.ip);
        assert_eq!(now.mac, wanted.mac);
        assert_eq!(now.dns_name, wanted.dns_name);
    }
}

#[tokio::test]
async fn an_icmp_echo_request_through_eoe_gets_the_slaves_reply() {
    let rig = Rig::default_segment();
    for position in [DRIVE, EOE_PORT] {
        let slave = rig.slave(position);
        let me = settings(20 + position as u8);
        slave.eoe_set_ip(&me).await.unwrap();
        let small = b"ecatd ping".to_vec();
        let (echo, out_small, in_small) = ping(&slave, &me, 1, &small).await;
        assert_eq!(echo, small);
        // 1400 bytes: a dozen fragments each way through 128-byte mailboxes.
        let large: Vec<u8> = (0..1400u32).map(|i| (i * 7) as u8).collect();
        let (echo, out_large, in_large) = ping(&slave, &me, 2, &large).await;
        assert_eq!(echo, large);
        let stats = slave.stats();
        assert_eq!(stats.eoe_frames_out, 2);
        assert_eq!(stats.eoe_frames_in, 2);
        // Whole Ethernet frames, counted once each however many fragments carried them.
        assert_eq!(stats.eoe_bytes_out, (out_small + out_large) as u64);
        assert_eq!(stats.eoe_bytes_in, (in_small + in_large) as u64);
        assert!(stats.eoe_bytes_out > 1400, "{stats:?}");
        assert_eq!(stats.eoe_reassembly_errors, 0);
    }
    assert_eq!(rig.slave(EOE_PORT).station(), station(EOE_PORT));
}

/// The default segment with the drive's mailboxes `size` bytes each way; its send mailbox is
/// read only while a request waits or when the test says so (no idle polls, no "mailbox
/// full" bits), so what the slave sends back is read when the test has counted what came
/// before.
fn with_drive_mailboxes(size: u16) -> Rig {
    let mut topology = Topology::default_segment();
    let drive = &mut topology.slaves[DRIVE];
    drive.mailbox = Some(MailboxSpec {
        rx_size: size,
        tx_size: size,
        start: None,
    });
    drive.esc.ram_kib = drive.esc.ram_kib.max(8);
    let mailbox = MailboxConfig {
        idle_poll: None,
        ..MailboxConfig::default()
    };
    Rig::start_without_status_bits(&topology, mailbox, |_, _| {})
}

#[tokio::test]
async fn a_frame_of_many_fragments_goes_in_chains_the_bus_writes_as_the_slave_takes_them() {
    // 128 bytes: a write and the read beside it share a frame; 1 KiB: they do not fit one.
    for size in [128u16, 1024] {
        let rig = with_drive_mailboxes(size);
        let slave = rig.slave(DRIVE);
        let me = settings(40);
        slave.eoe_set_ip(&me).await.unwrap();
        assert_eq!(usize::from(slave.config().write.len), usize::from(size));
        let frame = echo_request(&me, 0x4343, 1, &[0x5A; 1400]);
        let fragments = Fragmenter::new(&frame, size.into(), 0).unwrap().count();
        let turns = fragments.div_ceil(CHAIN);
        let (bus, mailbox) = (rig.bus.stats(), slave.stats());
        let mut replies = slave.subscribe_eoe();
        slave.eoe_send(&frame).await.unwrap();
        let (bus_after, mailbox_after) = (rig.bus.stats(), slave.stats());
        // The simulated slave takes each fragment within the frame that wrote it: every
        // write counts once, and the bus wrote all but the first of each run: batches of
        // up to CHAIN fragments, each joining the run before it when it came in time
        // (one run for the frame at best, one per batch at worst). The echo reply, waiting
        // in SM1 meanwhile, comes back the same way, in chains of reads, once the test has
        // the slave's send mailbox read.
        assert_eq!(mailbox_after.write_full, mailbox.write_full, "{size}");
        assert_eq!(
            mailbox_after.writes - mailbox.writes,
            fragments as u64,
            "{size}"
        );
        let chained = bus_after.datagrams_chained - bus.datagrams_chained;
        let runs = fragments as u64 - chained;
        assert!((1..=turns as u64).contains(&runs), "{size}: {runs} runs");
        assert_eq!(mailbox_after.eoe_frames_out - mailbox.eoe_frames_out, 1);
        // The device got the whole frame: it answers the echo request, as long.
        slave.notify_mailbox_full();
        let reply = tokio::time::timeout(Duration::from_secs(5), replies.recv())
            .await
            .expect("the echo reply")
            .unwrap();
        assert_eq!(reply.frame.len(), frame.len(), "{size}");
        let read_chained = rig.bus.stats().datagrams_chained - bus_after.datagrams_chained;
        assert!(
            read_chained > 0,
            "{size}: the reply's fragments were read by chained reads"
        );
    }
}

#[tokio::test]
async fn the_address_filter_answer_and_frame_limits() {
    // A 128-byte mailbox holds 122 bytes of EoE data: less than the fixed layout's 122 +
    // header, so the filter goes in the packed layout (spec-notes §eoe), which holds a
    // short filter; a full one (16 addresses, 4 masks) does not fit either and is refused
    // before anything is sent.
    let rig = Rig::default_segment();
    let slave = rig.slave(EOE_PORT);
    let mut one = AddressFilter {
        filter_count: 1,
        ..AddressFilter::default()
    };
    one.filters[0] = [0x02, 0x45, 0x43, 0x53, 0x00, 0x04];
    slave.eoe_set_address_filter(&one).await.unwrap();
    let writes = slave.stats().writes;
    assert!(writes > 0);
    let full = AddressFilter {
        filter_count: 16,
        mask_count: 4,
        ..AddressFilter::default()
    };
    assert!(matches!(
        slave.eoe_set_address_filter(&full).await,
        Err(MailboxError::Invalid(_))
    ));
    assert_eq!(slave.stats().writes, writes, "nothing sent");
    let mut topology = Topology::default_segment();
    let mailbox = topology.slaves[EOE_PORT].mailbox.as_mut().unwrap();
    mailbox.rx_size = 256;
    mailbox.tx_size = 256;
    let rig = Rig::start(
        &topology,
        Default::default(),
        5,
        mailbox_support::bus_config(),
    );
    let slave = rig.slave(EOE_PORT);
    // The simulated EoE slave takes a filter (it answers success).
    slave
        .eoe_set_address_filter(&AddressFilter::default())
        .await
        .unwrap();
    assert!(matches!(
        slave.eoe_send(&vec![0u8; 4000]).await,
        Err(MailboxError::TooLarge { .. })
    ));
}

#[tokio::test]
async fn voe_echo() {
    let rig = Rig::default_segment();
    let drive = rig.slave(DRIVE);
    let data: Vec<u8> = (0..100u8).collect();
    let answer = drive.voe(0x1164, 0x0042, &data).await.unwrap();
    assert_eq!(answer.vendor_id, 0x1164);
    assert_eq!(answer.vendor_type, 0x0042);
    assert_eq!(answer.data, VoeEcho::transform(&data));
    // Another vendor's protocol: the slave answers with a mailbox error.
    assert_eq!(
        drive.voe(0x0002, 1, &data).await.unwrap_err(),
        MailboxError::Mailbox(MailboxErrorCode::ServiceNotSupported)
    );
}
