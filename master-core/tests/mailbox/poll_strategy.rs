//! How many reads of SM1 one exchange costs: a slave that answers at once is read in the
//! write's own frame, and a slow one (a real ESC's application answers after its own delay)
//! gets a few eager reads, then reads after growing pauses or a "mailbox full" notice, never
//! a read per round trip for as long as it takes; once its answer time is known, it is read
//! when the answer is due.

use crate::mailbox_support;

use std::time::{Duration, Instant};

use mailbox_support::{DRIVE, Rig, bus_config};
use master_core::link::FaultConfig;
use master_core::mailbox::MailboxConfig;
use sim::topology::Topology;

/// The default segment with the drive answering `delay_us` after each request.
fn topology(delay_us: u32) -> Topology {
    let mut topology = Topology::default_segment();
    topology.slaves[DRIVE].esc.response_delay_us = delay_us;
    topology
}

/// The drive's segment with idle polling off, so that every read of SM1 counted is one an
/// upload asked for (the owner's idle reads, every 10 ms by default, would land among the
/// uploads whenever they take longer than that).
fn rig(delay_us: u32) -> Rig {
    Rig::start_with(
        &topology(delay_us),
        FaultConfig::default(),
        1,
        bus_config(),
        no_idle_poll(),
        |_, _| {},
    )
}

fn no_idle_poll() -> MailboxConfig {
    MailboxConfig {
        idle_poll: None,
        ..MailboxConfig::default()
    }
}

fn vendor_id() -> Vec<u8> {
    Topology::default_segment().slaves[DRIVE]
        .vendor_id
        .to_le_bytes()
        .to_vec()
}

#[tokio::test]
async fn a_slave_that_answers_at_once_costs_one_write_and_one_read_per_upload() {
    // Without the "mailbox full" bits in the cyclic frame. With them, an answer can cost
    // one more (empty) read, rightly: when the bus thread sends the write before the read
    // is queued (a loaded machine) and a cycle runs between the two frames, the cycle sees
    // SM1 full, and the engine reads again on that notice, since it cannot tell the
    // message it announced from a new one.
    let rig = Rig::start_without_status_bits(&topology(0), no_idle_poll(), |_, _| {});
    let drive = rig.slave(DRIVE);
    assert_eq!(drive.sdo_upload(0x1018, 1).await.unwrap(), vendor_id());
    let bus = rig.bus.stats();
    let mailbox = drive.stats();
    const UPLOADS: u64 = 20;
    for _ in 0..UPLOADS {
        assert_eq!(drive.sdo_upload(0x1018, 1).await.unwrap(), vendor_id());
    }
    let sent = rig.bus.stats().datagrams_sent - bus.datagrams_sent;
    let after = drive.stats();
    assert_eq!(after.writes - mailbox.writes, UPLOADS);
    assert_eq!(after.reads - mailbox.reads, UPLOADS);
    // The read that found the answer is the one sent behind the write: no other.
    assert_eq!(
        sent,
        2 * UPLOADS,
        "datagrams for {UPLOADS} uploads: {bus:?} then {:?}",
        rig.bus.stats()
    );
}

/// Datagrams (the write and every read of SM1) of each of `uploads` uploads from the drive
/// when it answers `delay_us` after each request, after `learn` uploads not counted (from
/// which the engine learns when the drive answers), fewest first; each upload is checked.
async fn datagrams_of_each_upload(delay_us: u32, learn: u64, uploads: u64) -> Vec<u64> {
    let rig = rig(delay_us);
    let drive = rig.slave(DRIVE);
    let upload = || async {
        let t = Instant::now();
        assert_eq!(drive.sdo_upload(0x1018, 1).await.unwrap(), vendor_id());
        assert!(
            t.elapsed() >= Duration::from_micros(delay_us.into()),
            "answered before the slave had the answer ready"
        );
    };
    for _ in 0..learn {
        upload().await;
    }
    let mut counts = Vec::new();
    for _ in 0..uploads {
        let before = rig.bus.stats().datagrams_sent;
        upload().await;
        counts.push(rig.bus.stats().datagrams_sent - before);
    }
    counts.sort_unstable();
    counts
}

fn mean(counts: &[u64]) -> f64 {
    counts.iter().sum::<u64>() as f64 / counts.len() as f64
}

/// The upload in the middle: a planned read goes early by how late the last ones left, so
/// a stall of the machine (a test binary beside this one) costs the next few uploads the
/// eager reads and a pause, which the median leaves out and the mean would not.
fn median(counts: &[u64]) -> u64 {
    counts[counts.len() / 2]
}

#[tokio::test]
async fn a_slave_that_answers_after_100_us_is_read_a_few_times_per_upload() {
    // Before the engine knows the slave: the write, the read behind it, four eager reads,
    // then pauses of 50 and 75 µs: eight datagrams when every pause ends on time, fewer
    // when the machine makes them late; one more when a "mailbox full" notice left over
    // from the last upload ends a pause early.
    let counts = datagrams_of_each_upload(100, 0, 2).await;
    assert!(mean(&counts) <= 9.0, "datagrams per upload: {counts:?}");
}

#[tokio::test]
async fn a_slave_that_answers_after_1_ms_is_answered_without_a_read_per_round_trip() {
    // Pauses of 50, 75, 112, 168, 253, 379 µs reach 1 ms: twelve datagrams with the write
    // and the five first reads (thirteen with a left-over "mailbox full" notice). The
    // in-process link answers in microseconds, so a strategy that read at every round trip
    // would send hundreds, and one that paused a whole poll interval after the eager reads
    // would answer a millisecond late.
    let counts = datagrams_of_each_upload(1000, 0, 2).await;
    assert!(mean(&counts) <= 13.0, "datagrams per upload: {counts:?}");
    // Once its time is known, the slave is read when its answer is due: three datagrams
    // (the write, the read behind it, the planned read) in the typical upload, ten or
    // eleven without the plan. A 100 µs slave shows no such difference here (the eager
    // reads of an unoptimised build over the in-process link often cover 100 µs
    // themselves); `perf_veth` counts its frames on the veth rig.
    let counts = datagrams_of_each_upload(1000, 2, 11).await;
    assert!(
        median(&counts) <= 7,
        "datagrams per upload, once known: {counts:?}"
    );
}
