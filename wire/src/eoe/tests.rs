//! Tests of the EoE message codec, fragmentation and reassembly.

use std::net::Ipv4Addr;

use proptest::prelude::*;

use super::*;

use crate::Emit;
use crate::mailbox::{Mailbox, MailboxHeader, MailboxType};

/// A made-up Ethernet frame of `len` bytes: broadcast, a local MAC, EtherType 0x0800, then a
/// counting pattern.
fn ethernet_frame(len: usize) -> Vec<u8> {
    let mut frame = vec![
        0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02, 0, 0, 0, 0, 1, 0x08, 0x00,
    ];
    frame.extend((0..len.saturating_sub(14)).map(|i| (i * 7 + 3) as u8));
    frame.truncate(len);
    frame
}

fn parse(bytes: &[u8]) -> Result<EoeRepr<'_>> {
    EoeRepr::parse(&EoePacket::new_checked(bytes)?)
}

/// Emits into a 0xa5-filled buffer of exactly `buffer_len` bytes.
fn emit(repr: &EoeRepr<'_>) -> Vec<u8> {
    let mut out = vec![0xa5u8; repr.buffer_len()];
    repr.emit(&mut EoePacket::new_unchecked(&mut out[..]))
        .unwrap();
    out
}

#[test]
fn c13_single_fragment_mailbox() {
    let frame = ethernet_frame(100);
    let mut bytes = vec![0x68, 0x00, 0x00, 0x00, 0x00, 0x12, 0x00, 0x01, 0x00, 0x31];
    bytes.extend_from_slice(&frame);

    let mbx = Mailbox::new_checked(&bytes[..]).unwrap();
    let header = MailboxHeader::parse(&mbx).unwrap();
    assert_eq!(header.mailbox_type, MailboxType::Eoe);
    assert_eq!((header.length, header.counter), (104, 1));
    let repr = parse(mbx.data()).unwrap();
    let expected = FragmentRepr {
        port: 0,
        last: true,
        time_request: false,
        fragment_number: 0,
        offset_field: 4,
        frame_number: 3,
        data: &frame,
        timestamp: None,
    };
    assert_eq!(repr, EoeRepr::Fragment(expected));
    assert_eq!(
        repr.to_string(),
        "EoE frag #0 frame 3 size=4x32 last (100 bytes)"
    );

    // The fragmenter produces exactly this fragment for a 128-byte mailbox.
    let frags: Vec<_> = Fragmenter::new(&frame, 128, 3).unwrap().collect();
    assert_eq!(frags, vec![expected]);

    let mut out = vec![0xa5u8; bytes.len()];
    header
        .emit(&mut Mailbox::new_unchecked(&mut out[..]))
        .unwrap();
    EoeRepr::Fragment(frags[0])
        .emit(&mut EoePacket::new_unchecked(&mut out[6..]))
        .unwrap();
    assert_eq!(out, bytes);
}

// ETG.1000.6, spec-notes §eoe.
static SET_IP: [u8; 22] = [
    0x10, 0x00, 0x00, 0x00, 0x00, 0x22, 0x02, 0x00, 0x00, 0x00, 0x06, 0x00, 0x00, 0x00, 0x0a, 0x01,
    0xa8, 0xc0, 0x00, 0xff, 0xff, 0xff,
];

#[test]
fn c14_set_ip_packed() {
    let mbx = Mailbox::new_checked(&SET_IP[..]).unwrap();
    let header = MailboxHeader::parse(&mbx).unwrap();
    assert_eq!((header.mailbox_type, header.counter), (MailboxType::Eoe, 2));
    let repr = parse(mbx.data()).unwrap();
    let expected = EoeRepr::SetIpRequest {
        port: 0,
        params: IpParameters {
            ip: Some(Ipv4Addr::new(192, 168, 1, 10)),
            subnet_mask: Some(Ipv4Addr::new(255, 255, 255, 0)),
            ..IpParameters::default()
        },
    };
    assert_eq!(repr, expected);
    assert_eq!(
        repr.to_string(),
        "EoE set-IP ip=192.168.1.10 mask=255.255.255.0"
    );
    let mut out = [0xa5u8; SET_IP.len()];
    header
        .emit(&mut Mailbox::new_unchecked(&mut out[..]))
        .unwrap();
    repr.emit(&mut EoePacket::new_unchecked(&mut out[6..]))
        .unwrap();
    assert_eq!(out, SET_IP);
}

/// Set IP with all six flags, worked out by hand (ETG.1000.6, spec-notes §eoe; 58-byte body).
fn all_flags_bytes() -> Vec<u8> {
    let mut b = vec![0x02, 0x00, 0x00, 0x00]; // EoE header, type 2
    b.extend_from_slice(&[0x3f, 0x00, 0x00, 0x00]); // flags
    b.extend_from_slice(&[0x02, 0x11, 0x22, 0x33, 0x44, 0x55]); // MAC
    b.extend_from_slice(&[0x0a, 0x01, 0xa8, 0xc0]); // 192.168.1.10
    b.extend_from_slice(&[0x00, 0xff, 0xff, 0xff]); // 255.255.255.0
    b.extend_from_slice(&[0x01, 0x01, 0xa8, 0xc0]); // 192.168.1.1
    b.extend_from_slice(&[0x08, 0x08, 0x08, 0x08]); // 8.8.8.8
    b.extend_from_slice(b"slave1");
    b.extend_from_slice(&[0u8; 26]);
    assert_eq!(b.len(), 4 + 58);
    b
}

fn all_flags_params() -> IpParameters<'static> {
    IpParameters {
        mac: Some([0x02, 0x11, 0x22, 0x33, 0x44, 0x55]),
        ip: Some(Ipv4Addr::new(192, 168, 1, 10)),
        subnet_mask: Some(Ipv4Addr::new(255, 255, 255, 0)),
        default_gateway: Some(Ipv4Addr::new(192, 168, 1, 1)),
        dns_server: Some(Ipv4Addr::new(8, 8, 8, 8)),
        dns_name: Some(b"slave1"),
    }
}

#[test]
fn set_ip_all_six_flags() {
    let bytes = all_flags_bytes();
    let repr = parse(&bytes).unwrap();
    let expected = EoeRepr::SetIpRequest {
        port: 0,
        params: all_flags_params(),
    };
    assert_eq!(repr, expected);
    assert_eq!(emit(&repr), bytes);
    assert_eq!(
        repr.to_string(),
        "EoE set-IP mac=02:11:22:33:44:55 ip=192.168.1.10 mask=255.255.255.0 \
         gw=192.168.1.1 dns=8.8.8.8 name=\"slave1\""
    );
}

#[test]
fn set_ip_fixed_layout_tolerated() {
    // IgH style: IP + mask flagged, but all 58 bytes present with the fields at fixed offsets.
    let mut bytes = vec![0x02, 0x00, 0x00, 0x00, 0x06, 0x00, 0x00, 0x00];
    bytes.extend_from_slice(&[0u8; 6]); // MAC slot (absent)
    bytes.extend_from_slice(&[0x0a, 0x01, 0xa8, 0xc0]);
    bytes.extend_from_slice(&[0x00, 0xff, 0xff, 0xff]);
    bytes.extend_from_slice(&[0u8; 8 + 32]);
    assert_eq!(bytes.len(), 4 + 58);
    let repr = parse(&bytes).unwrap();
    assert_eq!(
        repr,
        EoeRepr::SetIpRequest {
            port: 0,
            params: IpParameters {
                ip: Some(Ipv4Addr::new(192, 168, 1, 10)),
                subnet_mask: Some(Ipv4Addr::new(255, 255, 255, 0)),
                ..IpParameters::default()
            }
        }
    );
    // Emit is packed: the worked example's bytes (spec-notes §eoe).
    assert_eq!(emit(&repr), &SET_IP[6..]);
}

#[test]
fn set_ip_errors() {
    // Flags say IP + mask, only the IP is present.
    let short = [
        0x02, 0x00, 0x00, 0x00, 0x06, 0x00, 0x00, 0x00, 0x0a, 0x01, 0xa8, 0xc0,
    ];
    assert!(matches!(
        parse(&short),
        Err(WireError::Truncated {
            need: 12,
            have: 8,
            ..
        })
    ));
    assert!(matches!(
        parse(&[0x02, 0x00, 0x00, 0x00, 0x06]),
        Err(WireError::Truncated {
            need: 4,
            have: 1,
            ..
        })
    ));
    let long_name = [b'x'; 33];
    let bad = EoeRepr::SetIpRequest {
        port: 0,
        params: IpParameters {
            dns_name: Some(&long_name),
            ..IpParameters::default()
        },
    };
    let mut out = vec![0u8; bad.buffer_len()];
    assert!(matches!(
        bad.emit(&mut EoePacket::new_unchecked(&mut out[..])),
        Err(WireError::BadLength { declared: 33, .. })
    ));
    assert!(out.iter().all(|&b| b == 0), "a refused emit writes nothing");
    let nul_name = EoeRepr::SetIpRequest {
        port: 0,
        params: IpParameters {
            dns_name: Some(b"a\0b"),
            ..IpParameters::default()
        },
    };
    let mut out = vec![0u8; nul_name.buffer_len()];
    assert!(
        nul_name
            .emit(&mut EoePacket::new_unchecked(&mut out[..]))
            .is_err()
    );
    let bad_port = EoeRepr::GetIpRequest { port: 16 };
    let mut out = [0u8; 4];
    assert!(
        bad_port
            .emit(&mut EoePacket::new_unchecked(&mut out[..]))
            .is_err()
    );
    assert_eq!(out, [0u8; 4]);
}

#[test]
fn responses_and_requests() {
    // Set IP response, result 0x0201 (no IP support).
    let resp = parse(&[0x03, 0x00, 0x01, 0x02]).unwrap();
    assert_eq!(
        resp,
        EoeRepr::SetIpResponse {
            port: 0,
            result: EoeResult::NoIpSupport
        }
    );
    assert_eq!(resp.to_string(), "EoE set-IP resp 0x0201 No IP support");
    assert_eq!(emit(&resp), [0x03, 0x00, 0x01, 0x02]);

    // Get IP request on port 1.
    let req = parse(&[0x16, 0x00, 0x00, 0x00]).unwrap();
    assert_eq!(req, EoeRepr::GetIpRequest { port: 1 });
    assert_eq!(req.to_string(), "EoE get-IP port 1");
    assert_eq!(emit(&req), [0x16, 0x00, 0x00, 0x00]);

    // Get IP response: success, IP only.
    let bytes = [
        0x07, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x0a, 0x01, 0xa8, 0xc0,
    ];
    let resp = parse(&bytes).unwrap();
    assert_eq!(
        resp,
        EoeRepr::GetIpResponse {
            port: 0,
            result: EoeResult::Success,
            params: IpParameters {
                ip: Some(Ipv4Addr::new(192, 168, 1, 10)),
                ..IpParameters::default()
            }
        }
    );
    assert_eq!(emit(&resp), bytes);
    // Get IP response with an error and no body.
    assert_eq!(
        parse(&[0x07, 0x00, 0x01, 0x00]).unwrap(),
        EoeRepr::GetIpResponse {
            port: 0,
            result: EoeResult::UnspecifiedError,
            params: IpParameters::default()
        }
    );

    // Set address filter response: no filter support.
    assert_eq!(
        parse(&[0x05, 0x00, 0x01, 0x04]).unwrap(),
        EoeRepr::SetAddressFilterResponse {
            port: 0,
            result: EoeResult::NoFilterSupport
        }
    );

    // Timestamp response for frame 3: 0x12345678.
    let ts = [0x01, 0x00, 0x00, 0x30, 0x78, 0x56, 0x34, 0x12];
    let repr = parse(&ts).unwrap();
    assert_eq!(
        repr,
        EoeRepr::Timestamp {
            port: 0,
            frame_number: 3,
            timestamp: 0x1234_5678
        }
    );
    assert_eq!(emit(&repr), ts);
    assert!(matches!(parse(&ts[..6]), Err(WireError::Truncated { .. })));

    // Get address filter request: kept raw.
    let other = parse(&[0x08, 0x00, 0x00, 0x00]).unwrap();
    assert_eq!(
        other,
        EoeRepr::Other {
            frame_type: EoeFrameType::GetAddressFilterRequest,
            port: 0,
            info: 0,
            body: &[]
        }
    );
    let disguised = EoeRepr::Other {
        frame_type: EoeFrameType::SetIpRequest,
        port: 0,
        info: 0,
        body: &[],
    };
    let mut out = [0u8; 4];
    assert!(
        disguised
            .emit(&mut EoePacket::new_unchecked(&mut out[..]))
            .is_err()
    );
}

#[test]
fn address_filter() {
    // Options 0x0082: 2 filters, 0 masks, no broadcasts; fixed layout (122 bytes).
    let mut bytes = vec![0x04, 0x00, 0x00, 0x00, 0x82, 0x00];
    bytes.extend_from_slice(&[0x01, 0x02, 0x03, 0x04, 0x05, 0x06]);
    bytes.extend_from_slice(&[0x11, 0x12, 0x13, 0x14, 0x15, 0x16]);
    bytes.extend_from_slice(&[0u8; 6 * 18]);
    assert_eq!(bytes.len(), 4 + 122);
    let repr = parse(&bytes).unwrap();
    let EoeRepr::SetAddressFilterRequest { port: 0, filter } = repr else {
        panic!("{repr:?}");
    };
    assert_eq!((filter.filter_count, filter.mask_count), (2, 0));
    assert!(filter.no_broadcasts);
    assert_eq!(filter.filters[1], [0x11, 0x12, 0x13, 0x14, 0x15, 0x16]);
    assert_eq!(
        repr.to_string(),
        "EoE set-filter filters=2 masks=0 no-broadcasts"
    );
    assert_eq!(emit(&repr), bytes);

    // Packed: 1 filter, 1 mask (options 0x0011).
    let packed = [
        0x04, 0x00, 0x00, 0x00, 0x11, 0x00, 1, 2, 3, 4, 5, 6, 0xff, 0xff, 0xff, 0, 0, 0,
    ];
    let EoeRepr::SetAddressFilterRequest { filter, .. } = parse(&packed).unwrap() else {
        panic!();
    };
    assert_eq!(filter.filters[0], [1, 2, 3, 4, 5, 6]);
    assert_eq!(filter.masks[0], [0xff, 0xff, 0xff, 0, 0, 0]);
    assert!(matches!(
        parse(&packed[..17]),
        Err(WireError::Truncated { .. })
    ));
}

/// Fragments `frame` for `mailbox_size`, checks the sender rules (spec-notes §eoe) on every fragment,
/// sends each through emit/parse in a full mailbox and reassembles.
fn fragment_and_reassemble(frame: &[u8], mailbox_size: usize, frame_number: u8) -> usize {
    let mut reassembler = Reassembler::default();
    let frags: Vec<_> = Fragmenter::new(frame, mailbox_size, frame_number)
        .unwrap()
        .collect();
    let mut delivered = None;
    let mut sent = 0;
    for (i, frag) in frags.iter().enumerate() {
        assert_eq!(usize::from(frag.fragment_number), i);
        assert_eq!(frag.frame_number, frame_number);
        assert_eq!(frag.last, i + 1 == frags.len());
        if i == 0 {
            assert_eq!(usize::from(frag.offset_field), frame.len().div_ceil(32));
        } else {
            assert_eq!(usize::from(frag.offset_field) * 32, sent);
        }
        if !frag.last {
            assert_eq!(
                frag.data.len() % 32,
                0,
                "non-last fragments carry 32-byte multiples"
            );
        }
        sent += frag.data.len();

        let repr = EoeRepr::Fragment(*frag);
        let header = MailboxHeader {
            length: repr.buffer_len() as u16,
            address: 0,
            channel: 0,
            priority: 0,
            mailbox_type: MailboxType::Eoe,
            counter: 1,
        };
        let mut mbx_bytes = vec![0u8; 6 + repr.buffer_len()];
        assert!(mbx_bytes.len() <= mailbox_size, "fragment fits the mailbox");
        header
            .emit(&mut Mailbox::new_unchecked(&mut mbx_bytes[..]))
            .unwrap();
        repr.emit(&mut EoePacket::new_unchecked(&mut mbx_bytes[6..]))
            .unwrap();
        let mbx = Mailbox::new_checked(&mbx_bytes[..]).unwrap();
        let EoeRepr::Fragment(parsed) = parse(mbx.data()).unwrap() else {
            panic!("not a fragment");
        };
        assert_eq!(&parsed, frag);
        if let Some(done) = reassembler.push(&parsed).unwrap() {
            delivered = Some(done.frame.to_vec());
        }
    }
    assert_eq!(delivered.as_deref(), Some(frame));
    frags.len()
}

#[test]
fn fragmentation_round_trips() {
    let big = ethernet_frame(1514);
    let small = ethernet_frame(64);
    // 128: (128 − 10) = 118 per fragment, 96 per non-last one: 15 × 96 = 1440, then 74.
    assert_eq!(fragment_and_reassemble(&big, 128, 0), 16);
    // 1024: 992 then 522.
    assert_eq!(fragment_and_reassemble(&big, 1024, 15), 2);
    assert_eq!(fragment_and_reassemble(&small, 128, 7), 1);
    assert_eq!(fragment_and_reassemble(&small, 1024, 8), 1);
}

#[test]
fn fragmenter_refusals() {
    let frame = ethernet_frame(100);
    assert!(Fragmenter::new(&frame, 128, 16).is_err());
    // 41-byte mailbox: 31 bytes per fragment, no room for a 32-byte non-last fragment.
    assert!(Fragmenter::new(&frame, 41, 0).is_err());
    assert!(Fragmenter::new(&frame[..31], 41, 0).is_ok());
    let port3: Vec<_> = Fragmenter::new(&frame, 64, 0)
        .unwrap()
        .with_port(3)
        .collect();
    assert_eq!(port3.len(), 3);
    assert!(port3.iter().all(|f| f.port == 3));
    let bad_port = Fragmenter::new(&frame, 128, 0)
        .unwrap()
        .with_port(16)
        .next()
        .unwrap();
    let mut out = vec![0u8; bad_port.buffer_len()];
    assert!(
        bad_port
            .emit(&mut EoePacket::new_unchecked(&mut out[..]))
            .is_err()
    );
    assert!(matches!(
        Fragmenter::new(&vec![0u8; 2017], 1024, 0),
        Err(WireError::BadLength {
            declared: 2017,
            available: 2016,
            ..
        })
    ));
}

fn frag(number: u8, offset: u8, frame: u8, last: bool, data: &[u8]) -> FragmentRepr<'_> {
    FragmentRepr {
        port: 0,
        last,
        time_request: false,
        fragment_number: number,
        offset_field: offset,
        frame_number: frame,
        data,
        timestamp: None,
    }
}

#[test]
fn reassembler_rejects_bad_sequences() {
    let data = [0x55u8; 64];
    let mut r = Reassembler::default();

    // Out of order: fragment 2 after fragment 0.
    assert_eq!(r.push(&frag(0, 4, 1, false, &data[..32])).unwrap(), None);
    assert_eq!(
        r.push(&frag(2, 2, 1, true, &data[..32])).unwrap_err(),
        ReassemblyError::FragmentNumber {
            expected: 1,
            got: 2
        }
    );
    assert!(!r.in_progress(), "the partial frame is dropped");
    // ...so a later fragment 1 has nothing to continue.
    assert_eq!(
        r.push(&frag(1, 1, 1, true, &data[..32])).unwrap_err(),
        ReassemblyError::NoFrameInProgress { fragment_number: 1 }
    );

    // Wrong frame number.
    r.push(&frag(0, 4, 1, false, &data[..32])).unwrap();
    assert_eq!(
        r.push(&frag(1, 1, 2, true, &data[..32])).unwrap_err(),
        ReassemblyError::FrameNumber {
            expected: 1,
            got: 2
        }
    );

    // Wrong offset.
    r.push(&frag(0, 4, 1, false, &data[..32])).unwrap();
    assert_eq!(
        r.push(&frag(1, 2, 1, true, &data[..32])).unwrap_err(),
        ReassemblyError::Offset {
            expected: 32,
            got: 64
        }
    );

    // Overflow of the announced size (2 × 32 bytes announced, 96 sent).
    r.push(&frag(0, 2, 1, false, &data[..64])).unwrap();
    assert_eq!(
        r.push(&frag(1, 2, 1, true, &data[..32])).unwrap_err(),
        ReassemblyError::Overflow {
            size: 96,
            limit: 64
        }
    );
    // Overflow of the configured limit.
    let mut small = Reassembler::new(40);
    assert_eq!(
        small.push(&frag(0, 2, 0, true, &data[..50])).unwrap_err(),
        ReassemblyError::Overflow {
            size: 50,
            limit: 40
        }
    );
    assert!(matches!(
        WireError::from(ReassemblyError::Overflow { size: 1, limit: 0 }),
        WireError::Invalid {
            what: "EoE reassembly",
            ..
        }
    ));
}

#[test]
fn reassembler_accepts_igh_over_report_and_timestamp() {
    // A 64-byte frame announced as 64 / 32 + 1 = 3 units (IgH), with a timestamp.
    let data = [0x33u8; 64];
    let mut r = Reassembler::default();
    let mut last = frag(0, 3, 9, true, &data);
    last.timestamp = Some(42);
    let done = r.push(&last).unwrap().unwrap();
    assert_eq!(done.frame, &data);
    assert_eq!((done.frame_number, done.timestamp), (9, Some(42)));

    // The timestamp round-trips through the wire too.
    let bytes = emit(&EoeRepr::Fragment(last));
    assert_eq!(bytes[1], 0x03, "last + time appended");
    assert_eq!(bytes[bytes.len() - 4..], [42, 0, 0, 0]);
    assert_eq!(parse(&bytes).unwrap(), EoeRepr::Fragment(last));
}

fn arb_mac() -> impl Strategy<Value = [u8; 6]> {
    any::<[u8; 6]>()
}

fn arb_ip() -> impl Strategy<Value = Option<Ipv4Addr>> {
    proptest::option::of(any::<u32>().prop_map(Ipv4Addr::from))
}

/// Arbitrary IP parameters; the DNS name borrows from a leaked pool so that the strategy can
/// return `'static` values.
fn arb_params() -> impl Strategy<Value = IpParameters<'static>> {
    (
        proptest::option::of(arb_mac()),
        arb_ip(),
        arb_ip(),
        arb_ip(),
        arb_ip(),
        proptest::option::of(proptest::collection::vec(1u8..=255, 0..=32)),
    )
        .prop_map(
            |(mac, ip, subnet_mask, default_gateway, dns_server, name)| IpParameters {
                mac,
                ip,
                subnet_mask,
                default_gateway,
                dns_server,
                dns_name: name.map(|n| &*Box::leak(n.into_boxed_slice())),
            },
        )
}

fn arb_filter() -> impl Strategy<Value = AddressFilter> {
    (
        0u8..16,
        0u8..4,
        any::<bool>(),
        any::<[[u8; 6]; 16]>(),
        any::<[[u8; 6]; 4]>(),
    )
        .prop_map(
            |(filter_count, mask_count, no_broadcasts, filters, masks)| AddressFilter {
                filter_count,
                mask_count,
                no_broadcasts,
                filters,
                masks,
                packed: false,
            },
        )
}

#[test]
fn a_packed_filter_carries_only_the_counted_slots_and_reads_back() {
    let mut filter = AddressFilter {
        filter_count: 2,
        mask_count: 1,
        no_broadcasts: true,
        packed: true,
        ..AddressFilter::default()
    };
    filter.filters[0] = [2, 0, 0, 0, 0, 1];
    filter.filters[1] = [2, 0, 0, 0, 0, 2];
    filter.masks[0] = [0xff; 6];
    assert_eq!(filter.buffer_len(), 2 + 18);
    let mut body = [0u8; 20];
    filter.emit_body(&mut body).unwrap();
    assert_eq!(body[..2], [0x92, 0x00], "2 filters, 1 mask, no broadcasts");
    assert_eq!(body[2..8], [2, 0, 0, 0, 0, 1]);
    assert_eq!(body[14..20], [0xff; 6]);
    assert_eq!(AddressFilter::parse_body(&body).unwrap(), filter);
    assert!(filter.emit_body(&mut [0u8; 19]).is_err(), "too small");
}

pub(crate) fn arb_eoe() -> impl Strategy<Value = EoeRepr<'static>> {
    let data = || proptest::collection::vec(any::<u8>(), 0..80).prop_map(|v| &*v.leak());
    prop_oneof![
        (
            0u8..16,
            any::<bool>(),
            any::<bool>(),
            0u8..64,
            0u8..64,
            0u8..16,
            data(),
            proptest::option::of(any::<u32>()),
        )
            .prop_map(
                |(
                    port,
                    last,
                    time_request,
                    fragment_number,
                    offset_field,
                    frame_number,
                    data,
                    timestamp,
                )| {
                    EoeRepr::Fragment(FragmentRepr {
                        port,
                        last,
                        time_request,
                        fragment_number,
                        offset_field,
                        frame_number,
                        data,
                        timestamp,
                    })
                }
            ),
        (0u8..16, 0u8..16, any::<u32>()).prop_map(|(port, frame_number, timestamp)| {
            EoeRepr::Timestamp {
                port,
                frame_number,
                timestamp,
            }
        }),
        (0u8..16, arb_params()).prop_map(|(port, params)| EoeRepr::SetIpRequest { port, params }),
        (0u8..16, any::<u16>()).prop_map(|(port, r)| EoeRepr::SetIpResponse {
            port,
            result: EoeResult::from(r)
        }),
        (0u8..16, arb_filter())
            .prop_map(|(port, filter)| EoeRepr::SetAddressFilterRequest { port, filter }),
        (0u8..16, any::<u16>()).prop_map(|(port, r)| EoeRepr::SetAddressFilterResponse {
            port,
            result: EoeResult::from(r)
        }),
        (0u8..16).prop_map(|port| EoeRepr::GetIpRequest { port }),
        (0u8..16, any::<u16>(), arb_params()).prop_map(|(port, r, params)| {
            EoeRepr::GetIpResponse {
                port,
                result: EoeResult::from(r),
                params,
            }
        }),
        (8u8..16, 0u8..16, any::<u16>(), data()).prop_map(|(ty, port, info, body)| {
            EoeRepr::Other {
                frame_type: EoeFrameType::from(ty),
                port,
                info,
                body,
            }
        }),
    ]
}

proptest! {
    #[test]
    fn round_trip(repr in arb_eoe()) {
        let buf = repr.to_vec().unwrap();
        prop_assert_eq!(parse(&buf).unwrap(), repr);
    }

    #[test]
    fn fragment_reassemble_any(len in 0usize..=2016, mailbox in 42usize..1500, n in 0u8..16) {
        let frame = ethernet_frame(len);
        let mut r = Reassembler::default();
        let mut out = None;
        for f in Fragmenter::new(&frame, mailbox, n).unwrap() {
            prop_assert!(10 + f.data.len() <= mailbox);
            if let Some(done) = r.push(&f).unwrap() {
                out = Some(done.frame.to_vec());
            }
        }
        prop_assert_eq!(out, Some(frame));
    }

    #[test]
    fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..160)) {
        if let Ok(packet) = EoePacket::new_checked(&bytes[..])
            && let Ok(repr) = EoeRepr::parse(&packet) {
                let _ = repr.to_string();
                if let EoeRepr::Fragment(f) = repr {
                    let _ = Reassembler::new(64).push(&f);
                }
            }
        let _ = IpParameters::parse_body(&bytes);
        let _ = AddressFilter::parse_body(&bytes);
    }

    #[test]
    fn reassembler_never_panics(frags in proptest::collection::vec(
        (0u8..64, 0u8..64, 0u8..16, any::<bool>(), 0usize..200), 0..20)) {
        let data = [0u8; 200];
        let mut r = Reassembler::new(1514);
        for (number, offset, frame, last, len) in frags {
            if let Ok(Some(done)) = r.push(&frag(number, offset, frame, last, &data[..len])) {
                prop_assert!(done.frame.len() <= 1514);
            }
        }
    }
}
