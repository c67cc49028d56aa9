use super::*;
use crate::Emit;
use crate::error::WireError;
use crate::mailbox::{Mailbox, MailboxHeader, MailboxType};
use proptest::prelude::*;

// ETG.1000.6, spec-notes §soe.
static READ_REQ: [u8; 10] = [0x04, 0x00, 0x00, 0x00, 0x00, 0x15, 0x01, 0x40, 0x18, 0x00];
static NO_IDN_REPLY: [u8; 12] = [
    0x06, 0x00, 0x00, 0x00, 0x00, 0x15, 0x12, 0x40, 0x18, 0x00, 0x01, 0x10,
];

fn mailbox_case(bytes: &[u8], expected: SoeRepr<'_>) {
    let mbx = Mailbox::new_checked(bytes).unwrap();
    let header = MailboxHeader::parse(&mbx).unwrap();
    assert_eq!(header.mailbox_type, MailboxType::Soe);
    let repr = SoeRepr::parse(&SoePacket::new_checked(mbx.data()).unwrap()).unwrap();
    assert_eq!(repr, expected);
    let mut out = vec![0xa5u8; bytes.len()];
    header
        .emit(&mut Mailbox::new_unchecked(&mut out[..]))
        .unwrap();
    repr.emit(&mut SoePacket::new_unchecked(&mut out[6..]))
        .unwrap();
    assert_eq!(out, bytes);
}

#[test]
fn c15_read_request() {
    let repr = SoeRepr {
        opcode: SoeOpcode::ReadRequest,
        drive: 0,
        elements: ElementFlags::VALUE,
        idn_or_fragments: IdnOrFragments::Idn("S-0-0024".parse().unwrap()),
        error: None,
        data: &[],
    };
    mailbox_case(&READ_REQ, repr);
    assert_eq!(
        repr.to_string(),
        "SoE read req S-0-0024 drive 0 elements=value"
    );
}

#[test]
fn c15_error_reply() {
    let repr = SoeRepr {
        opcode: SoeOpcode::ReadResponse,
        drive: 0,
        elements: ElementFlags::VALUE,
        idn_or_fragments: IdnOrFragments::Idn(Idn::from_raw(0x0018)),
        error: Some(SoeError::NoIdn),
        data: &[],
    };
    mailbox_case(&NO_IDN_REPLY, repr);
    assert_eq!(
        repr.to_string(),
        "SoE read resp S-0-0024 drive 0 elements=value error 0x1001 No IDN"
    );
}

#[test]
fn error_code_position() {
    // Read response with 2 data bytes then the error code last.
    let read = [0x12, 0x40, 0x18, 0x00, 0xaa, 0xbb, 0x01, 0x70];
    let repr = SoeRepr::parse(&SoePacket::new_checked(&read[..]).unwrap()).unwrap();
    assert_eq!(repr.error, Some(SoeError::Unknown(0x7001)));
    assert_eq!(repr.data, &[0xaa, 0xbb]);
    // Write response: code at offset 4 (opcode 4 | error 0x10, drive 1 = 0x20).
    let write = [0x34, 0x40, 0x18, 0x00, 0x04, 0x70];
    let repr = SoeRepr::parse(&SoePacket::new_checked(&write[..]).unwrap()).unwrap();
    assert_eq!(repr.opcode, SoeOpcode::WriteResponse);
    assert_eq!(repr.drive, 1);
    assert_eq!(repr.error, Some(SoeError::DataReadOnly));
    assert!(repr.data.is_empty());
    // Error bit without the code.
    assert!(matches!(
        SoePacket::new_checked(&[0x14u8, 0x40, 0x18, 0x00, 0x01][..]),
        Err(WireError::Truncated {
            need: 6,
            have: 5,
            ..
        })
    ));
    assert!(matches!(
        SoePacket::new_checked(&[0x01u8, 0x40, 0x18][..]),
        Err(WireError::Truncated {
            need: 4,
            have: 3,
            ..
        })
    ));
}

#[test]
fn idn_text() {
    assert_eq!(Idn::from_raw(0x0018).to_string(), "S-0-0024");
    assert_eq!(Idn::from_raw(0x8001).to_string(), "P-0-0001");
    assert_eq!(Idn::from_raw(0xF123).to_string(), "P-7-0291");
    assert_eq!("P-0-0001".parse::<Idn>().unwrap().raw(), 0x8001);
    assert_eq!("S-0-16".parse::<Idn>().unwrap().raw(), 0x0010);
    assert_eq!("S-7-4095".parse::<Idn>().unwrap().raw(), 0x7FFF);
    for bad in [
        "", "S-0", "X-0-1", "S-8-1", "S-0-4096", "S-0-1-2", "S--1", "S-0-+1",
    ] {
        assert!(bad.parse::<Idn>().is_err(), "{bad}");
    }
}

#[test]
fn element_flags_display() {
    assert_eq!(ElementFlags::VALUE.to_string(), "value");
    assert_eq!(
        (ElementFlags::NAME | ElementFlags::ATTRIBUTE).to_string(),
        "name+attribute"
    );
    assert_eq!(ElementFlags::empty().to_string(), "none");
    assert_eq!(ElementFlags::from_bits(0x40), ElementFlags::VALUE);
}

#[test]
fn attribute_decode() {
    // Worked from spec-notes §soe: factor 1, 4 bytes (010), unsigned (1), 3 decimals,
    // write-protected in OP → 0x4312_0001.
    let attr = SoeAttribute::from_u32(0x4312_0001);
    assert_eq!(
        attr,
        SoeAttribute {
            conversion_factor: 1,
            element_size: 4,
            list: false,
            procedure_command: false,
            data_type: SoeDataType::Unsigned,
            decimal_places: 3,
            write_protected_preop: false,
            write_protected_safeop: false,
            write_protected_op: true,
        }
    );
    assert_eq!(attr.to_u32().unwrap(), 0x4312_0001);
    // A list of u16 (IDN list): size 2 (01) + list bit 18 → bits 16-18 = 101; type IDN 5;
    // procedure bit 19.
    let list = SoeAttribute::from_u32(0x005D_0000);
    assert_eq!(list.element_size, 2);
    assert!(list.list && list.procedure_command);
    assert_eq!(list.data_type, SoeDataType::Idn);
    let bad = SoeAttribute {
        element_size: 3,
        ..attr
    };
    assert!(bad.to_u32().is_err());
}

#[test]
fn multi_fragment_write_sequence() {
    // Mailbox of 32 bytes: capacity 32 − 10 = 22; value 3 × 22 + 5 = 71 bytes.
    let cap = fragment_capacity(32);
    assert_eq!(cap, 22);
    let value: Vec<u8> = (0..71u8).collect();
    let frags: Vec<_> = fragments(value.len(), cap).unwrap().collect();
    assert_eq!(
        frags,
        vec![
            SoeFragment {
                range: 0..22,
                fragments_left: Some(3)
            },
            SoeFragment {
                range: 22..44,
                fragments_left: Some(2)
            },
            SoeFragment {
                range: 44..66,
                fragments_left: Some(1)
            },
            SoeFragment {
                range: 66..71,
                fragments_left: None
            },
        ]
    );
    // Build the four write requests and check the headers byte by byte.
    let idn = Idn::from_raw(0x0018);
    let expected_headers: [[u8; 4]; 4] = [
        [0x0b, 0x40, 0x03, 0x00],
        [0x0b, 0x40, 0x02, 0x00],
        [0x0b, 0x40, 0x01, 0x00],
        [0x03, 0x40, 0x18, 0x00],
    ];
    let mut reassembled = Vec::new();
    for (frag, header) in frags.iter().zip(expected_headers) {
        let repr = SoeRepr {
            opcode: SoeOpcode::WriteRequest,
            drive: 0,
            elements: ElementFlags::VALUE,
            idn_or_fragments: match frag.fragments_left {
                Some(n) => IdnOrFragments::FragmentsLeft(n),
                None => IdnOrFragments::Idn(idn),
            },
            error: None,
            data: &value[frag.range.clone()],
        };
        let mut buf = vec![0xa5u8; repr.buffer_len()];
        assert!(buf.len() <= cap + HEADER_LEN);
        repr.emit(&mut SoePacket::new_unchecked(&mut buf[..]))
            .unwrap();
        assert_eq!(buf[..4], header);
        let parsed = SoeRepr::parse(&SoePacket::new_checked(&buf[..]).unwrap()).unwrap();
        reassembled.extend_from_slice(parsed.data);
    }
    assert_eq!(reassembled, value);
}

#[test]
fn fragment_edge_cases() {
    // Exact multiple: IgH gives ceil(44/22) − 1 = 1 for the first.
    let f: Vec<_> = fragments(44, 22)
        .unwrap()
        .map(|f| f.fragments_left)
        .collect();
    assert_eq!(f, vec![Some(1), None]);
    let f: Vec<_> = fragments(0, 22).unwrap().collect();
    assert_eq!(
        f,
        vec![SoeFragment {
            range: 0..0,
            fragments_left: None
        }]
    );
    assert!(fragments(1, 0).is_err());
    assert!(fragments(70_000, 1).is_err());
    assert_eq!(fragments(65_536, 1).unwrap().count(), 65_536);
}

#[test]
fn emit_refuses_bad_drive() {
    let repr = SoeRepr {
        opcode: SoeOpcode::ReadRequest,
        drive: 8,
        elements: ElementFlags::VALUE,
        idn_or_fragments: IdnOrFragments::Idn(Idn::from_raw(1)),
        error: None,
        data: &[],
    };
    let mut buf = [0u8; 4];
    assert!(
        repr.emit(&mut SoePacket::new_unchecked(&mut buf[..]))
            .is_err()
    );
    assert_eq!(buf, [0u8; 4]);
    let mut small = [0u8; 3];
    assert!(matches!(
        SoeRepr { drive: 0, ..repr }.emit(&mut SoePacket::new_unchecked(&mut small[..])),
        Err(WireError::BufferTooSmall { .. })
    ));
}

pub(crate) fn arb_soe() -> impl Strategy<Value = (SoeRepr<'static>, Vec<u8>)> {
    (
        0u8..8,
        0u8..8,
        any::<u8>(),
        any::<bool>(),
        any::<u16>(),
        proptest::option::of(any::<u16>()),
        proptest::collection::vec(any::<u8>(), 0..32),
    )
        .prop_map(|(op, drive, el, inc, raw, err, data)| {
            let repr = SoeRepr {
                opcode: SoeOpcode::from(op),
                drive,
                elements: ElementFlags::from_bits(el),
                idn_or_fragments: if inc {
                    IdnOrFragments::FragmentsLeft(raw)
                } else {
                    IdnOrFragments::Idn(Idn::from_raw(raw))
                },
                error: err.map(SoeError::from),
                data: &[],
            };
            (repr, data)
        })
}

proptest! {
    #[test]
    fn round_trip((template, data) in arb_soe()) {
        let repr = SoeRepr { data: &data, ..template };
        let buf = repr.to_vec().unwrap();
        let parsed = SoeRepr::parse(&SoePacket::new_checked(&buf[..]).unwrap()).unwrap();
        prop_assert_eq!(parsed, repr);
    }

    #[test]
    fn idn_text_round_trip(raw in any::<u16>()) {
        let idn = Idn::from_raw(raw);
        prop_assert_eq!(idn.to_string().parse::<Idn>().unwrap(), idn);
    }

    #[test]
    fn attribute_round_trip(raw in any::<u32>()) {
        let clean = raw & !((1 << 23) | (1 << 31));
        prop_assert_eq!(SoeAttribute::from_u32(clean).to_u32().unwrap(), clean);
    }

    #[test]
    fn fragments_cover_the_value(total in 0usize..2000, cap in 1usize..300) {
        let frags: Vec<_> = fragments(total, cap).unwrap().collect();
        let mut next = 0;
        for (i, f) in frags.iter().enumerate() {
            prop_assert_eq!(f.range.start, next);
            prop_assert!(f.range.len() <= cap);
            next = f.range.end;
            let left = frags.len() - 1 - i;
            prop_assert_eq!(f.fragments_left, if left == 0 { None } else { Some(left as u16) });
        }
        prop_assert_eq!(next, total);
    }

    #[test]
    fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..32)) {
        if let Ok(packet) = SoePacket::new_checked(&bytes[..])
            && let Ok(repr) = SoeRepr::parse(&packet) {
                let _ = repr.to_string();
            }
        if let Ok(s) = core::str::from_utf8(&bytes) {
            let _ = s.parse::<Idn>();
        }
    }
}
