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
//!
//! Without real-time scheduling, a sleeping bus thread also asks for the shortest time
//! slice the kernel's fair scheduler grants ([`SHORT_SLICE_NS`], Linux 6.12 and later;
//! older kernels ignore the request). EEVDF, that scheduler, gives a woken thread a virtual
//! deadline one slice after its eligible time, so a short slice puts it ahead of threads
//! that run long slices and it preempts them at its wake-up, while its share of the CPU
//! stays what its weight says. It needs no privilege. On `perf_veth` (2 cores, the rows
//! loading both; three runs each way, alternated) it moved the cycle's jitter under the
//! rows from p50 ≤ 25 / p90 ≤ 50-100 µs to p50 ≤ 10 / p90 ≤ 50 µs and halved the missed
//! cycles, at no cost to the API rows; the p99 (≤ 250 µs) did not move
//! (docs/performance.md). A busy-polling bus thread does not ask: it never sleeps, and a
//! short slice would only cut its spinning into more pieces.

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

/// The time slice a sleeping bus thread asks the fair scheduler for: 100 µs, the
/// smallest it grants (`sched_setattr(2)`, `sched_runtime` of `SCHED_OTHER`).
pub(crate) const SHORT_SLICE_NS: u64 = 100_000;

/// Applies `priority`, the minimal timer slack and, for a thread that sleeps between
/// frames (`short_slice`), the short time slice to the calling thread; returns whether it
/// now runs under `SCHED_FIFO`.
pub(crate) fn apply(priority: ThreadPriority, short_slice: bool) -> bool {
    set_min_timer_slack();
    if short_slice {
        set_short_slice();
    }
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

/// `struct sched_attr` of `sched_setattr(2)`, its first version (48 bytes), which every
/// kernel since 3.14 accepts.
#[cfg(target_os = "linux")]
#[repr(C)]
#[derive(Default)]
struct SchedAttr {
    size: u32,
    policy: u32,
    flags: u64,
    nice: i32,
    priority: u32,
    runtime: u64,
    deadline: u64,
    period: u64,
}

/// Asks for [`SHORT_SLICE_NS`] under the calling thread's ordinary policy, keeping its nice
/// value. A kernel without custom slices takes the call and ignores the runtime.
#[cfg(target_os = "linux")]
fn set_short_slice() {
    let Some(mut attr) = own_attr() else { return };
    if attr.policy != libc::SCHED_OTHER as u32 {
        return;
    }
    attr.size = std::mem::size_of::<SchedAttr>() as u32;
    attr.flags = 0;
    attr.runtime = SHORT_SLICE_NS;
    // SAFETY: `attr` is a valid, initialised sched_attr of the size it declares, outliving
    // the call; pid 0 is the calling thread. Failure leaves the scheduling as it was.
    let _ = unsafe { libc::syscall(libc::SYS_sched_setattr, 0, std::ptr::from_ref(&attr), 0) };
}

#[cfg(not(target_os = "linux"))]
fn set_short_slice() {}

/// The calling thread's time slice as the kernel reports it (`sched_runtime` of
/// `sched_getattr(2)`), in ns; 0 where it reports none.
#[cfg(target_os = "linux")]
pub(crate) fn own_time_slice_ns() -> u64 {
    own_attr().map_or(0, |attr| attr.runtime)
}

#[cfg(not(target_os = "linux"))]
pub(crate) fn own_time_slice_ns() -> u64 {
    0
}

/// The real-time policy (`"SCHED_FIFO"` or `"SCHED_RR"`) and priority the calling thread
/// runs under; `None` under an ordinary policy (or where the kernel does not say). ecatd
/// asks it of its main thread, whose scheduling every thread it starts inherits.
#[cfg(target_os = "linux")]
pub fn calling_thread_realtime() -> Option<(&'static str, u32)> {
    let attr = own_attr()?;
    match attr.policy as i32 {
        libc::SCHED_FIFO => Some(("SCHED_FIFO", attr.priority)),
        libc::SCHED_RR => Some(("SCHED_RR", attr.priority)),
        _ => None,
    }
}

/// The real-time policy of the calling thread: none known off Linux.
#[cfg(not(target_os = "linux"))]
pub fn calling_thread_realtime() -> Option<(&'static str, u32)> {
    None
}

/// The calling thread's scheduling attributes (`sched_getattr(2)`).
#[cfg(target_os = "linux")]
fn own_attr() -> Option<SchedAttr> {
    let mut attr = SchedAttr::default();
    let size = std::mem::size_of::<SchedAttr>() as u32;
    // SAFETY: `attr` is writable and `size` bytes long; pid 0 is the calling thread.
    let result = unsafe {
        libc::syscall(
            libc::SYS_sched_getattr,
            0,
            std::ptr::from_mut(&mut attr),
            size,
            0,
        )
    };
    (result == 0).then_some(attr)
}

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
            assert!(!apply(ThreadPriority::Inherit, false));
            assert_eq!(policy(), before);
            assert_eq!(calling_thread_realtime(), None, "an ordinary thread");
            let granted = apply(ThreadPriority::Realtime(10), false);
            assert_eq!(granted, policy() == libc::SCHED_FIFO);
            let expected = granted.then_some(("SCHED_FIFO", 10));
            assert_eq!(calling_thread_realtime(), expected);
        });
        spawned.join().unwrap();
    }
}
