//! Counters of one slave's mailbox, readable while the engine runs.

use std::sync::atomic::{AtomicU64, Ordering};

/// Live counters, shared between the slave's owner task and the handles.
#[derive(Debug, Default)]
pub(crate) struct Stats {
    pub requests: AtomicU64,
    pub failed: AtomicU64,
    pub cancelled: AtomicU64,
    pub writes: AtomicU64,
    pub write_full: AtomicU64,
    pub reads: AtomicU64,
    pub lost_reads: AtomicU64,
    pub repeats: AtomicU64,
    pub duplicates: AtomicU64,
    pub malformed: AtomicU64,
    pub unexpected: AtomicU64,
    pub emergencies: AtomicU64,
    pub soe_notifications: AtomicU64,
    pub eoe_frames_in: AtomicU64,
    pub eoe_frames_out: AtomicU64,
    pub eoe_bytes_in: AtomicU64,
    pub eoe_bytes_out: AtomicU64,
    pub eoe_reassembly_errors: AtomicU64,
    pub events_unheard: AtomicU64,
}

/// Adds `n`.
pub(crate) fn add(counter: &AtomicU64, n: usize) {
    counter.fetch_add(u64::try_from(n).unwrap_or(u64::MAX), Ordering::Relaxed);
}

/// Adds one.
pub(crate) fn inc(counter: &AtomicU64) {
    counter.fetch_add(1, Ordering::Relaxed);
}

/// What one slave's mailbox has seen so far ([`SlaveMailbox::stats`](crate::mailbox::SlaveMailbox::stats)).
///
/// Every message the engine read from the slave is accounted for: handed to a request,
/// published as an event, or counted here as dropped (duplicate, malformed, unexpected).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MailboxStats {
    /// Requests taken from the queue.
    pub requests: u64,
    /// Requests that ended with an error (other than their caller going away).
    pub failed: u64,
    /// Requests whose caller went away before they completed.
    pub cancelled: u64,
    /// Messages written into the slave's receive mailbox (SM0).
    pub writes: u64,
    /// Writes refused because the receive mailbox was still full (written again later).
    pub write_full: u64,
    /// Messages read from the slave's send mailbox (SM1).
    pub reads: u64,
    /// Reads of the send mailbox whose frame was lost.
    pub lost_reads: u64,
    /// Repeat procedures run to recover them (ETG.1000.4, spec-notes §mbx.repeat).
    pub repeats: u64,
    /// Messages dropped because they were read twice (the slave's counter after a repeat).
    pub duplicates: u64,
    /// Messages dropped because they could not be parsed.
    pub malformed: u64,
    /// Well-formed messages nobody waited for (a late answer to a request that timed
    /// out, a mailbox error reply while idle), dropped.
    pub unexpected: u64,
    /// CoE emergencies received.
    pub emergencies: u64,
    /// SoE notifications and slave-info messages received.
    pub soe_notifications: u64,
    /// Ethernet frames received over EoE (reassembled).
    pub eoe_frames_in: u64,
    /// Ethernet frames sent over EoE.
    pub eoe_frames_out: u64,
    /// Bytes of the Ethernet frames received over EoE (destination MAC to payload end).
    pub eoe_bytes_in: u64,
    /// Bytes of the Ethernet frames sent over EoE.
    pub eoe_bytes_out: u64,
    /// Partly received EoE frames dropped (a fragment missing, out of order, or late).
    pub eoe_reassembly_errors: u64,
    /// Events (EoE frames, SoE notifications) published while nobody subscribed. Emergencies
    /// are kept in the history in any case.
    pub events_unheard: u64,
}

impl Stats {
    /// Reads every counter.
    pub fn snapshot(&self) -> MailboxStats {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        MailboxStats {
            requests: get(&self.requests),
            failed: get(&self.failed),
            cancelled: get(&self.cancelled),
            writes: get(&self.writes),
            write_full: get(&self.write_full),
            reads: get(&self.reads),
            lost_reads: get(&self.lost_reads),
            repeats: get(&self.repeats),
            duplicates: get(&self.duplicates),
            malformed: get(&self.malformed),
            unexpected: get(&self.unexpected),
            emergencies: get(&self.emergencies),
            soe_notifications: get(&self.soe_notifications),
            eoe_frames_in: get(&self.eoe_frames_in),
            eoe_frames_out: get(&self.eoe_frames_out),
            eoe_bytes_in: get(&self.eoe_bytes_in),
            eoe_bytes_out: get(&self.eoe_bytes_out),
            eoe_reassembly_errors: get(&self.eoe_reassembly_errors),
            events_unheard: get(&self.events_unheard),
        }
    }
}
