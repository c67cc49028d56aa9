//! The slave's own tiny IPv4 host behind EoE: it answers ARP requests for its IP address and
//! ICMP echo requests addressed to it, so `ping` through a master's EoE interface works.
//!
//! Parsing and building (headers, lengths, checksums) is etherparse's; nothing here writes
//! protocol bytes by hand.

use etherparse::{
    ArpEthIpv4Packet, ArpOperation, Icmpv4Type, LinkSlice, NetSlice, PacketBuilder, SlicedPacket,
    TransportSlice,
};

use super::ip_config::IpConfig;

/// Ethernet frames shorter than this (without FCS) are padded, as a real MAC does.
const MIN_FRAME_LEN: usize = 60;

/// TTL of the echo replies (a common host default).
const TTL: u8 = 64;

const BROADCAST: [u8; 6] = [0xFF; 6];

/// What the endpoint made of a frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Answer {
    /// An ARP reply for the slave's address.
    Arp(Vec<u8>),
    /// An ICMP echo reply.
    IcmpEcho(Vec<u8>),
}

/// The reply the slave sends to `frame`, if it answers it at all. Without an IP address (and
/// without a MAC, set or from the factory) the slave is not on the network yet and answers
/// nothing.
pub fn answer(frame: &[u8], config: &IpConfig) -> Option<Answer> {
    let (Some(mac), Some(ip)) = (config.station_mac(), config.ip) else {
        return None;
    };
    let packet = SlicedPacket::from_ethernet(frame).ok()?;
    let Some(LinkSlice::Ethernet2(ethernet)) = &packet.link else {
        return None;
    };
    let destination = ethernet.destination();
    if destination != mac && destination != BROADCAST {
        return None;
    }
    match (&packet.net, &packet.transport) {
        (Some(NetSlice::Arp(arp)), _) => {
            let request = arp.to_packet().try_eth_ipv4().ok()?;
            if request.operation != ArpOperation::REQUEST || request.target_ipv4 != ip.octets() {
                return None;
            }
            let reply = ArpEthIpv4Packet {
                operation: ArpOperation::REPLY,
                sender_mac: mac,
                sender_ipv4: ip.octets(),
                target_mac: request.sender_mac,
                target_ipv4: request.sender_ipv4,
            };
            let mut out = Vec::new();
            PacketBuilder::ethernet2(mac, request.sender_mac)
                .arp(reply.to_arp_packet())
                .write(&mut out)
                .ok()?;
            Some(Answer::Arp(padded(out)))
        }
        (Some(NetSlice::Ipv4(ipv4)), Some(TransportSlice::Icmpv4(icmp))) => {
            let header = ipv4.header();
            // A fragment of a larger datagram is not answered: the slave does not reassemble IP.
            if destination != mac || header.destination_addr() != ip || ipv4.is_payload_fragmented()
            {
                return None;
            }
            let Icmpv4Type::EchoRequest(echo) = icmp.icmp_type() else {
                return None;
            };
            let mut out = Vec::new();
            PacketBuilder::ethernet2(mac, ethernet.source())
                .ipv4(ip.octets(), header.source(), TTL)
                .icmpv4_echo_reply(echo.id, echo.seq)
                .write(&mut out, icmp.payload())
                .ok()?;
            Some(Answer::IcmpEcho(padded(out)))
        }
        _ => None,
    }
}

fn padded(mut frame: Vec<u8>) -> Vec<u8> {
    if frame.len() < MIN_FRAME_LEN {
        frame.resize(MIN_FRAME_LEN, 0);
    }
    frame
}
