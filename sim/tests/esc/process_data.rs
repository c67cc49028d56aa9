//! Process data through the 3-buffer SyncManagers and FMMUs, from INIT to OP with whole
//! frames (ETG.1000.4, spec-notes §esc.fmmu, §esc.sm, §bringup).

use crate::segment_support;

use ecat_wire::command::Command;
use ecat_wire::register::fmmu::{Fmmu, FmmuRepr};
use ecat_wire::sii::SiiBuilder;
use ecat_wire::sii::fixed::{MailboxProtocols, SiiFixedRepr, SiiMailboxArea};
use ecat_wire::sii::syncm::{SyncmEnable, SyncmEntry, SyncmType};
use segment_support::*;

const S: u16 = 0x1001;

fn fmmu(f: FmmuRepr) -> Vec<u8> {
    let mut bytes = vec![0u8; 16];
    f.emit(&mut Fmmu::new_unchecked(&mut bytes[..])).unwrap();
    bytes
}

/// One slave with 4 bytes of outputs and 2 bytes of inputs in SAFEOP; outputs mapped at
/// logical 0x100, inputs at 0x104.
fn bench() -> Bench {
    let mut bench = Bench::new(1);
    {
        let mut d = bench.dev(0);
        d.sizes.outputs = 4;
        d.sizes.inputs = 2;
        d.inputs = vec![0x11, 0x22];
    }
    bench.assign_addresses();
    bench.bring_to_preop(S);
    bench.configure_process_data(S, 4, 2);
    let mut fmmus = fmmu(FmmuRepr::outputs(0x100, 4, 0x1100));
    fmmus.extend(fmmu(FmmuRepr::inputs(0x104, 2, 0x1180)));
    bench.one(fp(Command::Fpwr, S, 0x0600, &fmmus));
    assert_eq!(bench.request(S, 0x0004), (0x0004, 0));
    bench
}

#[test]
fn cyclic_exchange_to_op() {
    let mut bench = bench();
    assert_eq!(
        bench.request(S, 0x0008),
        (0x0014, 0x0019),
        "no valid outputs yet"
    );
    let r = bench.one(l(Command::Lrw, 0x100, &[1, 2, 3, 4, 0, 0]));
    assert_eq!(r.wkc, 3);
    assert_eq!(r.data, vec![1, 2, 3, 4, 0x11, 0x22]);
    assert_eq!(bench.request(S, 0x0018), (0x0008, 0));
    bench.dev(0).inputs = vec![0x33, 0x44];
    let r = bench.one(l(Command::Lrw, 0x100, &[5, 6, 7, 8, 0, 0]));
    assert_eq!((r.wkc, &r.data[4..]), (3, &[0x33u8, 0x44][..]));
    assert_eq!(bench.dev(0).outputs.last().unwrap(), &vec![5, 6, 7, 8]);
    let transitions = bench.dev(0).transitions.clone();
    assert_eq!(transitions.len(), 3, "{transitions:?}");
}

#[test]
fn outputs_change_buffer_only_on_the_last_byte() {
    let mut bench = bench();
    bench.one(l(Command::Lwr, 0x100, &[1, 1, 1, 1]));
    // A logical write of the first two output bytes only: not committed.
    let r = bench.one(l(Command::Lwr, 0x100, &[9, 9]));
    assert_eq!(r.wkc, 1);
    assert_eq!(bench.dev(0).outputs.len(), 1);
    // The master reading back SM2 gets the last complete buffer.
    let r = bench.one(fp(Command::Fprd, S, 0x1100, &[0; 4]));
    assert_eq!((r.wkc, r.data.as_slice()), (1, &[1u8, 1, 1, 1][..]));
    // Writing the last byte completes the buffer started above.
    bench.one(l(Command::Lwr, 0x103, &[7]));
    assert_eq!(bench.dev(0).outputs.last().unwrap(), &vec![9, 9, 1, 7]);
    let status = bench.one(fp(Command::Fprd, S, 0x0815, &[0])).data[0];
    assert_ne!(status & 0x30, 0x30, "a buffer has been written");
}

#[test]
fn inputs_are_consistent_within_a_buffer() {
    let mut bench = bench();
    let r = bench.one(l(Command::Lrd, 0x104, &[0]));
    assert_eq!(r.data, vec![0x11]);
    // The device changes its inputs while the read buffer is open; the rest of that buffer
    // still belongs to the old snapshot.
    bench.dev(0).inputs = vec![0x55, 0x66];
    let r = bench.one(l(Command::Lrd, 0x105, &[0]));
    assert_eq!(r.data, vec![0x22]);
    let r = bench.one(l(Command::Lrd, 0x104, &[0, 0]));
    assert_eq!(
        r.data,
        vec![0x55, 0x66],
        "a new read gets the newest complete buffer"
    );
}

#[test]
fn process_data_sms_stop_below_safeop() {
    let mut bench = bench();
    assert_eq!(bench.request(S, 0x0002), (0x0002, 0));
    let r = bench.one(l(Command::Lrw, 0x100, &[0; 6]));
    assert_eq!(
        r.wkc, 3,
        "FMMUs still map; the RAM behind them is plain memory now"
    );
    assert!(bench.dev(0).outputs.is_empty(), "the device gets nothing");
    assert_eq!(bench.one(fp(Command::Fprd, S, 0x0817, &[0])).data[0] & 1, 1);
}

#[test]
fn bit_oriented_slave_shares_a_logical_byte() {
    // Two slaves with 4 output bits each, packed into one logical byte (SOEM's bit slaves).
    let mut bench = Bench::new(2);
    bench.assign_addresses();
    for p in 0..2 {
        bench.dev(p).sizes.outputs = 1;
        let s = station(p);
        bench.bring_to_preop(s);
        bench.configure_process_data(s, 1, 0);
        let f = FmmuRepr {
            logical_start_bit: 4 * p as u8,
            logical_stop_bit: 4 * p as u8 + 3,
            ..FmmuRepr::outputs(0x200, 1, 0x1100)
        };
        bench.one(fp(Command::Fpwr, s, 0x0600, &fmmu(f)));
        assert_eq!(bench.request(s, 0x0004), (0x0004, 0));
    }
    let r = bench.one(l(Command::Lwr, 0x200, &[0xA5]));
    assert_eq!(r.wkc, 2);
    assert_eq!(bench.dev(0).outputs, vec![vec![0x05]]);
    assert_eq!(bench.dev(1).outputs, vec![vec![0x0A]]);
}

#[test]
fn simple_terminal_without_mailbox() {
    // Like an EL2004: no mailbox, 1 byte of outputs through SM0 on the digital output
    // register 0x0F00 (control 0x44: buffered, write, watchdog).
    let mut b = SiiBuilder::new(SiiFixedRepr {
        pdi_control: 0x0104,
        std_rx_mailbox: SiiMailboxArea::default(),
        std_tx_mailbox: SiiMailboxArea::default(),
        mailbox_protocols: MailboxProtocols(0),
        ..fixed()
    });
    b.syncm = vec![SyncmEntry {
        start: 0x0F00,
        length: 1,
        control: 0x44,
        status: 0,
        enable: SyncmEnable(1),
        sm_type: SyncmType::Outputs,
    }];
    let mut bench = Bench::empty();
    bench.push(Default::default(), b.build().unwrap());
    bench.dev(0).sizes.outputs = 1;
    bench.assign_addresses();
    assert_eq!(bench.request(S, 0x0002), (0x0002, 0), "no mailbox to check");
    let sm0 = [0x00, 0x0F, 0x01, 0x00, 0x44, 0x00, 0x01, 0x00];
    bench.one(fp(Command::Fpwr, S, 0x0800, &sm0));
    bench.one(fp(
        Command::Fpwr,
        S,
        0x0600,
        &fmmu(FmmuRepr::outputs(0, 1, 0x0F00)),
    ));
    assert_eq!(bench.request(S, 0x0004), (0x0004, 0));
    let r = bench.one(l(Command::Lrw, 0, &[0x0F]));
    assert_eq!(r.wkc, 2);
    assert_eq!(bench.dev(0).outputs, vec![vec![0x0F]]);
    assert_eq!(bench.request(S, 0x0008), (0x0008, 0));
    assert_eq!(
        bench.esc(0).read_u8(0x0140),
        0x04,
        "PDI: digital I/O from SII word 0"
    );
    assert_eq!(bench.esc(0).read_u8(0x0141), 0x01, "device emulation");
}
