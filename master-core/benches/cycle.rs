//! The cyclic exchange against the simulator in-process (no kernel, no wire: what the
//! master and the bus thread cost).
//!
//! Prints two tables, both **in-process** (the veth rig has its own bench,
//! `cargo bench -p ecat-tests --bench cycle_veth`):
//! 1. the highest sustainable cycle rate for 1, 16 and 64 slaves: the shortest period (of
//!    a fixed list) at which no cycle is lost, every working counter is right and at least
//!    90 % of the periods run, with the cycles per second achieved (the frame carries the
//!    reference time, the whole image and the mailbox-status bits);
//! 2. the cycle-time jitter at 1 kHz (16 slaves), as percentiles of |cycle time − period|,
//!    quiet and while another thread runs SDO uploads back to back on every drive (a storm
//!    through the mailbox engine sharing the bus), each with the bus thread at inherited
//!    priority and asking for `SCHED_FIFO` (granted or not: the `rt` column), and quiet
//!    while a live capture ([`CaptureTap`], as `ecat pcap` uses) copies every frame to a
//!    thread writing pcapng (`captured` counts its frames, `dropped` those it could not
//!    queue). The start delay is how long after its due time a cycle's frame went out; `held` counts acyclic
//!    frames kept back so as not to delay a cycle.
//!
//! Run with `cargo bench -p master-core --bench cycle` (a release build; numbers on a
//! loaded machine spread widely, compare rows of one run).

#[path = "../tests/master_support/mod.rs"]
mod master_support;
#[path = "support/pcap_writer.rs"]
mod pcap_writer;
#[path = "support/rate.rs"]
mod rate;
#[path = "support/storm.rs"]
mod storm;

use std::thread;
use std::time::Duration;

use master_core::bus::{BusConfig, HistogramSnapshot, ThreadPriority};
use master_core::link::Link;
use master_core::link::{CaptureHub, CaptureTap};
use master_core::master::MasterConfig;
use master_support::{Rig, block_on, rig_with};
use rate::{fastest_period, micros};
use sim::link::InProcessLink;
use sim::topology::Topology;
use storm::Storm;

/// How long each measurement runs.
const RUN: Duration = Duration::from_secs(2);

fn scanned(slaves: usize, period: Duration, priority: ThreadPriority) -> Rig<InProcessLink> {
    scanned_with(slaves, period, priority, |link| link)
}

fn scanned_with<L: Link + 'static>(
    slaves: usize,
    period: Duration,
    priority: ThreadPriority,
    wrap: impl FnOnce(InProcessLink) -> L,
) -> Rig<L> {
    let rig = rig_with(
        Topology::repeated(slaves),
        MasterConfig {
            cycle_period: period,
            watch_interval: None,
            ..MasterConfig::default()
        },
        BusConfig {
            priority,
            ..BusConfig::default()
        },
        wrap,
    );
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    rig
}

/// Periods tried for the highest rate, longest first.
const PERIODS_US: [u64; 9] = [1000, 500, 250, 100, 50, 25, 20, 15, 10];
/// How long each period is tried.
const TRY: Duration = Duration::from_millis(500);

/// The shortest period at which every cycle comes back and at least 90 % of the periods
/// run; returns it with the cycles per second achieved, the round-trip median and the
/// image size.
fn max_rate(slaves: usize) -> (Duration, f64, f64, usize) {
    let rig = scanned(slaves, Duration::from_millis(1), ThreadPriority::Inherit);
    let master = rig.master();
    let image = master.cycle_stats().image_len;
    let (period, rate, round_trip) = fastest_period(master, &PERIODS_US, TRY);
    (period, rate, round_trip, image)
}

/// One jitter measurement.
struct JitterRun {
    jitter: HistogramSnapshot,
    start_delay: HistogramSnapshot,
    uploads: u64,
    late: u64,
    held: u64,
    realtime: bool,
    /// Frames the capture wrote and frames it dropped (a capture row only).
    captured: Option<(u64, u64)>,
}

fn jitter_row(name: &str, run: &JitterRun) {
    let j = &run.jitter;
    let rate = run.uploads as f64 / RUN.as_secs_f64();
    let (captured, dropped) = run
        .captured
        .map_or(("-".to_owned(), "-".to_owned()), |(c, d)| {
            (c.to_string(), d.to_string())
        });
    println!(
        "{:<30} {:>3} {:>6} {:>7.1} {:>7.1} {:>7.1} {:>8.1} {:>8.1} {:>9.1} {:>5} {:>6} {:>9.0} {:>9} {:>7}",
        name,
        if run.realtime { "yes" } else { "no" },
        j.count(),
        micros(j.quantile(0.5)),
        micros(j.quantile(0.9)),
        micros(j.quantile(0.99)),
        micros(j.quantile(0.999)),
        micros(j.quantile(1.0)),
        micros(run.start_delay.quantile(0.99)),
        run.late,
        run.held,
        rate,
        captured,
        dropped,
    );
}

/// Jitter at 1 kHz over `RUN` on 16 slaves, with `storm` uploads running meanwhile.
fn jitter(storm: bool, priority: ThreadPriority) -> JitterRun {
    let rig = scanned(16, Duration::from_millis(1), priority);
    measure(rig.master(), storm, None)
}

/// Jitter at 1 kHz over `RUN` on 16 slaves while a live capture takes every frame: the
/// bus's link goes through a [`CaptureTap`] and a thread writes what it queues as pcapng,
/// as ecatd's capture does.
fn jitter_capturing(priority: ThreadPriority) -> JitterRun {
    let hub = CaptureHub::new();
    let tap_hub = std::sync::Arc::clone(&hub);
    let rig = scanned_with(16, Duration::from_millis(1), priority, move |link| {
        CaptureTap::new(link, tap_hub)
    });
    let capture = hub.open(4096).expect("no other capture");
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let writer_stop = std::sync::Arc::clone(&stop);
    let writer = thread::spawn(move || {
        let mut out = pcap_writer::PcapNg::new(std::io::sink());
        while !writer_stop.load(std::sync::atomic::Ordering::Relaxed) {
            if let Some(frame) = capture.next(Duration::from_millis(50)) {
                out.write(&frame);
            }
        }
        (out.frames, capture.dropped())
    });
    let mut run = measure(rig.master(), false, None);
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    run.captured = Some(writer.join().expect("capture writer"));
    run
}

fn measure(
    master: &master_core::master::Master,
    storm: bool,
    captured: Option<(u64, u64)>,
) -> JitterRun {
    // Every drive (every fifth slave) gets uploads.
    let storm = storm.then(|| Storm::start(master, (0..16u16).step_by(5)));
    // A fresh master: its histograms hold this run (and the few cycles of its bring-up).
    thread::sleep(RUN);
    let uploads = storm.map_or(0, Storm::stop);
    let bus = master.bus().stats();
    let timing = master.cycle_timing();
    JitterRun {
        jitter: timing.jitter,
        start_delay: timing.start_delay,
        uploads,
        late: bus.cycles_late,
        held: bus.acyclic_held,
        realtime: bus.realtime,
        captured,
    }
}

fn main() {
    println!(
        "highest sustainable cycle rate (in-process simulator: no cycle lost, ≥ 90 % of periods run)"
    );
    println!(
        "{:<8} {:>12} {:>12} {:>12} {:>16}",
        "slaves", "image bytes", "period µs", "cycles/s", "round trip µs"
    );
    for slaves in [1, 16, 64] {
        let (period, rate, round_trip, image) = max_rate(slaves);
        println!(
            "{:<8} {:>12} {:>12} {:>12.0} {:>16.1}",
            slaves,
            image,
            period.as_micros(),
            rate,
            round_trip
        );
    }
    println!();
    println!("cycle-time jitter at 1 kHz, 16 slaves, in-process (|cycle time − 1 ms|, µs)");
    println!(
        "{:<30} {:>3} {:>6} {:>7} {:>7} {:>7} {:>8} {:>8} {:>9} {:>5} {:>6} {:>9} {:>9} {:>7}",
        "",
        "rt",
        "cycles",
        "p50",
        "p90",
        "p99",
        "p99.9",
        "max",
        "start p99",
        "late",
        "held",
        "uploads/s",
        "captured",
        "dropped"
    );
    for (name, priority) in [
        ("inherited priority", ThreadPriority::Inherit),
        ("SCHED_FIFO asked", ThreadPriority::Realtime(80)),
    ] {
        jitter_row(&format!("quiet, {name}"), &jitter(false, priority));
        jitter_row(&format!("storm, {name}"), &jitter(true, priority));
        jitter_row(&format!("capturing, {name}"), &jitter_capturing(priority));
    }
}
