//! How the bus thread asks the kernel to schedule it (`bus/sched.rs`): a thread that sleeps
//! between frames takes the fair scheduler's shortest slice, so that its wake-up for a cycle
//! preempts threads on the default slice; a busy-polling one, which never sleeps, keeps the
//! default. Read back from the kernel (`BusStatsSnapshot::time_slice_ns`).

use crate::bus_support;

use bus_support::bus::{config, start};
use bus_support::responder::Answer;
use master_core::bus::{BusConfig, WaitMode};

/// The shortest slice the kernel grants, which a sleeping bus thread asks for.
const SHORT_SLICE_NS: u64 = 100_000;

/// Whether the running kernel has EEVDF's custom slices (Linux 6.12 and later).
fn kernel_has_custom_slices() -> bool {
    let release = std::fs::read_to_string("/proc/sys/kernel/osrelease").expect("osrelease");
    let mut numbers = release
        .split(|c: char| !c.is_ascii_digit())
        .filter_map(|n| n.parse::<u32>().ok());
    let version = (numbers.next(), numbers.next());
    version >= (Some(6), Some(12))
}

/// The bus thread's slice as it reported it, taken after the thread ended (so after it
/// had started and applied its scheduling).
fn slice_of_a_bus(wait_mode: WaitMode) -> u64 {
    let bus = start(
        1,
        Answer,
        BusConfig {
            wait_mode,
            ..config()
        },
    );
    let (stats, _, _) = bus.stop();
    assert!(!stats.realtime, "nothing asked for SCHED_FIFO");
    stats.time_slice_ns
}

#[test]
fn a_sleeping_bus_thread_takes_the_short_slice_and_a_busy_polling_one_keeps_the_default() {
    let sleeping = slice_of_a_bus(WaitMode::Poll);
    let spinning = slice_of_a_bus(WaitMode::BusyPoll);
    if kernel_has_custom_slices() {
        assert_eq!(sleeping, SHORT_SLICE_NS);
        assert!(
            spinning > SHORT_SLICE_NS,
            "the default slice ({spinning} ns) is longer than the short one"
        );
    } else {
        assert_eq!(sleeping, spinning, "an older kernel ignores the request");
    }
}
