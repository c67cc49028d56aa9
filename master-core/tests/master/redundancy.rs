//! Cable redundancy against the simulator's ring (spec-notes §redundancy): the built-in
//! segment wired from the primary port through every slave back to the backup port, with
//! the 1 kHz cycle and distributed clocks running. A cut after each position in turn (the
//! master's own primary cable and the return cable included), and a slave losing power:
//! every slave stays in OP, outputs reach the output terminal and inputs come back from the
//! input terminal on whichever side they are, the cycle's working counter is short in at
//! most the one cycle that met the cut, the break is located within two cycles, and a heal
//! is seen within two cycles, without a rescan. The last slave losing power leaves the
//! backup port with nothing: it is given up once nothing has come back that way for a while.

use crate::master_support;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use master_core::bus::redundancy::{RingLink, RingState, RingStatus};
use master_core::mailbox::FoeOptions;
use master_core::master::{MasterConfig, SlaveAddress};
use master_core::wire::register::AlState;
use master_support::{Rig, block_on, rig_ring, wait_until};
use sim::esc::DcConfig;
use sim::link::RingPort;
use sim::topology::Topology;

type RingRig = Rig<RingLink<RingPort, RingPort>>;

fn ring_status(rig: &RingRig) -> RingStatus {
    rig.master().bus().ring().expect("a ring").status()
}

fn completed(rig: &RingRig) -> u64 {
    rig.master().cycle_stats().completed
}

/// Waits for `n` more cycles to complete.
fn cycles(rig: &RingRig, n: u64) {
    let from = completed(rig);
    assert!(
        wait_until(|| completed(rig) >= from + n),
        "the cycle stopped at {}",
        completed(rig)
    );
}

fn states(rig: &RingRig) -> Vec<AlState> {
    let segment = rig.segment();
    (0..segment.len())
        .map(|p| segment.esc(p).unwrap().al_state())
        .collect()
}

/// Cycles that came back with a wrong working counter, or not at all.
fn bad_cycles(rig: &RingRig) -> u64 {
    let stats = rig.master().cycle_stats();
    stats.wrong_wkc + stats.lost
}

fn started() -> RingRig {
    let rig = rig_ring(Topology::default_segment(), MasterConfig::default());
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    cycles(&rig, 5);
    rig
}

/// Output channel `n` of the DO8 set alone, and seen by the DI8 it is wired to (inputs
/// read back through the master's image).
fn output_reaches_the_terminal_and_comes_back(rig: &RingRig, channel: u8) {
    let do8 = SlaveAddress::Position(1);
    let di8 = SlaveAddress::Position(2);
    let master = rig.master();
    for n in 1..=8u8 {
        let entry = master.entry(do8, 0x7000, n).unwrap();
        master
            .write_entry(&entry, &[u8::from(n == channel)])
            .unwrap();
    }
    let probe = rig.handles[1].outputs.clone().expect("output probe");
    let expected = 1u8 << (channel - 1);
    assert!(
        wait_until(|| probe.image() == [expected]),
        "channel {channel}: physical outputs {:?}",
        probe.image()
    );
    let input = master.entry(di8, 0x6000, channel).unwrap();
    assert!(
        wait_until(|| master.read_entry(&input).unwrap() == vec![1]),
        "channel {channel} does not come back through the DI8"
    );
}

#[test]
fn a_closed_ring_runs_the_segment_and_knows_its_size() {
    let rig = started();
    let status = ring_status(&rig);
    assert_eq!(status.state, RingState::Closed);
    assert_eq!(usize::from(status.ring_slaves), rig.topology.slaves.len());
    assert_eq!(status.break_after, None);
    assert_eq!(states(&rig), vec![AlState::Op; rig.topology.slaves.len()]);
    output_reaches_the_terminal_and_comes_back(&rig, 3);
    let stats = rig.master().cycle_stats();
    assert_eq!(stats.last_wkc, stats.expected_wkc);
}

#[test]
fn every_cut_is_located_survived_and_healed_without_a_rescan() {
    let rig = started();
    let n = rig.topology.slaves.len();
    let scans = rig.master().slaves().len();
    let mut channel = 1;
    for cable in 0..=n {
        let bad_before = bad_cycles(&rig);
        rig.segment().break_cable(cable).unwrap();
        cycles(&rig, 2);
        let status = ring_status(&rig);
        assert_eq!(status.state, RingState::Broken, "cable {cable}");
        assert_eq!(status.break_after, Some(cable as u16), "cable {cable}");
        assert_eq!(usize::from(status.backup_side), n - cable, "cable {cable}");
        assert_eq!(status.unreachable, 0);
        // Outputs and inputs across the break, every slave in OP all along.
        channel = channel % 8 + 1;
        output_reaches_the_terminal_and_comes_back(&rig, channel);
        cycles(&rig, 50);
        assert_eq!(states(&rig), vec![AlState::Op; n], "cable {cable}");
        let bad = bad_cycles(&rig) - bad_before;
        assert!(
            bad <= 1,
            "cable {cable}: {bad} cycles with a wrong working counter"
        );

        let bad_before = bad_cycles(&rig);
        rig.segment().heal();
        cycles(&rig, 2);
        let status = ring_status(&rig);
        assert_eq!(
            status.state,
            RingState::Closed,
            "healed after cable {cable}"
        );
        cycles(&rig, 20);
        let bad = bad_cycles(&rig) - bad_before;
        assert!(bad <= 1, "heal after cable {cable}: {bad} bad cycles");
        assert_eq!(status.breaks, cable as u64 + 1);
        assert_eq!(status.heals, cable as u64 + 1);
    }
    assert_eq!(rig.master().slaves().len(), scans, "no rescan");
    assert_eq!(states(&rig), vec![AlState::Op; n]);
}

#[test]
fn a_slave_without_power_is_unreachable_and_the_rest_run_on() {
    let rig = started();
    let n = rig.topology.slaves.len();
    rig.segment().kill(3).unwrap();
    cycles(&rig, 2);
    let status = ring_status(&rig);
    assert_eq!(status.state, RingState::Broken);
    assert_eq!(status.break_after, Some(3));
    assert_eq!(usize::from(status.backup_side), n - 4);
    assert_eq!(status.unreachable, 1);
    // The DO8 and DI8 (positions 1 and 2) keep working from the primary side.
    output_reaches_the_terminal_and_comes_back(&rig, 5);
    let segment_states = states(&rig);
    for (p, state) in segment_states.iter().enumerate() {
        if p != 3 {
            assert_eq!(*state, AlState::Op, "slave {p}");
        }
    }
}

#[test]
fn the_last_slave_without_power_is_given_up_once_nothing_comes_back_its_way() {
    // The backup port then gets nothing back at all. A frame back on the primary port
    // alone is held back while a copy from the backup side may still come (the frames that
    // look lost); once nothing has come that way for the ring link's `GONE_AFTER`, the
    // short copy is the frame and the last slave is reported unreachable.
    let rig = started();
    let n = rig.topology.slaves.len();
    rig.segment().kill(n - 1).unwrap();
    assert!(
        wait_until(|| ring_status(&rig).unreachable == 1),
        "{:?}",
        ring_status(&rig)
    );
    let status = ring_status(&rig);
    assert_eq!(status.state, RingState::Broken);
    assert_eq!(status.break_after, Some(n as u16 - 1));
    assert_eq!(status.backup_side, 0);
    assert!(status.incomplete > 0, "{status:?}");
    output_reaches_the_terminal_and_comes_back(&rig, 6);
    let held = ring_status(&rig).incomplete;
    cycles(&rig, 20);
    assert_eq!(
        ring_status(&rig).incomplete,
        held,
        "nothing held back any more"
    );
    for (p, state) in states(&rig).iter().enumerate().take(n - 1) {
        assert_eq!(*state, AlState::Op, "slave {p}");
    }
}

/// An FoE read of the drive (position 0) and a segmented SDO upload of the CoE store
/// (position 3) run in a loop while the ring is cut, healed and cut at another place:
/// every transfer completes with the right data.
#[test]
fn mailbox_transfers_running_across_cuts_complete() {
    let rig = started();
    let master = rig.master();
    let drive = master.mailbox(SlaveAddress::Position(0)).unwrap();
    let store = master.mailbox(SlaveAddress::Position(3)).unwrap();
    let firmware = block_on(drive.foe_read("firmware.bin", FoeOptions::default())).unwrap();
    let blob = block_on(store.sdo_upload(0x2000, 0)).unwrap();
    assert_eq!((firmware.len(), blob.len()), (1024, 4096));
    let stop = Arc::new(AtomicBool::new(false));
    let done = std::thread::scope(|scope| {
        let transfers = scope.spawn(|| {
            let mut done = 0u32;
            while !stop.load(Ordering::Relaxed) && done < 10_000 {
                let read = block_on(drive.foe_read("firmware.bin", FoeOptions::default()))
                    .expect("FoE read across a cut");
                assert_eq!(read, firmware);
                let read = block_on(store.sdo_upload(0x2000, 0)).expect("SDO across a cut");
                assert_eq!(read, blob);
                done += 1;
            }
            done
        });
        for cable in [0, 2, 4, 5, 1] {
            rig.segment().break_cable(cable).unwrap();
            cycles(&rig, 30);
            rig.segment().heal();
            cycles(&rig, 30);
        }
        stop.store(true, Ordering::Relaxed);
        transfers.join().expect("transfers")
    });
    assert!(done > 0);
    assert_eq!(ring_status(&rig).breaks, 5);
}

/// Clock drift of each slave against the time base (ppb), as in the DC tests.
const DRIFT: [i32; 5] = [0, 50_000, -30_000, 10_000, -50_000];

/// With the ring broken after two slaves, the far side takes its time from its own first
/// clock (position 2) instead of the master's zeros: with drifting clocks and time running,
/// each side's clocks stay within 200 ns of that side's reference (the bound of the DC
/// tests), plus on the far side the stand-in reference's own propagation delay (the far
/// side's slaves keep the delays measured from the real reference: a constant offset, not
/// a drift), while nothing holds the two references together.
#[test]
fn each_side_of_a_break_keeps_its_clocks_together() {
    let rig = rig_ring(Topology::default_segment(), MasterConfig::default());
    for (p, drift) in DRIFT.iter().enumerate() {
        rig.segment().esc_mut(p).unwrap().set_dc_config(DcConfig {
            hop_delay_ns: 100,
            clock_start_ns: 7_000_000_000 * p as u64 + 123_457,
            drift_ppb: *drift,
        });
    }
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let dc = rig.master().dc_slaves();
    assert_eq!(dc.len(), DRIFT.len());
    let stand_in_delay = i64::from(dc[2].delay_ns);
    assert!(stand_in_delay > 0, "the delays were measured on the ring");
    rig.segment().break_cable(2).unwrap();
    cycles(&rig, 2);
    assert_eq!(ring_status(&rig).break_after, Some(2));
    let (mut worst, mut worst_far) = (0i64, 0i64);
    for _ in 0..300 {
        rig.time.advance(1_000_000);
        let times: Vec<i64> = {
            let segment = rig.segment();
            let now = segment.now_ns();
            (0..DRIFT.len())
                .map(|p| segment.esc(p).unwrap().system_time(now) as i64)
                .collect()
        };
        worst = worst.max((times[1] - times[0]).abs());
        for t in &times[3..] {
            worst_far = worst_far.max((t - times[2]).abs());
        }
        cycles(&rig, 1);
    }
    assert!(
        worst <= 200,
        "worst difference to the reference: {worst} ns"
    );
    assert!(
        worst_far <= 200 + stand_in_delay,
        "worst difference to the far side's own reference: {worst_far} ns \
         (its delay {stand_in_delay} ns)"
    );
    assert_eq!(states(&rig), vec![AlState::Op; DRIFT.len()]);
}

/// A ring already broken when the master starts: the scan finds every slave through both
/// ports (positions behind the break addressed through the backup port), brings them to
/// OP, and the heal closes the ring without a rescan.
#[test]
fn a_ring_broken_before_the_scan_is_brought_up_from_both_sides() {
    let rig = rig_ring(Topology::default_segment(), MasterConfig::default());
    let n = rig.topology.slaves.len();
    rig.segment().break_cable(2).unwrap();
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    assert_eq!(rig.master().slaves().len(), n);
    for (slave, spec) in rig.master().slaves().iter().zip(&rig.topology.slaves) {
        assert_eq!(slave.name, spec.name, "slave {}", slave.position);
    }
    cycles(&rig, 5);
    assert_eq!(states(&rig), vec![AlState::Op; n]);
    let status = ring_status(&rig);
    assert_eq!(
        (status.state, status.break_after),
        (RingState::Broken, Some(2))
    );
    output_reaches_the_terminal_and_comes_back(&rig, 6);
    rig.segment().heal();
    cycles(&rig, 2);
    assert_eq!(ring_status(&rig).state, RingState::Closed);
    assert_eq!(usize::from(ring_status(&rig).ring_slaves), n);
}
