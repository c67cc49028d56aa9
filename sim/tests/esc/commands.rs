//! Working counters, addressing and data of every datagram command, with whole frames
//! through a segment (ETG.1000.4, ETG.1000.3, spec-notes §commands, §addressing, §esc.fmmu).

use crate::segment_support;

use ecat_wire::command::Command;
use ecat_wire::register::fmmu::{Fmmu, FmmuRepr};
use proptest::prelude::*;
use segment_support::*;

#[test]
fn brd_counts_the_slaves() {
    let mut bench = Bench::new(3);
    let r = bench.one(b(Command::Brd, 0x0000, &[0, 0]));
    assert_eq!(r.wkc, 3, "C.1: WKC = number of slaves");
    assert_eq!(r.adp, 3, "every slave incremented ADP");
    assert_eq!(r.data, vec![0x04, 0x01], "OR of type/revision");
}

#[test]
fn aprd_addresses_the_second_slave() {
    let mut bench = Bench::new(3);
    bench.assign_addresses();
    let r = bench.one(ap(Command::Aprd, 1, 0x0010, &[0, 0]));
    assert_eq!((r.wkc, r.u16()), (1, 0x1002));
    assert_eq!(r.adp, 2, "0xFFFF incremented three times");
    let r = bench.one(ap(Command::Aprd, 3, 0x0010, &[0, 0]));
    assert_eq!(r.wkc, 0, "no fourth slave");
    let r = bench.one(ap(Command::Apwr, 2, 0x0010, &[0x34, 0x12]));
    assert_eq!(r.wkc, 1);
    assert_eq!(bench.esc(2).station_address(), 0x1234);
}

#[test]
fn fprd_by_station_and_by_alias_only_when_enabled() {
    let mut bench = Bench::empty();
    bench.push(Default::default(), sii(0));
    bench.push(Default::default(), sii(0x0777));
    bench.assign_addresses();
    let r = bench.one(fp(Command::Fprd, 0x1002, 0x0012, &[0, 0]));
    assert_eq!(
        (r.wkc, r.u16(), r.adp),
        (1, 0x0777, 0x1002),
        "ADP unchanged"
    );
    assert_eq!(bench.one(fp(Command::Fprd, 0x0777, 0x0010, &[0, 0])).wkc, 0);
    assert_eq!(bench.one(b(Command::Bwr, 0x0103, &[0x01])).wkc, 2);
    let r = bench.one(fp(Command::Fprd, 0x0777, 0x0010, &[0, 0]));
    assert_eq!((r.wkc, r.u16()), (1, 0x1002), "alias enabled");
    assert_eq!(bench.one(fp(Command::Fprd, 0x1001, 0x0010, &[0, 0])).wkc, 1);
}

#[test]
fn read_write_commands_count_three_per_slave() {
    let mut bench = Bench::new(3);
    bench.assign_addresses();
    let r = bench.one(ap(Command::Aprw, 1, 0x0010, &[0x22, 0x20]));
    assert_eq!((r.wkc, r.u16()), (3, 0x1002), "old value returned");
    let r = bench.one(fp(Command::Fprw, 0x2022, 0x0010, &[0x02, 0x10]));
    assert_eq!((r.wkc, r.u16()), (3, 0x2022));
    let r = bench.one(b(Command::Brw, 0x0020, &[0x00]));
    assert_eq!(r.wkc, 9, "BRW: 3 per slave");
    let r = bench.one(b(Command::Bwr, 0x0200, &[0x04, 0x00]));
    assert_eq!(r.wkc, 3);
}

#[test]
fn read_multiple_write_counts_every_slave() {
    let mut bench = Bench::new(3);
    bench.assign_addresses();
    let r = bench.one(fp(Command::Frmw, 0x1001, 0x0910, &[0; 8]));
    assert_eq!(r.wkc, 3, "1 read + 2 writes");
    let r = bench.one(ap(Command::Armw, 1, 0x0910, &[0; 8]));
    assert_eq!((r.wkc, r.adp), (3, 2));
    // FRMW on 0x0010: slave 0 reads its address, the others take it.
    bench.one(fp(Command::Frmw, 0x1001, 0x0010, &[0, 0]));
    assert_eq!(bench.esc(2).station_address(), 0x1001);
}

fn fmmu_bytes(f: FmmuRepr) -> Vec<u8> {
    let mut buf = vec![0u8; 16];
    f.emit(&mut Fmmu::new_unchecked(&mut buf[..])).unwrap();
    buf
}

/// Brings slave `p` with 2 bytes of outputs and 1 byte of inputs to SAFEOP, with the three
/// FMMUs of the worked example (spec-notes §esc.fmmu) shifted to `logical` (outputs, inputs, SM1 status).
fn process_data_slave(bench: &mut Bench, p: usize, logical: u32) {
    {
        let mut d = bench.dev(p);
        d.sizes.outputs = 2;
        d.sizes.inputs = 1;
        d.inputs = vec![0x5A];
    }
    let s = station(p);
    bench.bring_to_preop(s);
    bench.configure_process_data(s, 2, 1);
    let fmmus = [
        FmmuRepr::outputs(logical, 2, 0x1100),
        FmmuRepr::inputs(logical + 2, 1, 0x1180),
        FmmuRepr::inputs(logical + 3, 1, 0x080D),
    ];
    let bytes: Vec<u8> = fmmus.iter().flat_map(|f| fmmu_bytes(*f)).collect();
    assert_eq!(bench.one(fp(Command::Fpwr, s, 0x0600, &bytes)).wkc, 1);
    assert_eq!(bench.request(s, 0x0004), (0x0004, 0));
}

#[test]
fn c18_fmmu_bytes_and_lrw_wkc_3() {
    let mut bench = Bench::new(1);
    bench.assign_addresses();
    process_data_slave(&mut bench, 0, 0);
    // The FMMU registers hold exactly the bytes of the worked example (spec-notes §esc.fmmu).
    let r = bench.one(fp(Command::Fprd, 0x1001, 0x0600, &[0; 48]));
    assert_eq!(
        r.data,
        [
            0x00, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x07, 0x00, 0x11, 0x00, 0x02, 0x01, 0x00,
            0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x07, 0x80, 0x11, 0x00, 0x01,
            0x01, 0x00, 0x00, 0x00, 0x03, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x07, 0x0d, 0x08,
            0x00, 0x01, 0x01, 0x00, 0x00, 0x00,
        ]
    );
    let r = bench.one(l(Command::Lrw, 0, &[0xA1, 0xB2, 0, 0]));
    assert_eq!(
        r.wkc, 3,
        "write +2, reads +1 once although two read FMMUs hit"
    );
    assert_eq!(r.data[..3], [0xA1, 0xB2, 0x5A]);
    assert_eq!(r.data[3] & 0x08, 0, "SM1 empty");
    assert_eq!(bench.dev(0).outputs, vec![vec![0xA1, 0xB2]]);
    let r = bench.one(l(Command::Lrd, 0, &[0; 4]));
    assert_eq!(r.wkc, 1, "two read FMMUs, one increment");
    let r = bench.one(l(Command::Lwr, 0, &[1, 2, 3, 4]));
    assert_eq!(r.wkc, 1);
    assert_eq!(
        bench.one(l(Command::Lrd, 0x100, &[0; 4])).wkc,
        0,
        "no mapping"
    );
}

#[test]
fn lrw_over_several_slaves_counts_per_slave() {
    let mut bench = Bench::new(3);
    bench.assign_addresses();
    for p in 0..3 {
        process_data_slave(&mut bench, p, 4 * p as u32);
    }
    let r = bench.one(l(Command::Lrw, 0, &[0; 12]));
    assert_eq!(r.wkc, 9, "2 × outputs + 1 × inputs per slave");
    let r = bench.one(l(Command::Lrw, 4, &[0; 2]));
    assert_eq!(r.wkc, 2, "only slave 1's outputs");
}

#[test]
fn non_ethercat_frames_are_not_processed() {
    let mut bench = Bench::new(1);
    let mut ip = vec![0u8; 60];
    ip[12] = 0x08;
    assert!(!bench.segment.process(&mut ip));
    let mut short = vec![0xFF; 10];
    assert!(!bench.segment.process(&mut short));
    // EtherCAT type 5 (mailbox over UDP gateway) is not a datagram frame.
    let mut frame = vec![0u8; 60];
    frame[12] = 0x88;
    frame[13] = 0xA4;
    frame[14] = 0x00;
    frame[15] = 0x50;
    let copy = frame.clone();
    assert!(!bench.segment.process(&mut frame));
    assert_eq!(frame, copy, "untouched");
}

#[test]
fn irq_field_carries_masked_events() {
    let mut bench = Bench::new(2);
    bench.assign_addresses();
    bench.one(b(Command::Bwr, 0x0200, &[0x08, 0x00]));
    // An invalid request on slave 1 changes its AL status (error).
    bench.one(fp(Command::Fpwr, 0x1002, 0x0120, &[0x04, 0x00]));
    let r = bench.one(b(Command::Brd, 0x0130, &[0, 0]));
    assert_eq!(r.irq, 0x0008);
    assert_eq!(
        bench.one(b(Command::Nop, 0, &[])).irq,
        0,
        "read acknowledged it"
    );
}

#[test]
fn malformed_chain_stops_and_counts() {
    let mut bench = Bench::new(1);
    let mut buf = vec![0u8; 60];
    let mut builder = ecat_wire::datagram::FrameBuilder::new(&mut buf).unwrap();
    builder
        .push_zeroed(
            Command::Brd,
            0,
            ecat_wire::command::DatagramAddress::broadcast(0),
            2,
        )
        .unwrap();
    let len = builder.finish(MASTER_MAC).unwrap();
    buf[16 + 7] |= 0x80; // M bit set on the last datagram
    assert!(bench.segment.process(&mut buf[..len]));
    assert_eq!(bench.esc(0).read_u8(0x030C), 1, "processing unit error");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]
    #[test]
    fn any_frame_is_handled_without_panic(
        payload in proptest::collection::vec(any::<u8>(), 0..200),
        header in any::<u16>(),
    ) {
        let mut bench = Bench::new(2);
        let mut frame = vec![0xFFu8; 12];
        frame.extend_from_slice(&[0x88, 0xA4]);
        frame.extend_from_slice(&((header & 0x07FF) | 0x1000).to_le_bytes());
        frame.extend_from_slice(&payload);
        let _ = bench.segment.process(&mut frame);
    }

    #[test]
    fn any_datagram_is_handled_without_panic(
        command in 0u8..16,
        address in any::<u32>(),
        data in proptest::collection::vec(any::<u8>(), 0..64),
    ) {
        let mut bench = Bench::new(2);
        bench.assign_addresses();
        bench.bring_to_preop(0x1001);
        let d = Dg { command: Command::from(command), address, data };
        let _ = bench.send(&[d.clone(), d]);
    }
}
