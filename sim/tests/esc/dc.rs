//! Distributed clocks with whole frames: a master's propagation-delay measurement, offset
//! compensation and drift compensation give the values the segment was built with
//! (ETG.1000.4, spec-notes §dc).

use crate::segment_support;

use ecat_wire::command::Command;
use ecat_wire::register::dc::{PortReceiveTimes, SystemTimeDifference};
use ecat_wire::register::dl::DlStatus;
use segment_support::*;
use sim::esc::TimeSource;

const HOPS: [u32; 4] = [120, 200, 150, 300];
const CLOCKS: [u64; 4] = [5_000_000, 77_000_000_000, 3, 123_456_789];

fn bench() -> Bench {
    let mut bench = Bench::with(4, |p, c| {
        c.dc.hop_delay_ns = HOPS[p];
        c.dc.clock_start_ns = CLOCKS[p];
    });
    bench.assign_addresses();
    bench
}

struct Latch {
    ports: PortReceiveTimes,
    processing_unit: u64,
    dl: DlStatus,
}

/// spec-notes §dc steps 1-2: BWR 0x0900, then read the port times, 0x0918 and DL status.
fn latch(bench: &mut Bench) -> (u64, Vec<Latch>) {
    let master_time = bench.time.now_ns();
    let r = bench.one(b(Command::Bwr, 0x0900, &[0; 4]));
    assert_eq!(r.wkc, 4);
    let mut latches = Vec::new();
    for p in 0..4 {
        let r = bench.send(&[
            fp(Command::Fprd, station(p), 0x0900, &[0; 16]),
            fp(Command::Fprd, station(p), 0x0918, &[0; 8]),
            fp(Command::Fprd, station(p), 0x0110, &[0; 2]),
        ]);
        latches.push(Latch {
            ports: PortReceiveTimes::parse(&r[0].data).unwrap(),
            processing_unit: r[1].u64(),
            dl: DlStatus::parse(&r[2].data).unwrap(),
        });
    }
    (master_time, latches)
}

/// ETG.1000.4, spec-notes §dc step 4 for a line: the delay of each slave from the first one.
fn delays(latches: &[Latch]) -> Vec<u32> {
    let loop_time = |l: &Latch| {
        if l.dl.port_active(1) {
            l.ports.span(0, 1).unwrap()
        } else {
            0
        }
    };
    let mut delays = vec![0u32];
    for i in 1..latches.len() {
        let hop = (loop_time(&latches[i - 1]) - loop_time(&latches[i])) / 2;
        delays.push(delays[i - 1] + hop);
    }
    delays
}

#[test]
fn measured_delays_are_the_configured_hop_delays() {
    let mut bench = bench();
    let (master_time, latches) = latch(&mut bench);
    assert_eq!(
        latches
            .iter()
            .map(|l| l.dl.active_ports())
            .collect::<Vec<_>>(),
        [2, 2, 2, 1],
        "a line, the last slave closes port 1"
    );
    assert_eq!(delays(&latches), [0, 200, 350, 650]);
    // Port 0 and the processing unit see the frame at the same local time; that local time
    // is the slave's clock (running since time-base 0) at the moment the frame arrived.
    let mut arrival = master_time;
    for (p, l) in latches.iter().enumerate() {
        arrival += u64::from(HOPS[p]);
        assert_eq!(l.processing_unit, CLOCKS[p] + arrival);
        assert_eq!(l.ports.0[0], l.processing_unit as u32);
    }
}

#[test]
fn offset_and_drift_compensation_converge() {
    let mut bench = bench();
    bench.time.advance(1_000_000);
    let (master_time, latches) = latch(&mut bench);
    let delays = delays(&latches);
    // spec-notes §dc: offset = master time − 0x0918; written with the delay as IgH does (12 bytes).
    for p in 0..4 {
        let offset = master_time.wrapping_sub(latches[p].processing_unit);
        let mut data = offset.to_le_bytes().to_vec();
        data.extend_from_slice(&delays[p].to_le_bytes());
        assert_eq!(
            bench.one(fp(Command::Fpwr, station(p), 0x0920, &data)).wkc,
            1
        );
    }
    bench.one(b(Command::Bwr, 0x0930, &[0x00, 0x10]));
    // spec-notes §dc: distribute the reference time (slave 0) until the filtered differences (depth
    // 4 after reset) settle.
    for _ in 0..150 {
        bench.time.advance(1_000_000);
        let r = bench.one(fp(Command::Frmw, station(0), 0x0910, &[0; 8]));
        assert_eq!(r.wkc, 4);
    }
    for p in 1..4 {
        let r = bench.one(fp(Command::Fprd, station(p), 0x092C, &[0; 4]));
        let diff = SystemTimeDifference::decode(r.u32());
        assert!(diff.magnitude <= 1, "slave {p}: {diff}");
    }
    // All system times agree at the same instant, and equal the master time minus the
    // reference's own hop delay (the master did not compensate that one).
    let now = bench.time.now_ns();
    for p in 0..4 {
        assert_eq!(
            bench.esc(p).system_time(now),
            bench.esc(0).system_time(now),
            "slave {p}"
        );
    }
    assert_eq!(bench.esc(0).system_time(now), now - u64::from(HOPS[0]));
    // A BRD of 0x092C is the cheap worst-case check (IgH's sync monitor).
    let r = bench.one(b(Command::Brd, 0x092C, &[0; 4]));
    assert!(r.u32() & 0x7FFF_FFFF <= 1);
}

#[test]
fn thirty_two_bit_distribution_also_converges() {
    let mut bench = bench();
    let (master_time, latches) = latch(&mut bench);
    let delays = delays(&latches);
    for p in 0..4 {
        let offset = master_time.wrapping_sub(latches[p].processing_unit);
        bench.one(fp(Command::Fpwr, station(p), 0x0920, &offset.to_le_bytes()));
        bench.one(fp(
            Command::Fpwr,
            station(p),
            0x0928,
            &delays[p].to_le_bytes(),
        ));
    }
    for _ in 0..20 {
        bench.time.advance(500_000);
        bench.one(ap(Command::Armw, 0, 0x0910, &[0; 4]));
    }
    let now = bench.time.now_ns();
    for p in 1..4 {
        assert_eq!(bench.esc(p).system_time(now), bench.esc(0).system_time(now));
    }
}

#[test]
fn drifting_clock_is_steered() {
    let mut bench = Bench::with(2, |p, c| {
        c.dc.hop_delay_ns = 100;
        c.dc.drift_ppb = if p == 1 { 50_000 } else { 0 };
    });
    bench.assign_addresses();
    bench.one(fp(Command::Fpwr, station(1), 0x0928, &100u32.to_le_bytes()));
    for _ in 0..200 {
        bench.time.advance(1_000_000);
        bench.one(fp(Command::Frmw, station(0), 0x0910, &[0; 8]));
    }
    // 50 ppm drift = 50 ns per 1 ms cycle, well inside the 4096 ns per-update slew.
    let r = bench.one(fp(Command::Fprd, station(1), 0x092C, &[0; 4]));
    let diff = SystemTimeDifference::decode(r.u32());
    assert!(diff.magnitude <= 60, "{diff}");
}
