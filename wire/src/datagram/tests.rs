use super::*;
use crate::frame::EthercatFrame;
use proptest::prelude::*;

fn parse(bytes: &[u8]) -> Result<DatagramRepr<'_>> {
    DatagramRepr::parse(&Datagram::new_checked(bytes)?)
}

fn emit(repr: &DatagramRepr<'_>) -> Vec<u8> {
    let mut bytes = vec![0xa5u8; repr.buffer_len()];
    repr.emit(&mut Datagram::new_unchecked(&mut bytes[..]))
        .unwrap();
    bytes
}

/// Checks parse → expected and emit (into 0xa5) → identical bytes.
fn check_exact(bytes: &[u8], expected: DatagramRepr<'_>) {
    assert_eq!(parse(bytes).unwrap(), expected);
    assert_eq!(emit(&expected), bytes);
}

fn node(station: u16, ado: u16) -> DatagramAddress {
    DatagramAddress::Node { station, ado }
}

// ETG.1000.4, spec-notes §commands, datagram part: BRD idx 1, ADP 0, ADO 0, len 2.
static C1_BRD: [u8; 14] = [
    0x07, 0x01, 0x00, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
];

#[test]
fn c1_brd() {
    check_exact(
        &C1_BRD,
        DatagramRepr::request(Command::Brd, 1, DatagramAddress::broadcast(0), &[0, 0]),
    );
}

#[test]
fn c2_apwr_station_addresses() {
    let first = [
        0x02, 0x02, 0x00, 0x00, 0x10, 0x00, 0x02, 0x00, 0x00, 0x00, 0x01, 0x10, 0x00, 0x00,
    ];
    let second = [
        0x02, 0x03, 0xff, 0xff, 0x10, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x10, 0x00, 0x00,
    ];
    let pos = DatagramAddress::position;
    check_exact(
        &first,
        DatagramRepr::request(Command::Apwr, 2, pos(0, 0x0010), &[0x01, 0x10]),
    );
    check_exact(
        &second,
        DatagramRepr::request(Command::Apwr, 3, pos(1, 0x0010), &[0x02, 0x10]),
    );
    let parsed = parse(&second).unwrap();
    assert_eq!(parsed.typed_address().unwrap().ring_position(), Some(1));
    assert_eq!(
        parsed.to_string(),
        "APWR idx=3 adp=0xffff ado=0x0010 len=2 wkc=0"
    );
}

#[test]
fn c3_sii_read() {
    let command = [
        0x05, 0x04, 0x01, 0x10, 0x02, 0x05, 0x06, 0x00, 0x00, 0x00, 0x00, 0x01, 0x08, 0x00, 0x00,
        0x00, 0x00, 0x00,
    ];
    let fpwr = DatagramRepr::request(
        Command::Fpwr,
        4,
        node(0x1001, 0x0502),
        &[0x00, 0x01, 0x08, 0x00, 0x00, 0x00],
    );
    check_exact(&command, fpwr);
    assert_eq!(
        fpwr.to_string(),
        "FPWR idx=4 adp=0x1001 ado=0x0502 len=6 wkc=0"
    );
    let data = [
        0x04, 0x05, 0x01, 0x10, 0x08, 0x05, 0x08, 0x00, 0x00, 0x00, 0, 0, 0, 0, 0, 0, 0, 0, 0x00,
        0x00,
    ];
    check_exact(
        &data,
        DatagramRepr::request(Command::Fprd, 5, node(0x1001, 0x0508), &[0; 8]),
    );
    // Returned from an EL2004 (spec-notes §esc.sii-if) with WKC 1: vendor 2, product 0x07D43052.
    let mut returned = data;
    returned[10..18].copy_from_slice(&[0x02, 0x00, 0x00, 0x00, 0x52, 0x30, 0xd4, 0x07]);
    returned[18] = 0x01;
    let parsed = parse(&returned).unwrap();
    assert_eq!(
        parsed.data,
        &[0x02, 0x00, 0x00, 0x00, 0x52, 0x30, 0xd4, 0x07]
    );
    assert_eq!(parsed.wkc, 1);
}

#[test]
fn c4_mailbox_sync_managers() {
    // FPWR idx 6 to station 0x1001, ADO 0x0800, 16 bytes (header worked out by hand).
    let sm = [
        0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00, 0x80, 0x10, 0x80, 0x00, 0x22, 0x00, 0x01,
        0x00,
    ];
    let mut bytes = vec![0x05, 0x06, 0x01, 0x10, 0x00, 0x08, 0x10, 0x00, 0x00, 0x00];
    bytes.extend_from_slice(&sm);
    bytes.extend_from_slice(&[0x00, 0x00]);
    check_exact(
        &bytes,
        DatagramRepr::request(Command::Fpwr, 6, node(0x1001, 0x0800), &sm),
    );
}

#[test]
fn c5_al_control() {
    for (data, idx) in [([0x02, 0x00], 7u8), ([0x12, 0x00], 8u8)] {
        let bytes = [
            0x05, idx, 0x01, 0x10, 0x20, 0x01, 0x02, 0x00, 0x00, 0x00, data[0], data[1], 0x00, 0x00,
        ];
        check_exact(
            &bytes,
            DatagramRepr::request(Command::Fpwr, idx, node(0x1001, 0x0120), &data),
        );
    }
}

#[test]
fn c17_dc_datagrams() {
    let latch = [
        0x08, 0x05, 0x00, 0x00, 0x00, 0x09, 0x04, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
        0x00,
    ];
    check_exact(
        &latch,
        DatagramRepr::request(Command::Bwr, 5, DatagramAddress::broadcast(0x0900), &[0; 4]),
    );
    let frmw = [
        0x0e, 0x06, 0x01, 0x10, 0x10, 0x09, 0x08, 0x00, 0x00, 0x00, 0, 0, 0, 0, 0, 0, 0, 0, 0x00,
        0x00,
    ];
    check_exact(
        &frmw,
        DatagramRepr::request(Command::Frmw, 6, node(0x1001, 0x0910), &[0; 8]),
    );
}

#[test]
fn c18_cyclic_lrw() {
    // Outputs o0 o1 = 0x12 0x34 (example values), 2 input bytes zero.
    let bytes = [
        0x0c, 0x07, 0x00, 0x00, 0x00, 0x00, 0x04, 0x00, 0x00, 0x00, 0x12, 0x34, 0x00, 0x00, 0x00,
        0x00,
    ];
    let lrw = DatagramRepr::request(
        Command::Lrw,
        7,
        DatagramAddress::Logical(0),
        &[0x12, 0x34, 0x00, 0x00],
    );
    check_exact(&bytes, lrw);
    // Returned with the expected WKC 3.
    let mut returned = bytes;
    returned[14] = 0x03;
    let parsed = parse(&returned).unwrap();
    assert_eq!(parsed.wkc, 3);
    assert_eq!(parsed.to_string(), "LRW idx=7 log=0x00000000 len=4 wkc=3");
}

#[test]
fn seed_station_address_write() {
    // spec-notes §capture: APWR to position 0, ADO 0x0010, data 0x03E9 (TwinCAT's station 1001).
    let bytes = [
        0x02, 0x81, 0x00, 0x00, 0x10, 0x00, 0x02, 0x00, 0x00, 0x00, 0xe9, 0x03, 0x00, 0x00,
    ];
    check_exact(
        &bytes,
        DatagramRepr::request(
            Command::Apwr,
            0x81,
            DatagramAddress::position(0, 0x0010),
            &1001u16.to_le_bytes(),
        ),
    );
}

/// spec-notes §capture, first frame: BWR idx 0x80 to ADO 0x0101 (loop control), 1 byte 00,
/// EtherCAT header 0x100d; the source MAC is all zeros in the capture.
static SEED_FIRST_FRAME: [u8; 60] = [
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x88, 0xa4, 0x0d,
    0x10, // EtherCAT header 0x100d: type 1, length 13
    0x08, 0x80, 0x00, 0x00, 0x01, 0x01, 0x01, 0x00, 0x00, 0x00, // BWR header
    0x00, // data
    0x00, 0x00, // WKC
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    0, // 31 bytes of padding
];

#[test]
fn seed_first_frame_built_and_parsed() {
    let mut buffer = [0xa5u8; 128];
    let mut builder = FrameBuilder::new(&mut buffer).unwrap();
    let bwr = DatagramRepr::request(Command::Bwr, 0x80, DatagramAddress::broadcast(0x0101), &[0]);
    assert_eq!(builder.push(&bwr), Ok(16));
    let total = builder.finish([0; 6]).unwrap();
    assert_eq!(total, 60);
    assert_eq!(buffer[..60], SEED_FIRST_FRAME);
    let frame = EthercatFrame::parse(&SEED_FIRST_FRAME).unwrap();
    assert_eq!(frame.header.length, 13);
    let all: Vec<_> = frame.datagrams().unwrap().collect();
    assert_eq!(all, vec![Ok(bwr)]);
}

#[test]
fn c1_frame_built() {
    let mut buffer = [0xa5u8; 60];
    let mut builder = FrameBuilder::new(&mut buffer).unwrap();
    let brd = DatagramRepr::request(Command::Brd, 1, DatagramAddress::broadcast(0), &[0, 0]);
    builder.push(&brd).unwrap();
    assert_eq!(builder.finish([0x02, 0, 0, 0, 0, 0x01]), Ok(60));
    let mut expected = [0u8; 60];
    expected[..6].copy_from_slice(&[0xff; 6]);
    expected[6..16].copy_from_slice(&[0x02, 0, 0, 0, 0, 0x01, 0x88, 0xa4, 0x0e, 0x10]);
    expected[16..30].copy_from_slice(&C1_BRD);
    assert_eq!(buffer, expected);
}

/// The cyclic frame of spec-notes §capture: LRD 0x11000 (inputs, 2 bytes), LWR 0x12000 (outputs, 2 bytes
/// 0xAA 0x55), LRD 0x40000 (1 byte: SM1 status 0x080D via FMMU, bit 3 = mailbox full),
/// FRMW 0x0910 from station 0x03E9 (8 bytes DC system time). Indices 0x10..=0x13.
#[rustfmt::skip]
static SEED_CYCLIC: [u8; 77] = [
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02, 0x00, 0x00, 0x00, 0x00, 0x01, 0x88, 0xa4,
    0x3d, 0x10, // 61 = 14 + 14 + 13 + 20 bytes, type 1
    0x0a, 0x10, 0x00, 0x10, 0x01, 0x00, 0x02, 0x80, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x0b, 0x11, 0x00, 0x20, 0x01, 0x00, 0x02, 0x80, 0x00, 0x00, 0xaa, 0x55, 0x00, 0x00,
    0x0a, 0x12, 0x00, 0x00, 0x04, 0x00, 0x01, 0x80, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x0e, 0x13, 0xe9, 0x03, 0x10, 0x09, 0x08, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
];

#[test]
fn seed_cyclic_frame() {
    let mut buffer = [0xa5u8; 1514];
    let mut builder = FrameBuilder::new(&mut buffer).unwrap();
    let log = DatagramAddress::Logical;
    let offsets = [
        builder.push_zeroed(Command::Lrd, 0x10, log(0x11000), 2),
        builder.push(&DatagramRepr::request(
            Command::Lwr,
            0x11,
            log(0x12000),
            &[0xaa, 0x55],
        )),
        builder.push_zeroed(Command::Lrd, 0x12, log(0x40000), 1),
        builder.push_zeroed(Command::Frmw, 0x13, node(0x03E9, 0x0910), 8),
    ]
    .map(Result::unwrap);
    assert_eq!(offsets, [16, 30, 44, 57]);
    assert_eq!(builder.datagram_count(), 4);
    assert_eq!(builder.len(), 77);
    let total = builder.finish([0x02, 0, 0, 0, 0, 0x01]).unwrap();
    assert_eq!(total, 77, "above the minimum: no padding");
    assert_eq!(buffer[..77], SEED_CYCLIC);

    let frame = EthercatFrame::parse(&buffer[..total]).unwrap();
    assert_eq!(frame.header.length, 61);
    let parsed: Vec<_> = frame.datagrams().unwrap().map(Result::unwrap).collect();
    let more: Vec<_> = parsed.iter().map(|d| d.more).collect();
    assert_eq!(more, [true, true, true, false]);
    let commands: Vec<_> = parsed.iter().map(|d| d.command).collect();
    assert_eq!(
        commands,
        [Command::Lrd, Command::Lwr, Command::Lrd, Command::Frmw]
    );
    assert_eq!(parsed[1].data, &[0xaa, 0x55]);
    assert_eq!(parsed[3].typed_address(), Some(node(0x03E9, 0x0910)));
    // Read back by offset, as the bus loop does with the offsets `push` returned.
    for (offset, expected) in offsets.iter().zip(&parsed) {
        let view = frame.datagram_at(*offset).unwrap();
        assert_eq!(DatagramRepr::parse(&view).unwrap(), *expected);
    }
    assert_eq!(
        frame.to_string(),
        "ETH 02:00:00:00:00:01 > ff:ff:ff:ff:ff:ff type=0x88a4 ECAT EtherCAT command len=61\n  \
         LRD idx=16 log=0x00011000 len=2 wkc=0\n  \
         LWR idx=17 log=0x00012000 len=2 wkc=0\n  \
         LRD idx=18 log=0x00040000 len=1 wkc=0\n  \
         FRMW idx=19 adp=0x03e9 ado=0x0910 len=8 wkc=0"
    );
}

#[test]
fn padding_after_last_datagram_is_ignored() {
    // The count-slaves BRD of spec-notes §commands followed by garbage that is not a datagram: M = 0 ends the chain.
    let mut payload = C1_BRD.to_vec();
    payload.extend_from_slice(&[0xff; 20]);
    let mut chain = Datagrams::new(&payload);
    assert!(chain.next().unwrap().is_ok());
    assert!(chain.next().is_none());
    assert_eq!(chain.offset(), 14);
}

#[test]
fn more_bit_without_following_datagram_is_an_error() {
    let mut payload = C1_BRD;
    payload[7] = 0x80;
    let mut chain = Datagrams::new(&payload);
    assert!(chain.next().unwrap().unwrap().more);
    assert_eq!(
        chain.next().unwrap(),
        Err(WireError::Truncated {
            what: "datagram chain (M bit set)",
            need: 12,
            have: 0
        })
    );
    assert!(chain.next().is_none(), "an error ends the iteration");
    // M = 1 followed by a partial datagram is an error too.
    let mut longer = payload.to_vec();
    longer.extend_from_slice(&C1_BRD[..11]);
    let results: Vec<_> = Datagrams::new(&longer).collect();
    assert_eq!(results.len(), 2);
    assert!(results[1].is_err());
    // An empty payload has no datagram.
    assert!(Datagrams::new(&[]).next().unwrap().is_err());
}

#[test]
fn mutable_walk_processes_in_place() {
    // The reference cyclic frame's chain as an emulated slave would see it: bump every WKC
    // and fill the 1-byte mailbox status read with bit 3 (SM1 full).
    let mut payload = SEED_CYCLIC[16..].to_vec();
    payload.extend_from_slice(&[0u8; 5]); // padding is ignored
    let mut walk = DatagramsMut::new(&mut payload);
    for item in walk.by_ref() {
        let mut datagram = item.unwrap();
        if datagram.typed_address() == Some(DatagramAddress::Logical(0x40000)) {
            datagram.data_mut()[0] = 0x08;
        }
        let wkc = datagram.wkc();
        datagram.set_wkc(wkc + 1);
    }
    assert_eq!(walk.offset(), 61);
    let wkcs: Vec<_> = Datagrams::new(&payload).map(|d| d.unwrap().wkc).collect();
    assert_eq!(wkcs, [1, 1, 1, 1]);
    assert_eq!(
        payload[38], 0x08,
        "data byte of the third datagram (offset 28 + 10)"
    );

    // Same errors as the shared walk.
    let mut dangling = C1_BRD;
    dangling[7] = 0x80;
    let results: Vec<_> = DatagramsMut::new(&mut dangling)
        .map(|r| r.map(|_| ()))
        .collect();
    assert_eq!(
        results,
        [
            Ok(()),
            Err(WireError::Truncated {
                what: "datagram chain (M bit set)",
                need: 12,
                have: 0
            })
        ]
    );
    let mut reserved = C1_BRD;
    reserved[7] = 0x08;
    assert!(matches!(
        DatagramsMut::new(&mut reserved).next(),
        Some(Err(WireError::ReservedBits { .. }))
    ));
    // A slave controller's walk takes it, leaving the bits alone.
    let mut walk = DatagramsMut::ignoring_reserved_bits(&mut reserved);
    let datagram = walk.next().unwrap().unwrap();
    assert_eq!(datagram.len_flags() & 0x3800, 0x0800);
    assert!(walk.next().is_none());
    assert!(DatagramsMut::new(&mut []).next().unwrap().is_err());
}

#[test]
fn length_beyond_bytes_is_bad_length() {
    // BRD declaring 3 data bytes: 10 + 3 + 2 = 15 needed, 14 present.
    let mut bytes = C1_BRD;
    bytes[6] = 0x03;
    assert_eq!(
        Datagram::new_checked(&bytes[..]).unwrap_err(),
        WireError::BadLength {
            what: "datagram length",
            declared: 3,
            available: 2
        }
    );
    assert!(matches!(
        Datagram::new_checked(&C1_BRD[..9]),
        Err(WireError::Truncated {
            what: "datagram header",
            ..
        })
    ));
    assert!(matches!(
        Datagram::new_checked(&C1_BRD[..11]),
        Err(WireError::Truncated {
            what: "datagram",
            need: 14,
            have: 11
        })
    ));
    // The declared length inside a frame counts too.
    assert!(matches!(
        Datagrams::new(&bytes).next(),
        Some(Err(WireError::BadLength { .. }))
    ));
}

#[test]
fn reserved_bits_are_refused() {
    for bit in [0x08u8, 0x10, 0x20] {
        let mut bytes = C1_BRD;
        bytes[7] = bit;
        assert_eq!(
            parse(&bytes).unwrap_err(),
            WireError::ReservedBits {
                what: "datagram flags",
                value: u32::from(bit) << 8
            }
        );
    }
}

#[test]
fn flags_and_irq() {
    // C = 0x4000, M = 0x8000 → len/flags `02 c0`; IRQ 0x0102 → `02 01`.
    let mut bytes = C1_BRD;
    bytes[7] = 0xc0;
    bytes[8] = 0x02;
    bytes[9] = 0x01;
    let repr = DatagramRepr {
        circulating: true,
        more: true,
        irq: 0x0102,
        ..DatagramRepr::request(Command::Brd, 1, DatagramAddress::broadcast(0), &[0, 0])
    };
    check_exact(&bytes, repr);
    assert_eq!(
        repr.to_string(),
        "BRD idx=1 adp=0x0000 ado=0x0000 len=2 wkc=0 circulating irq=0x0102"
    );
    let nop = DatagramRepr::request(Command::Unknown(0x20), 0, DatagramAddress::Logical(5), &[]);
    assert_eq!(
        nop.to_string(),
        "CMD(0x20) idx=0 addr=0x00000005 len=0 wkc=0"
    );
}

#[test]
fn view_setters() {
    let mut bytes = C1_BRD;
    let mut view = Datagram::new_checked(&mut bytes[..]).unwrap();
    view.set_adp(3);
    view.set_wkc(3);
    view.set_more(true);
    view.set_more(false);
    view.set_circulating(true);
    view.data_mut().copy_from_slice(&[0x11, 0x00]);
    assert_eq!(view.total_len(), 14);
    assert_eq!(
        bytes,
        [
            0x07, 0x01, 0x03, 0x00, 0x00, 0x00, 0x02, 0x40, 0x00, 0x00, 0x11, 0x00, 0x03, 0x00
        ]
    );
}

#[test]
fn emit_refusals_write_nothing() {
    let big = [0u8; MAX_DATA_LEN + 1];
    let repr = DatagramRepr::request(Command::Lrw, 0, DatagramAddress::Logical(0), &big);
    let mut bytes = vec![0u8; repr.buffer_len()];
    assert!(matches!(
        repr.emit(&mut Datagram::new_unchecked(&mut bytes[..])),
        Err(WireError::BadLength {
            declared: 1487,
            available: 1486,
            ..
        })
    ));
    assert!(bytes.iter().all(|b| *b == 0));
    let small = DatagramRepr::request(Command::Lrw, 0, DatagramAddress::Logical(0), &[1, 2]);
    let mut short = [0u8; 13];
    assert!(matches!(
        small.emit(&mut Datagram::new_unchecked(&mut short[..])),
        Err(WireError::BufferTooSmall {
            need: 14,
            have: 13,
            ..
        })
    ));
    assert_eq!(short, [0u8; 13]);
}

#[test]
fn over_long_declared_length_is_refused_by_parse() {
    // len 1487 (0x05CF) with all bytes present: over the MTU limit.
    let mut bytes = vec![0u8; OVERHEAD + 1487];
    bytes[0] = 0x0c;
    bytes[6] = 0xcf;
    bytes[7] = 0x05;
    assert!(Datagram::new_checked(&bytes[..]).is_ok());
    assert!(matches!(
        parse(&bytes),
        Err(WireError::BadLength {
            declared: 1487,
            available: 1486,
            ..
        })
    ));
}

#[test]
fn builder_limits() {
    let mut small = [0u8; 59];
    assert!(matches!(
        FrameBuilder::new(&mut small),
        Err(WireError::BufferTooSmall {
            need: 60,
            have: 59,
            ..
        })
    ));
    // A maximum datagram fills a 1514-byte frame exactly; nothing fits after it.
    let mut buffer = vec![0xa5u8; 2000];
    let mut builder = FrameBuilder::new(&mut buffer).unwrap();
    assert_eq!(builder.remaining_data(), MAX_DATA_LEN);
    let full = builder
        .push_zeroed(Command::Lrw, 0, DatagramAddress::Logical(0), MAX_DATA_LEN)
        .unwrap();
    assert_eq!(full, 16);
    assert_eq!(builder.remaining_data(), 0);
    assert_eq!(
        builder.push_zeroed(Command::Nop, 1, DatagramAddress::Logical(0), 0),
        Err(WireError::BufferTooSmall {
            what: "EtherCAT frame",
            need: 1526,
            have: 1514
        })
    );
    assert!(matches!(
        builder.push_zeroed(
            Command::Nop,
            1,
            DatagramAddress::Logical(0),
            MAX_DATA_LEN + 1
        ),
        Err(WireError::BadLength { .. })
    ));
    assert_eq!(builder.datagram_count(), 1);
    assert_eq!(builder.finish([0; 6]), Ok(1514));
    assert_eq!(buffer[14..16], [0xda, 0x15], "length 1498 = 0x5DA, type 1");
    assert_eq!(buffer[1514], 0xa5, "nothing written past the frame");

    // A 60-byte buffer takes datagrams up to 44 bytes in total.
    let mut buffer = [0u8; 60];
    let mut builder = FrameBuilder::new(&mut buffer).unwrap();
    builder
        .push_zeroed(Command::Brd, 0, DatagramAddress::broadcast(0), 30)
        .unwrap();
    assert!(matches!(
        builder.push_zeroed(Command::Brd, 1, DatagramAddress::broadcast(0), 1),
        Err(WireError::BufferTooSmall {
            need: 71,
            have: 60,
            ..
        })
    ));
    // An empty frame is refused.
    let mut buffer = [0u8; 60];
    assert!(
        FrameBuilder::new(&mut buffer)
            .unwrap()
            .finish([0; 6])
            .is_err()
    );
}

#[test]
fn builder_datagram_mut_fills_in_place() {
    let mut buffer = [0u8; 64];
    let mut builder = FrameBuilder::new(&mut buffer).unwrap();
    let first = builder
        .push_zeroed(Command::Lwr, 1, DatagramAddress::Logical(0x1000), 2)
        .unwrap();
    builder
        .push_zeroed(Command::Lrd, 2, DatagramAddress::Logical(0x2000), 2)
        .unwrap();
    builder
        .datagram_mut(first)
        .unwrap()
        .data_mut()
        .copy_from_slice(&[7, 8]);
    assert!(builder.datagram_mut(3).is_err());
    let total = builder.finish([0; 6]).unwrap();
    let frame = EthercatFrame::parse(&buffer[..total]).unwrap();
    assert_eq!(frame.datagram_at(first).unwrap().data(), &[7, 8]);
}

pub(crate) fn arb_datagram(
    max_data: usize,
) -> impl Strategy<Value = (DatagramRepr<'static>, Vec<u8>)> {
    (
        any::<u8>(),
        any::<u8>(),
        any::<u32>(),
        proptest::collection::vec(any::<u8>(), 0..=max_data),
        any::<bool>(),
        any::<bool>(),
        any::<u16>(),
        any::<u16>(),
    )
        .prop_map(|(cmd, index, address, data, circulating, more, irq, wkc)| {
            (
                DatagramRepr {
                    command: Command::from(cmd),
                    index,
                    address,
                    data: &[],
                    circulating,
                    more,
                    irq,
                    wkc,
                },
                data,
            )
        })
}

proptest! {
    #[test]
    fn round_trip((repr, data) in arb_datagram(64), tail in 0usize..4) {
        let repr = DatagramRepr { data: &data, ..repr };
        let mut bytes = vec![0u8; repr.buffer_len() + tail];
        repr.emit(&mut Datagram::new_unchecked(&mut bytes[..])).unwrap();
        prop_assert_eq!(parse(&bytes).unwrap(), repr);
    }

    #[test]
    fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
        if let Ok(view) = Datagram::new_checked(&bytes[..]) {
            let _ = (view.data(), view.wkc(), view.typed_address(), view.total_len());
            let _ = DatagramRepr::parse(&view).map(|d| d.to_string());
        }
    }

    #[test]
    fn chain_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..128)) {
        let mut count = 0;
        for item in Datagrams::new(&bytes) {
            count += 1;
            let _ = item.map(|d| d.to_string());
        }
        // Each datagram takes at least 12 bytes, plus one final error at most.
        prop_assert!(count <= bytes.len() / OVERHEAD + 1);
    }

    #[test]
    fn mutable_chain_agrees_with_shared_chain(
        mut bytes in proptest::collection::vec(any::<u8>(), 0..128),
    ) {
        let shared: Vec<_> = Datagrams::new(&bytes)
            .map(|r| r.map(|d| d.buffer_len()))
            .collect();
        let mutable: Vec<_> = DatagramsMut::new(&mut bytes)
            .map(|r| r.map(|d| d.total_len()))
            .collect();
        prop_assert_eq!(shared, mutable);
    }

    #[test]
    fn builder_round_trip(
        datagrams in proptest::collection::vec(arb_datagram(40), 1..8),
        source: [u8; 6],
    ) {
        let mut buffer = vec![0xa5u8; 1514];
        let mut builder = FrameBuilder::new(&mut buffer).unwrap();
        let mut pushed = Vec::new();
        for (repr, data) in &datagrams {
            let repr = DatagramRepr { data, ..*repr };
            let offset = builder.push(&repr).unwrap();
            pushed.push((offset, repr));
        }
        let chain_len: usize = pushed.iter().map(|(_, d)| d.buffer_len()).sum();
        let total = builder.finish(source).unwrap();
        prop_assert_eq!(total, (16 + chain_len).max(60));
        let frame = EthercatFrame::parse(&buffer[..total]).unwrap();
        prop_assert_eq!(frame.ethernet.source, source);
        prop_assert_eq!(usize::from(frame.header.length), chain_len);
        prop_assert!(buffer[16 + chain_len..total].iter().all(|b| *b == 0));
        let parsed: Vec<_> = frame.datagrams().unwrap().collect::<Result<_>>().unwrap();
        prop_assert_eq!(parsed.len(), pushed.len());
        let last = pushed.len() - 1;
        for (i, ((offset, sent), got)) in pushed.iter().zip(&parsed).enumerate() {
            let expected = DatagramRepr { more: i != last, ..*sent };
            prop_assert_eq!(*got, expected);
            let view = frame.datagram_at(*offset).unwrap();
            prop_assert_eq!(DatagramRepr::parse(&view).unwrap(), expected);
        }
    }
}
