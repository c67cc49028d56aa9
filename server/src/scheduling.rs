//! How ecatd's threads are scheduled, said in the log at start-up.
//!
//! Only the bus thread should run real-time (`[bus] rt_priority`, docs/process-data.md).
//! A process started under a real-time policy as a whole (`chrt`, systemd's
//! `CPUSchedulingPolicy=`) has every thread real-time, since threads inherit their creator's
//! policy: the API's runtime workers and the gateway's workers would then run ahead of every
//! ordinary process of the host under a flood of requests (only the kernel's real-time
//! throttling, 5 % of each second, is left to the rest), and they would hold the bus thread
//! off at its own priority (`SCHED_FIFO` does not preempt a thread of equal priority). The
//! way to give the cycle real-time scheduling is the bus thread's own priority, which an
//! unprivileged service gets through `RLIMIT_RTPRIO` (`LimitRTPRIO=` in
//! `deploy/systemd/ecatd.service`). Neither finding is changed here, only reported: the
//! operator chose the scheduling.

/// Warns when the calling thread (ecatd's main thread, which every other thread of ecatd
/// inherits its scheduling from) runs under a real-time policy.
pub fn warn_if_started_realtime() {
    if let Some((policy, priority)) = master_core::bus::calling_thread_realtime() {
        tracing::warn!(
            policy,
            priority,
            "ecatd was started real-time as a whole: its API and gateway threads run \
             real-time too, ahead of the host's ordinary processes and at the bus thread's \
             priority; give the bus thread alone real-time scheduling with [bus] rt_priority \
             (and RLIMIT_RTPRIO or CAP_SYS_NICE), not a real-time policy for the process"
        );
    }
}

/// Warns when `[bus] rt_priority` asked for `asked` and the bus thread did not get it
/// (`granted`: what the bus thread reported once it ran).
pub fn warn_if_not_granted(asked: Option<u8>, granted: bool) {
    if let Some(asked) = asked
        && !granted
    {
        tracing::warn!(
            asked,
            "[bus] rt_priority not granted: the bus thread keeps the scheduling it inherited \
             (ordinary, unless ecatd was started real-time); ecatd needs CAP_SYS_NICE or an RLIMIT_RTPRIO of at least the priority \
             (systemd: LimitRTPRIO=)"
        );
    }
}
