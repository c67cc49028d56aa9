//! The "mailbox full" bit of every mailbox slave is read by the cyclic frame, and the
//! master reads a slave's mailbox only when its bit says so: an emergency raised by a
//! simulated slave arrives without that slave's send mailbox being polled (the datagrams
//! to its SM1 are counted).

use crate::master_pd_support;
use crate::master_support;

use std::time::Duration;

use master_core::bus::BusConfig;
use master_core::mailbox::MailboxConfig;
use master_core::master::{MasterConfig, SlaveAddress};
use master_core::wire::command::{Command, DatagramAddress};
use master_pd_support::{Recording, Returned, count_node, datagrams};
use master_support::{Rig, block_on, rig_with, wait_until};
use sim::device::coe::EmergencyTrigger;
use sim::topology::Topology;

/// The CoE store's position in the default segment.
const STORE: u16 = 3;

/// Logical address of the mailbox-status bits (0x40000 as in spec-notes §capture).
const STATUS_BASE: u32 = 0x0004_0000;

/// A master on the recorded in-process link.
type PdRig = Rig<Recording<sim::link::InProcessLink>>;

/// A scanned default segment whose CoE store can raise emergencies; every returned frame
/// is kept.
fn rig(config: MasterConfig) -> (PdRig, Returned, EmergencyTrigger) {
    let returned = Returned::default();
    let recorder = returned.clone();
    let rig = rig_with(
        Topology::default_segment(),
        MasterConfig {
            watch_interval: None,
            ..config
        },
        BusConfig::default(),
        move |inner| Recording {
            inner,
            returned: recorder,
        },
    );
    let raise = rig.handles[usize::from(STORE)].emergencies.clone().unwrap();
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    (rig, returned, raise)
}

/// Lets `cycles` more cycles run.
fn run_cycles(rig: &PdRig, cycles: u64) {
    let start = rig.master().cycle_stats().completed;
    assert!(wait_until(
        || rig.master().cycle_stats().completed >= start + cycles
    ));
}

/// Reads of the store's send mailbox (SM1) among `frames`.
fn sm1_reads(rig: &PdRig, frames: &[Vec<u8>]) -> usize {
    let info = rig.master().slave(SlaveAddress::Position(STORE)).unwrap();
    let mailbox = info.mailbox.unwrap();
    count_node(frames, Command::Fprd, info.station, mailbox.read.start)
}

#[test]
fn an_emergency_is_noticed_through_the_mapped_bit_not_by_polling() {
    let (rig, returned, raise) = rig(MasterConfig::default());
    let stats = rig.master().cycle_stats();
    // Drive, CoE store and EoE port have mailboxes: three bits mapped.
    assert_eq!(stats.mailbox_status_slaves, 3);
    let mut emergencies = rig
        .master()
        .mailbox(SlaveAddress::Position(STORE))
        .unwrap()
        .subscribe_emergencies();

    // Quiet: fifty cycles read the status bits, and nobody reads the store's mailbox.
    run_cycles(&rig, 2);
    returned.clear();
    run_cycles(&rig, 50);
    let quiet = returned.frames();
    assert_eq!(sm1_reads(&rig, &quiet), 0, "idle mailboxes are not polled");
    let status_reads: Vec<_> = datagrams(&quiet)
        .into_iter()
        .filter(|(c, a, ..)| {
            *c == Command::Lrd && *a == Some(DatagramAddress::Logical(STATUS_BASE))
        })
        .collect();
    assert!(status_reads.len() >= 50);
    assert!(
        status_reads
            .iter()
            .all(|(_, _, data, wkc)| *wkc == 3 && data == &[0]),
        "three slaves answer, no mailbox full"
    );

    // The store raises an emergency: the bit is seen, the mailbox read, the emergency out.
    returned.clear();
    assert!(raise.raise(0x8110, 0x11, [1, 2, 3, 4, 5]));
    let mut got = None;
    assert!(wait_until(|| {
        got = emergencies.try_recv().ok();
        got.is_some()
    }));
    let emergency = got.unwrap();
    assert_eq!(
        (
            emergency.error_code,
            emergency.error_register,
            emergency.data
        ),
        (0x8110, 0x11, [1, 2, 3, 4, 5])
    );
    let frames = returned.frames();
    let bit = 1u8 << STORE;
    // Cycles whose status read saw the store's mailbox full: each is one notice.
    let notices = datagrams(&frames)
        .iter()
        .filter(|(c, a, data, _)| {
            *c == Command::Lrd
                && *a == Some(DatagramAddress::Logical(STATUS_BASE))
                && data.first().is_some_and(|b| b & bit != 0)
        })
        .count();
    assert!(
        notices >= 1,
        "the cyclic frame saw the store's mailbox full"
    );
    // Polling is off: SM1 is read only on a notice (the cycles that read the status before
    // the emergency was fetched each give one; how many depends on the machine's timing).
    // The notice that finds the emergency reads until SM1 is empty (two reads) and the owner
    // then reads once more at once, as after any find; a later notice reads once.
    let reads = sm1_reads(&rig, &frames);
    assert!(
        (1..=notices + 2).contains(&reads),
        "{reads} reads of SM1 for {notices} notices: three for the one that finds the emergency, one for each later one"
    );
    assert!(rig.master().cycle_stats().mailbox_notices >= 1);
}

#[test]
fn without_the_mapping_idle_mailboxes_are_polled() {
    // The counterpart: the same quiet stretch with polling reads SM1 over and over, so the
    // zero above is the mapping's doing.
    let (rig, returned, _) = rig(MasterConfig {
        map_mailbox_status: false,
        mailbox: MailboxConfig {
            idle_poll: Some(Duration::from_millis(2)),
            ..MailboxConfig::default()
        },
        ..MasterConfig::default()
    });
    assert_eq!(rig.master().cycle_stats().mailbox_status_slaves, 0);
    returned.clear();
    run_cycles(&rig, 50);
    let quiet = returned.frames();
    assert!(sm1_reads(&rig, &quiet) >= 5, "{}", sm1_reads(&rig, &quiet));
    assert!(
        datagrams(&quiet).iter().all(|(c, ..)| *c != Command::Lrd),
        "no status datagram"
    );
}
