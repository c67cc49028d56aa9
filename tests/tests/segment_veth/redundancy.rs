//! ecatd's cable redundancy over two veth pairs (spec-notes §redundancy): the master's bus
//! on `mst0` (primary) and `mst1` (backup), `ecat-sim --backup-iface` wiring the built-in
//! segment back to the backup port. With the 1 kHz cycle, process data and distributed
//! clocks running, the cable after each position in turn is cut (`break k`, the master's
//! primary cable and the return cable included) and a slave loses power (`kill`): every
//! slave stays in OP, the output terminal follows the API and its wired input terminal
//! reads it back, the break is located within ten cycles (10 ms), a heal is seen within
//! ten cycles, the cycles with a wrong working counter around a cut are at most two more
//! than in an equally long quiet window of the same rig (printed; the goal of one is met
//! exactly in process, master-core's tests/master/redundancy.rs; a cut over that bound is
//! made again, at most three times in all, since the machine's noise comes in bursts), and an FoE read and SDO uploads
//! running across the cuts complete with the right data. No rescan.
//!
//! Needs root (namespaces, raw sockets).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use ecat_tests::rig::{Rig, SIM_BACKUP_IFACE, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use ecat_tests::veth_master::VethMaster;
use master_core::bus::BusConfig;
use master_core::bus::redundancy::{RingState, RingStatus};
use master_core::mailbox::FoeOptions;
use master_core::master::{MasterConfig, SlaveAddress};
use master_core::wire::register::AlState;
use sim::topology::Topology;

const PATIENCE: Duration = Duration::from_secs(20);
/// The output and input terminals of the built-in segment (the DI8 is wired to the DO8).
const DO8: usize = 1;
const DI8: usize = 2;
/// Cycles within which a cut or a heal must show in the ring's state: 10 ms at 1 kHz.
const REPORTED_WITHIN: u64 = 10;
/// Cycles each cut is held.
const HELD: u64 = 200;

fn wait_until(mut condition: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + PATIENCE;
    while Instant::now() < deadline {
        if condition() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    condition()
}

struct Ring {
    master: VethMaster,
    sim: SimProcess,
    /// The DO8 channel set last (0: none yet).
    channel: u8,
    _rig: Rig,
}

impl Ring {
    fn start() -> Ring {
        let rig = Rig::ring();
        let sim = SimProcess::start_controlled(
            &rig.sim,
            SIM_IFACE,
            &["--backup-iface", SIM_BACKUP_IFACE],
        );
        let master = VethMaster::on_ring(&rig, BusConfig::default(), MasterConfig::default());
        let report = master.scan();
        assert!(report.failures.is_empty(), "{:?}", report.failures);
        let ring = Ring {
            master,
            sim,
            channel: 0,
            _rig: rig,
        };
        ring.cycles(10);
        ring
    }

    fn status(&self) -> RingStatus {
        self.master.master().bus().ring().expect("a ring").status()
    }

    fn completed(&self) -> u64 {
        self.master.master().cycle_stats().completed
    }

    fn cycles(&self, n: u64) {
        let from = self.completed();
        assert!(
            wait_until(|| self.completed() >= from + n),
            "the cycle stopped"
        );
    }

    fn bad(&self) -> u64 {
        let stats = self.master.master().cycle_stats();
        stats.wrong_wkc + stats.lost
    }

    fn states(&self) -> Vec<AlState> {
        self.master
            .master()
            .slaves()
            .iter()
            .map(|s| s.al_state)
            .collect()
    }

    /// Sends `command` to the simulator (applied before its next frame) and returns the
    /// cycle count at its answer.
    fn change(&mut self, command: &str) -> u64 {
        self.sim.command(command);
        self.completed()
    }

    /// Sets the DO8 channel after the one set before alone (channel 1 first), so that the
    /// pins change; the simulator reports the pins and the DI8 wired to them reads the
    /// channel back through the master's image.
    fn output_round_trip(&mut self) {
        let channel = self.channel % 8 + 1;
        self.channel = channel;
        let m = self.master.master();
        let do8 = SlaveAddress::Position(DO8 as u16);
        for n in 1..=8u8 {
            let entry = m.entry(do8, 0x7000, n).unwrap();
            m.write_entry(&entry, &[u8::from(n == channel)]).unwrap();
        }
        let line = format!("ecat-sim: outputs {DO8} {:02x}", 1u8 << (channel - 1));
        let mut seen = Vec::new();
        let found = self
            .sim
            .wait_line(PATIENCE, |l| {
                seen.push(l.to_string());
                l == line
            })
            .is_some();
        assert!(
            found,
            "the simulator never reported {line:?}; it said {seen:?}; ring {:?}",
            self.status()
        );
        let input = m
            .entry(SlaveAddress::Position(DI8 as u16), 0x6000, channel)
            .unwrap();
        assert!(
            wait_until(|| m.read_entry(&input).unwrap() == vec![1]),
            "DI8 channel {channel} never came back"
        );
    }
}

/// Attempts a cut may take: see [`cut_and_heal`].
const ATTEMPTS: u32 = 3;

/// Cuts with `command`, checks the ring's report and the segment behind it, heals; returns
/// how many times the cut was made.
///
/// The bad cycles a cut may cost are judged against the rig's noise, and that noise comes
/// in bursts: one copy held up past the ring link's grace by a busy machine costs the cycle
/// waited for and the next one (sent without waiting for that copy's twin). So a cut over
/// the bound is made again, up to [`ATTEMPTS`] times: a ring that loses cycles at a cut
/// loses them every time, a burst of noise does not come back on cue.
fn cut_and_heal(ring: &mut Ring, command: &str, break_after: u16, unreachable: u16) -> u32 {
    for attempt in 1..=ATTEMPTS {
        let bad = cut_once(ring, command, break_after, unreachable);
        match bad {
            Some((bad, quiet, singles)) if attempt < ATTEMPTS => println!(
                "{command}: {bad} bad cycles, {quiet} when quiet, {singles} copies back alone: \
                 over the bound, made again"
            ),
            Some((bad, quiet, singles)) => panic!(
                "{command}: {bad} bad cycles, {quiet} when quiet, {singles} copies back \
                 alone, {ATTEMPTS} times over the bound"
            ),
            None => return attempt,
        }
    }
    unreachable!("the last attempt returns or panics")
}

/// One cut and heal; `Some((bad, quiet, single returns))` when the cut cost more cycles
/// than the bound allows.
fn cut_once(
    ring: &mut Ring,
    command: &str,
    break_after: u16,
    unreachable: u16,
) -> Option<(u64, u64, u64)> {
    let n = Topology::default_segment().slaves.len() as u16;
    // The rig's own noise: bad cycles in a quiet window as long as the cut is held.
    let quiet = ring.bad();
    ring.cycles(HELD);
    let quiet = ring.bad() - quiet;

    let before = ring.bad();
    let singles_before = ring.status().single_returns;
    let at = ring.change(command);
    assert!(wait_until(|| ring.completed() >= at + REPORTED_WITHIN));
    let status = ring.status();
    assert_eq!(status.state, RingState::Broken, "{command}: {status:?}");
    assert_eq!(status.break_after, Some(break_after), "{command}");
    assert_eq!(status.unreachable, unreachable, "{command}");
    assert_eq!(
        status.backup_side,
        n - break_after - unreachable,
        "{command}"
    );
    ring.output_round_trip();
    ring.cycles(HELD);
    let bad = ring.bad() - before;
    let singles = ring.status().single_returns - singles_before;
    println!(
        "{command}: {bad} cycles with a wrong working counter (quiet window: {quiet}), \
         {singles} frames back on one port only ({} not whole in all)",
        ring.status().incomplete
    );
    for (p, state) in ring.states().into_iter().enumerate() {
        if p as u16 != break_after || unreachable == 0 {
            assert_eq!(state, AlState::Op, "{command}: slave {p}");
        }
    }

    let at = ring.change("heal");
    assert!(wait_until(|| ring.completed() >= at + REPORTED_WITHIN));
    assert_eq!(
        ring.status().state,
        RingState::Closed,
        "heal after {command}"
    );
    // A slave without power answers nothing: every cycle misses it, by design. Otherwise
    // the goal is one cycle per cut, met exactly by the in-process test, where nothing is
    // late. Here one more is allowed: a copy lost with a master port's own cable is waited
    // for the ring link's grace, and the cycle sent meanwhile was built for a closed ring.
    // The test runs alone (.config/nextest.toml).
    (unreachable == 0 && bad > 2 + quiet).then_some((bad, quiet, singles))
}

#[test]
fn ecatd_survives_a_cut_after_every_position_and_a_dead_slave_on_a_veth_ring() {
    let mut ring = Ring::start();
    let n = Topology::default_segment().slaves.len();
    let scanned = ring.master.master().slaves().len();
    let status = ring.status();
    assert_eq!(status.state, RingState::Closed);
    assert_eq!(usize::from(status.ring_slaves), n);
    ring.output_round_trip();

    let mut cuts = 0;
    for cable in 0..=n {
        cuts += cut_and_heal(&mut ring, &format!("break {cable}"), cable as u16, 0);
    }
    // A slave without power other than the terminals under test: both its cables go.
    cuts += cut_and_heal(&mut ring, "kill 3", 3, 1);
    // The killed slave came back in INIT; the master brings it up again.
    assert!(
        wait_until(|| ring.states().iter().all(|s| *s == AlState::Op)),
        "states after the heal: {:?}",
        ring.states()
    );
    assert_eq!(ring.master.master().slaves().len(), scanned, "no rescan");
    let status = ring.status();
    // One break and one heal per cut made: none seen twice, none missed.
    assert_eq!(
        (status.breaks, status.heals),
        (u64::from(cuts), u64::from(cuts))
    );
}

#[test]
fn mailbox_transfers_across_cuts_complete_on_a_veth_ring() {
    let mut ring = Ring::start();
    let m = ring.master.master();
    let drive = m.mailbox(SlaveAddress::Position(0)).unwrap();
    let store = m.mailbox(SlaveAddress::Position(3)).unwrap();
    let watch = m.bus().ring().expect("a ring").clone();
    let firmware = ring
        .master
        .block_on(drive.foe_read("firmware.bin", FoeOptions::default()))
        .unwrap();
    let blob = ring.master.block_on(store.sdo_upload(0x2000, 0)).unwrap();
    assert_eq!((firmware.len(), blob.len()), (1024, 4096));
    let stop = AtomicBool::new(false);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .unwrap();
    // A transfer that fails shows the ring's counts: frames not handed up whole
    // (`incomplete`) are what keeps a lost copy from losing a message.
    let failed = |what: &str, err| -> Vec<u8> { panic!("{what}: {err:?}; {:?}", watch.status()) };
    let done = std::thread::scope(|scope| {
        let transfers = scope.spawn(|| {
            let mut done = 0u32;
            while !stop.load(Ordering::Relaxed) && done < 100_000 {
                let read = runtime
                    .block_on(drive.foe_read("firmware.bin", FoeOptions::default()))
                    .unwrap_or_else(|err| failed("FoE read across a cut", err));
                assert_eq!(read, firmware);
                let read = runtime
                    .block_on(store.sdo_upload(0x2000, 0))
                    .unwrap_or_else(|err| failed("SDO upload across a cut", err));
                assert_eq!(read, blob);
                done += 1;
            }
            done
        });
        // Behind the drive (0 and 1) and behind the store (2 to 4) in turn.
        for cable in [0, 4, 1, 3, 5] {
            ring.change(&format!("break {cable}"));
            ring.cycles(100);
            ring.change("heal");
            ring.cycles(100);
        }
        stop.store(true, Ordering::Relaxed);
        transfers.join().expect("transfers")
    });
    assert!(done > 0);
    assert_eq!(ring.status().breaks, 5);
}
