//! Mailbox SyncManagers through whole frames: handshake, blocked accesses, last-byte
//! commit, the repeat procedure, FMMU-mapped status polling and device polling
//! (ETG.1000.4, spec-notes §esc.sm, §mbx.handshake).

use crate::segment_support;

use ecat_wire::command::Command;
use ecat_wire::register::fmmu::{Fmmu, FmmuRepr};
use segment_support::*;

const S: u16 = 0x1001;

/// A 128-byte SM0 image with a mailbox header of `len` data bytes and `marker` after it.
fn message(len: u16, marker: u8) -> Vec<u8> {
    let mut m = vec![0u8; 128];
    m[..2].copy_from_slice(&len.to_le_bytes());
    m[5] = 0x13; // CoE, counter 1
    m[6] = marker;
    m
}

fn bench() -> Bench {
    let mut bench = Bench::new(1);
    bench.assign_addresses();
    bench.bring_to_preop(S);
    bench
}

#[test]
fn handshake_and_blocked_accesses_have_wkc_0() {
    let mut bench = bench();
    let r = bench.send(&[
        fp(Command::Fprd, S, 0x1080, &[0; 128]),
        fp(Command::Fpwr, S, 0x1080, &[0; 128]),
        fp(Command::Fprd, S, 0x1000, &[0; 128]),
        fp(Command::Fpwr, S, 0x1001, &[0; 127]),
    ]);
    assert_eq!(
        r.iter().map(|b| b.wkc).collect::<Vec<_>>(),
        [0, 0, 0, 0],
        "read of an empty SM1, write of SM1, read of SM0, write not at the start"
    );
    let r = bench.send(&[
        fp(Command::Fprd, S, 0x0805, &[0]),
        fp(Command::Fpwr, S, 0x1000, &message(4, 0x42)),
        fp(Command::Fprd, S, 0x080D, &[0]),
        fp(Command::Fprd, S, 0x1080, &[0; 128]),
        fp(Command::Fprd, S, 0x1080, &[0; 128]),
    ]);
    assert_eq!(r[0].data[0] & 0x08, 0, "SM0 empty (SOEM ecx_mbxempty)");
    assert_eq!(r[1].wkc, 1, "accepted");
    assert_eq!(r[2].data[0] & 0x08, 0x08, "reply waiting in SM1");
    assert_eq!((r[3].wkc, &r[3].data[..7]), (1, &message(4, 0x42)[..7]));
    assert_eq!(r[4].wkc, 0, "reading emptied it");
    assert_eq!(bench.dev(0).received, vec![message(4, 0x42)[..10].to_vec()]);
}

#[test]
fn sm0_commits_only_on_its_last_byte() {
    let mut bench = bench();
    let m = message(4, 1);
    assert_eq!(bench.one(fp(Command::Fpwr, S, 0x1000, &m[..127])).wkc, 1);
    assert!(bench.dev(0).received.is_empty(), "last byte missing");
    assert_eq!(bench.one(fp(Command::Fpwr, S, 0x1000, &m)).wkc, 1);
    assert_eq!(bench.dev(0).received.len(), 1);
}

#[test]
fn full_sm0_blocks_writes() {
    let mut bench = bench();
    // Nobody reads SM1: after SM1 and the outbox are full, SM0 stays full.
    let wkcs: Vec<u16> = (0..70)
        .map(|i| bench.one(fp(Command::Fpwr, S, 0x1000, &message(4, i))).wkc)
        .collect();
    assert!(wkcs[..66].iter().all(|&w| w == 1));
    assert!(wkcs[66..].iter().all(|&w| w == 0), "{wkcs:?}");
    assert_eq!(
        bench.one(fp(Command::Fprd, S, 0x0805, &[0])).data[0] & 0x08,
        0x08
    );
}

#[test]
fn bad_length_is_delivered_as_the_whole_sm() {
    let mut bench = bench();
    bench.one(fp(Command::Fpwr, S, 0x1000, &message(0x7B, 0)));
    assert_eq!(bench.dev(0).received[0].len(), 128, "123 > 128 − 6");
    bench.one(fp(Command::Fpwr, S, 0x1000, &message(0x7A, 0)));
    assert_eq!(bench.dev(0).received[1].len(), 128, "exactly fits");
}

#[test]
fn repeat_request_as_soem_does_it() {
    let mut bench = bench();
    bench.one(fp(Command::Fpwr, S, 0x1000, &message(4, 0xA)));
    // The read of A is "lost" on the way back: the test ignores its result.
    bench.one(fp(Command::Fprd, S, 0x1080, &[0; 128]));
    let s = bench.one(fp(Command::Fprd, S, 0x080D, &[0, 0])).u16();
    let r = bench.one(fp(Command::Fpwr, S, 0x080D, &(s ^ 0x0200).to_le_bytes()));
    assert_eq!(r.wkc, 1);
    let ack = bench.one(fp(Command::Fprd, S, 0x080F, &[0])).data[0];
    assert_eq!(ack & 0x02, 0x02, "repeat ack = repeat request");
    let r = bench.one(fp(Command::Fprd, S, 0x1080, &[0; 128]));
    assert_eq!((r.wkc, r.data[6]), (1, 0xA), "A posted again");
}

#[test]
fn sm1_status_bit_mapped_to_a_logical_bit() {
    let mut bench = bench();
    // 0x080D bit 3 (mailbox full) → logical 0x00010000 bit 5.
    let f = FmmuRepr {
        logical_start_bit: 5,
        logical_stop_bit: 5,
        physical_start_bit: 3,
        ..FmmuRepr::inputs(0x0001_0000, 1, 0x080D)
    };
    let mut bytes = vec![0u8; 16];
    f.emit(&mut Fmmu::new_unchecked(&mut bytes[..])).unwrap();
    bench.one(fp(Command::Fpwr, S, 0x0620, &bytes));
    let r = bench.one(l(Command::Lrd, 0x0001_0000, &[0b1101_1111]));
    assert_eq!(
        (r.wkc, r.data[0]),
        (1, 0b1101_1111),
        "empty: bit 5 cleared, others kept"
    );
    bench.one(fp(Command::Fpwr, S, 0x1000, &message(4, 0)));
    let r = bench.one(l(Command::Lrd, 0x0001_0000, &[0]));
    assert_eq!((r.wkc, r.data[0]), (1, 0b0010_0000), "full");
}

#[test]
fn unsolicited_messages_are_posted_when_polled() {
    let mut bench = bench();
    bench
        .dev(0)
        .unsolicited
        .push_back(message(10, 0xEE)[..16].to_vec());
    bench.one(b(Command::Nop, 0, &[]));
    assert!(bench.dev(0).polls >= 1);
    let r = bench.one(fp(Command::Fprd, S, 0x1080, &[0; 128]));
    assert_eq!((r.wkc, r.data[6]), (1, 0xEE));
    assert!(r.data[16..].iter().all(|&b| b == 0));
}

/// The firmware runs between frames: a message its application posted since the last frame
/// is in SM1 for the next frame's first datagram, not one frame later (a delayed reply is
/// read as soon as it is due; spec-notes §mbx.handshake).
#[test]
fn a_message_posted_between_frames_is_read_by_the_next_frame() {
    let mut bench = bench();
    // The previous frame's end found nothing to post; the application posts after it.
    bench.one(b(Command::Nop, 0, &[]));
    let polls = bench.dev(0).polls;
    bench
        .dev(0)
        .unsolicited
        .push_back(message(10, 0xEE)[..16].to_vec());
    let r = bench.one(fp(Command::Fprd, S, 0x1080, &[0; 128]));
    assert_eq!(
        (r.wkc, r.data[6]),
        (1, 0xEE),
        "read by the frame right after"
    );
    assert!(bench.dev(0).polls > polls);
    assert_eq!(
        bench.one(fp(Command::Fprd, S, 0x1080, &[0; 128])).wkc,
        0,
        "and only once"
    );
}

#[test]
fn no_mailbox_in_init() {
    let mut bench = Bench::new(1);
    bench.assign_addresses();
    bench.one(fp(Command::Fpwr, S, 0x0800, &MAILBOX_SMS));
    assert_eq!(
        bench.one(fp(Command::Fpwr, S, 0x1000, &message(4, 0))).wkc,
        0
    );
    assert_eq!(bench.dev(0).polls, 0);
}
