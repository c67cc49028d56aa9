//! The AL state machine through whole frames: every transition, every refusal code and the
//! acknowledge rules (ETG.1000.6, spec-notes §al).

use crate::segment_support;

use ecat_wire::command::Command;
use ecat_wire::register::al::AlState;
use ecat_wire::register::al_status_code::AlStatusCode;
use ecat_wire::sii::SiiBuilder;
use ecat_wire::sii::fixed::{SiiFixedRepr, SiiMailboxArea};
use segment_support::*;

const S: u16 = 0x1001;

fn bench() -> Bench {
    let mut bench = Bench::new(1);
    bench.assign_addresses();
    bench
}

#[test]
fn up_and_down_through_every_state() {
    let mut bench = bench();
    {
        let mut d = bench.dev(0);
        d.sizes.outputs = 1;
        d.sizes.inputs = 1;
    }
    bench.bring_to_preop(S);
    bench.configure_process_data(S, 1, 1);
    assert_eq!(bench.request(S, 0x0004), (0x0004, 0), "PREOP → SAFEOP");
    bench.one(fp(Command::Fpwr, S, 0x1100, &[0xAA]));
    assert_eq!(bench.request(S, 0x0008), (0x0008, 0), "SAFEOP → OP");
    assert_eq!(bench.request(S, 0x0004), (0x0004, 0), "OP → SAFEOP");
    assert_eq!(bench.request(S, 0x0008), (0x0008, 0), "SAFEOP → OP");
    assert_eq!(bench.request(S, 0x0002), (0x0002, 0), "OP → PREOP");
    assert_eq!(bench.request(S, 0x0004), (0x0004, 0), "PREOP → SAFEOP");
    assert_eq!(bench.request(S, 0x0002), (0x0002, 0), "SAFEOP → PREOP");
    assert_eq!(bench.request(S, 0x0004), (0x0004, 0), "PREOP → SAFEOP");
    assert_eq!(bench.request(S, 0x0001), (0x0001, 0), "SAFEOP → INIT");
    bench.bring_to_preop(S);
    assert_eq!(bench.request(S, 0x0001), (0x0001, 0), "PREOP → INIT");
    bench.bring_to_preop(S);
    bench.request(S, 0x0004);
    bench.one(fp(Command::Fpwr, S, 0x1100, &[0xAA]));
    bench.request(S, 0x0008);
    assert_eq!(bench.request(S, 0x0001), (0x0001, 0), "OP → INIT");
    use AlState::*;
    assert_eq!(
        bench.dev(0).transitions,
        [
            (Init, PreOp),
            (PreOp, SafeOp),
            (SafeOp, Op),
            (Op, SafeOp),
            (SafeOp, Op),
            (Op, PreOp),
            (PreOp, SafeOp),
            (SafeOp, PreOp),
            (PreOp, SafeOp),
            (SafeOp, Init),
            (Init, PreOp),
            (PreOp, Init),
            (Init, PreOp),
            (PreOp, SafeOp),
            (SafeOp, Op),
            (Op, Init),
        ]
    );
}

#[test]
fn refusal_codes() {
    let mut bench = bench();
    // 0x0016: PREOP without mailbox SyncManagers (spec-notes §al: status 0x0011, code 0x0016).
    assert_eq!(bench.request(S, 0x0002), (0x0011, 0x0016));
    // 0x0011: INIT → SAFEOP / OP.
    assert_eq!(bench.request(S, 0x0014), (0x0011, 0x0011));
    assert_eq!(bench.request(S, 0x0018), (0x0011, 0x0011));
    // 0x0012: unknown state.
    assert_eq!(bench.request(S, 0x0016), (0x0011, 0x0012));
    // 0x0013: no bootstrap mailbox in the SII.
    assert_eq!(bench.request(S, 0x0013), (0x0011, 0x0013));
    // 0x001D / 0x001E: process data SyncManagers do not fit the device.
    bench.request(S, 0x0011);
    bench.bring_to_preop(S);
    {
        let mut d = bench.dev(0);
        d.sizes.outputs = 2;
        d.sizes.inputs = 2;
    }
    bench.configure_process_data(S, 1, 2);
    assert_eq!(bench.request(S, 0x0004), (0x0012, 0x001D));
    bench.configure_process_data(S, 2, 0);
    assert_eq!(bench.request(S, 0x0014), (0x0012, 0x001E));
    // 0x0011 from PREOP: OP directly.
    assert_eq!(bench.request(S, 0x0018), (0x0012, 0x0011));
    // 0x0019: SAFEOP → OP without outputs.
    bench.configure_process_data(S, 2, 2);
    assert_eq!(bench.request(S, 0x0014), (0x0004, 0));
    assert_eq!(bench.request(S, 0x0008), (0x0014, 0x0019));
}

#[test]
fn bootstrap_mailbox_code_0x0015() {
    let mut bench = Bench::empty();
    let mut b = SiiBuilder::new(SiiFixedRepr {
        boot_rx_mailbox: SiiMailboxArea {
            offset: 0x1000,
            size: 512,
        },
        boot_tx_mailbox: SiiMailboxArea {
            offset: 0x1200,
            size: 512,
        },
        ..fixed()
    });
    b.syncm = Vec::new();
    bench.push(Default::default(), b.build().unwrap());
    bench.assign_addresses();
    bench.one(fp(Command::Fpwr, S, 0x0800, &MAILBOX_SMS));
    assert_eq!(
        bench.request(S, 0x0003),
        (0x0011, 0x0015),
        "standard mailbox in BOOT"
    );
    let sms = [
        0x00, 0x10, 0x00, 0x02, 0x26, 0x00, 0x01, 0x00, 0x00, 0x12, 0x00, 0x02, 0x22, 0x00, 0x01,
        0x00,
    ];
    bench.one(fp(Command::Fpwr, S, 0x0800, &sms));
    assert_eq!(bench.request(S, 0x0013), (0x0003, 0), "BOOT");
    // The bootstrap mailbox works.
    let mut m = vec![0u8; 512];
    m[0] = 4;
    m[5] = 0x04;
    assert_eq!(bench.one(fp(Command::Fpwr, S, 0x1000, &m)).wkc, 1);
    assert_eq!(bench.dev(0).received[0].len(), 10);
    assert_eq!(bench.request(S, 0x0004), (0x0013, 0x0011), "BOOT → SAFEOP");
    assert_eq!(
        bench.request(S, 0x0001),
        (0x0001, 0),
        "BOOT → INIT, implicit ack"
    );
}

#[test]
fn error_is_held_until_acknowledged() {
    let mut bench = bench();
    assert_eq!(bench.request(S, 0x0002), (0x0011, 0x0016));
    bench.one(fp(Command::Fpwr, S, 0x0800, &MAILBOX_SMS));
    assert_eq!(
        bench.request(S, 0x0002),
        (0x0011, 0x0016),
        "no ack: ignored"
    );
    assert_eq!(bench.request(S, 0x0012), (0x0002, 0), "PREOP + ack");
    // A device refusal: PREOP + E with the device's code.
    bench.dev(0).refuse = Some((AlState::SafeOp, AlStatusCode::InvalidWatchdogConfig));
    assert_eq!(bench.request(S, 0x0004), (0x0012, 0x001F));
    // Acknowledge while staying in PREOP.
    assert_eq!(bench.request(S, 0x0012), (0x0002, 0));
    // INIT acknowledges implicitly.
    assert_eq!(bench.request(S, 0x0008), (0x0012, 0x0011));
    assert_eq!(bench.request(S, 0x0001), (0x0001, 0));
}

#[test]
fn broadcast_state_requests_and_brd_of_the_states() {
    let mut bench = Bench::new(3);
    bench.assign_addresses();
    for p in 0..3 {
        bench.one(fp(Command::Fpwr, station(p), 0x0800, &MAILBOX_SMS));
    }
    let r = bench.one(b(Command::Bwr, 0x0120, &[0x02, 0x00]));
    assert_eq!(r.wkc, 3);
    let r = bench.one(b(Command::Brd, 0x0130, &[0, 0]));
    assert_eq!((r.wkc, r.u16()), (3, 0x0002), "SOEM ecx_readstate");
    bench.request(0x1002, 0x0004);
    let r = bench.one(b(Command::Brd, 0x0130, &[0, 0]));
    assert_eq!(r.u16(), 0x0004 | 0x0002, "OR of PREOP and SAFEOP");
    // SOEM's reset step: all to INIT with ack.
    bench.one(b(Command::Bwr, 0x0120, &[0x11, 0x00]));
    let r = bench.one(b(Command::Brd, 0x0130, &[0, 0]));
    assert_eq!(r.u16(), 0x0001);
}
