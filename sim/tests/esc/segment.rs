//! The segment: topology, unplugged slaves, power cycles and DL status (spec-notes §esc.dl).

use crate::segment_support;

use ecat_wire::command::Command;
use ecat_wire::register::dl::DlStatus;
use segment_support::*;

fn count(bench: &mut Bench) -> u16 {
    bench.one(b(Command::Brd, 0x0000, &[0, 0])).wkc
}

#[test]
fn unplugged_slave_and_everything_behind_it_are_invisible() {
    let mut bench = Bench::new(4);
    bench.assign_addresses();
    assert_eq!(count(&mut bench), 4);
    bench.segment.set_plugged(2, false);
    assert_eq!(bench.segment.reachable(), 2);
    assert_eq!(count(&mut bench), 2);
    assert_eq!(bench.one(fp(Command::Fprd, 0x1004, 0x0010, &[0, 0])).wkc, 0);
    let dl = DlStatus::decode(bench.one(ap(Command::Aprd, 1, 0x0110, &[0, 0])).u16());
    assert!(
        !dl.ports[1].link && dl.ports[1].loop_closed,
        "slave 1 port 1 without link"
    );
    assert_eq!(dl.active_ports(), 1);
    let lost = bench.one(fp(Command::Fprd, 0x1002, 0x0311, &[0])).data[0];
    assert_eq!(lost, 1, "lost link counter of port 1");
    bench.segment.set_plugged(2, true);
    assert_eq!(count(&mut bench), 4);
    assert_eq!(
        bench.esc(2).read_u8(0x0310),
        1,
        "slave 2 saw its port 0 link drop"
    );
    let r = bench.one(fp(Command::Fprd, 0x1002, 0x0110, &[0, 0]));
    assert_eq!(DlStatus::decode(r.u16()).active_ports(), 2);
}

#[test]
fn dl_status_change_event() {
    let mut bench = Bench::new(2);
    bench.one(b(Command::Brd, 0x0110, &[0, 0]));
    bench.one(b(Command::Bwr, 0x0200, &[0x04, 0x00]));
    assert_eq!(bench.one(b(Command::Nop, 0, &[])).irq, 0);
    bench.segment.set_plugged(1, false);
    assert_eq!(bench.one(b(Command::Nop, 0, &[])).irq, 0x0004);
}

#[test]
fn nothing_reachable_means_no_frame() {
    let mut bench = Bench::new(2);
    bench.segment.set_plugged(0, false);
    assert!(bench.try_send(&[b(Command::Brd, 0, &[0, 0])]).is_none());
    let mut empty = Bench::empty();
    assert!(empty.try_send(&[b(Command::Brd, 0, &[0, 0])]).is_none());
}

#[test]
fn forced_closed_port_ends_the_line() {
    let mut bench = Bench::new(3);
    bench.one(ap(Command::Apwr, 0, 0x0101, &[0x0C]));
    assert_eq!(count(&mut bench), 1);
    bench.one(ap(Command::Apwr, 0, 0x0101, &[0x00]));
    assert_eq!(count(&mut bench), 3);
}

#[test]
fn power_cycle_resets_registers_and_keeps_the_sii() {
    let mut bench = Bench::new(3);
    bench.assign_addresses();
    bench.bring_to_preop(0x1002);
    let sii = bench.esc(1).sii().to_vec();
    bench.segment.power_cycle(1);
    assert_eq!(bench.esc(1).station_address(), 0);
    assert_eq!(bench.esc(1).read_u16(0x0130), 0x0001, "INIT");
    assert_eq!(bench.esc(1).read_u8(0x0800), 0, "SM registers cleared");
    assert_eq!(bench.esc(1).sii(), sii.as_slice());
    assert_eq!(
        bench.esc(0).station_address(),
        0x1001,
        "neighbours untouched"
    );
    assert_eq!(
        bench.esc(0).read_u8(0x0311),
        1,
        "but they saw the link drop"
    );
    assert_eq!(bench.esc(2).read_u8(0x0310), 1);
    assert_eq!(count(&mut bench), 3);
}

#[test]
fn esc_reset_sequence_over_broadcast() {
    let mut bench = Bench::new(2);
    bench.assign_addresses();
    for byte in *b"RES" {
        assert_eq!(bench.one(b(Command::Bwr, 0x0040, &[byte])).wkc, 2);
    }
    assert_eq!(bench.esc(0).station_address(), 0);
    assert_eq!(bench.esc(1).station_address(), 0);
}

#[test]
fn frames_pass_slaves_in_order() {
    // APWR to position 0 and APRD of the same register at position 0 in one frame: the
    // write happens first.
    let mut bench = Bench::new(2);
    let r = bench.send(&[
        ap(Command::Apwr, 1, 0x0010, &[0x22, 0x00]),
        ap(Command::Aprd, 1, 0x0010, &[0, 0]),
    ]);
    assert_eq!((r[0].wkc, r[1].wkc, r[1].u16()), (1, 1, 0x0022));
}
