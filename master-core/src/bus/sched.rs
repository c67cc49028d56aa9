//! How the bus thread asks the kernel to schedule it.
//!
//! Measured on the in-process cycle benchmark (see docs/process-data.md): nearly every late
//! cycle was due while the bus thread was asleep, and the lateness was the kernel waking it
//! late, not work the bus did. Two causes, two remedies:
//! - the timer slack of an ordinary thread (50 µs by default) lets the kernel fire its
//!   timed wake-ups up to that much late, to batch them: the bus thread sets its own slack
//!   to the minimum, always (any thread may, and it costs a few more wake-ups);
//! - when every core is busy (another thread uploading SDOs back to back, a build), a
//!   woken thread of ordinary priority waits for a running one to use up its time slice,
//!   milliseconds. Only real-time scheduling (`SCHED_FIFO`) makes the bus thread run at
//!   once; it needs `CAP_SYS_NICE` or an `RLIMIT_RTPRIO`, so it is asked for
//!   ([`ThreadPriority::Realtime`]) and reported ([`BusStatsSnapshot::realtime`](super::BusStatsSnapshot::realtime)),
//!   never required.

/// How the bus thread is scheduled; see [`BusConfig::priority`](super::BusConfig::priority).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ThreadPriority {
    /// The scheduling the thread inherits from the process (normally `SCHED_OTHER`).
    #[default]
    Inherit,
    /// `SCHED_FIFO` at this priority (clamped to 1..=99) when the process is allowed to;
    /// otherwise the inherited scheduling. A real-time bus thread preempts every ordinary
    /// thread the moment a cycle is due. With [`WaitMode::BusyPoll`](super::WaitMode::BusyPoll)
    /// it also never leaves its core to ordinary threads (the kernel's real-time throttling,
    /// 5 % by default, is all they get there), so combine the two only on a core set aside.
    Realtime(u8),
}

/// Applies `priority` and the minimal timer slack to the calling thread; returns whether
/// it now runs under `SCHED_FIFO`.
pub(crate) fn apply(priority: ThreadPriority) -> bool {
    set_min_timer_slack();
    match priority {
        ThreadPriority::Inherit => false,
        ThreadPriority::Realtime(level) => set_fifo(level.clamp(1, 99)),
    }
}

/// Sets the calling thread's timer slack to the minimum, so that its timed waits end on
/// time rather than batched up to 50 µs late (also used by the mailbox engine's pause
/// thread).
#[cfg(target_os = "linux")]
pub(crate) fn set_min_timer_slack() {
    // SAFETY: PR_SET_TIMERSLACK takes an integer argument and touches no memory of ours;
    // it only changes the calling thread's slack. 1 ns is the smallest value (0 would mean
    // "back to the default").
    let _ = unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong, 0, 0, 0) };
}

#[cfg(not(target_os = "linux"))]
pub(crate) fn set_min_timer_slack() {}

#[cfg(unix)]
fn set_fifo(level: u8) -> bool {
    let param = libc::sched_param {
        sched_priority: libc::c_int::from(level),
    };
    // SAFETY: `param` is a valid, initialised sched_param that outlives the call, and
    // pthread_self() is always a valid handle for the calling thread. Failure (EPERM without
    // the privilege) leaves the scheduling as it was.
    let result =
        unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) };
    result == 0
}

#[cfg(not(unix))]
fn set_fifo(_level: u8) -> bool {
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inherit_changes_no_policy_and_realtime_reports_what_the_kernel_granted() {
        let policy = || {
            // SAFETY: pthread_self() is valid; the out-parameters are local and initialised.
            unsafe {
                let mut policy = 0;
                let mut param = libc::sched_param { sched_priority: 0 };
                libc::pthread_getschedparam(libc::pthread_self(), &mut policy, &mut param);
                policy
            }
        };
        let spawned = std::thread::spawn(move || {
            let before = policy();
            assert!(!apply(ThreadPriority::Inherit));
            assert_eq!(policy(), before);
            let granted = apply(ThreadPriority::Realtime(10));
            assert_eq!(granted, policy() == libc::SCHED_FIFO);
        });
        spawned.join().unwrap();
    }
}
