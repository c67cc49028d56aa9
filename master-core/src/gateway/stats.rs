//! The gateway's counters: lock-free atomics updated by every request, copied into a
//! [`MailboxGatewayStats`] snapshot at any time from any thread.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use crate::bus::{Histogram, HistogramSnapshot};
use crate::wire::mailbox::MailboxType;

/// Why a request failed (each failed request counts under exactly one reason).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FailureReason {
    /// Not an ETG.8200 message (too short, wrong type, lengths that disagree), or a
    /// protocol header too short for the service.
    Malformed,
    /// No slave at the address (or none that supports the protocol, for a broadcast).
    UnknownAddress,
    /// The protocol is not served at the address (not announced by the slave, not CoE at
    /// address 0, the slave's mailbox not running in its state).
    UnsupportedProtocol,
    /// The slave did not answer in time.
    Timeout,
    /// The client is not in the allowlist.
    Denied,
    /// Too many requests in flight (overall, for the client, or queued at the slave).
    Busy,
    /// The message is larger than the slave's receive mailbox.
    Oversized,
    /// Anything else (the bus or the master stopped, a slave's protocol violation).
    Other,
}

impl FailureReason {
    /// Every reason, in the order of [`FailureCounts`]' fields.
    pub const ALL: [FailureReason; 8] = [
        FailureReason::Malformed,
        FailureReason::UnknownAddress,
        FailureReason::UnsupportedProtocol,
        FailureReason::Timeout,
        FailureReason::Denied,
        FailureReason::Busy,
        FailureReason::Oversized,
        FailureReason::Other,
    ];

    /// A short name for logs and metric labels.
    pub fn name(self) -> &'static str {
        match self {
            FailureReason::Malformed => "malformed",
            FailureReason::UnknownAddress => "unknown_address",
            FailureReason::UnsupportedProtocol => "unsupported_protocol",
            FailureReason::Timeout => "timeout",
            FailureReason::Denied => "denied",
            FailureReason::Busy => "busy",
            FailureReason::Oversized => "oversized",
            FailureReason::Other => "other",
        }
    }

    fn slot(self) -> usize {
        self as usize
    }
}

/// Failed requests by reason; they add up to [`MailboxGatewayStats::failed_requests`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FailureCounts {
    /// Malformed datagrams and protocol headers.
    pub malformed: u64,
    /// Unknown addresses.
    pub unknown_address: u64,
    /// Protocols not served at the address.
    pub unsupported_protocol: u64,
    /// Slaves that did not answer in time.
    pub timeout: u64,
    /// Clients outside the allowlist.
    pub denied: u64,
    /// Requests refused for too many in flight.
    pub busy: u64,
    /// Messages larger than the slave's mailbox.
    pub oversized: u64,
    /// Everything else.
    pub other: u64,
}

impl FailureCounts {
    /// The count of one reason.
    pub fn get(&self, reason: FailureReason) -> u64 {
        match reason {
            FailureReason::Malformed => self.malformed,
            FailureReason::UnknownAddress => self.unknown_address,
            FailureReason::UnsupportedProtocol => self.unsupported_protocol,
            FailureReason::Timeout => self.timeout,
            FailureReason::Denied => self.denied,
            FailureReason::Busy => self.busy,
            FailureReason::Oversized => self.oversized,
            FailureReason::Other => self.other,
        }
    }
}

/// The gateway's statistics since it was last started (all zero before the first start).
///
/// The first eight fields are those of the gateway of spec-notes §gateway.dialect; the rest
/// are ours. Counters only grow while the gateway runs; a restart sets them to zero.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MailboxGatewayStats {
    /// UDP datagrams and TCP messages received, including those that failed to parse or
    /// were refused (a refused TCP connection counts once).
    pub total_requests: u64,
    /// Requests parsed and answered by a slave or by the master's dictionary (a slave's
    /// own error answer — SDO abort, FoE error — counts here: the gateway did its job).
    pub forwarded_requests: u64,
    /// Requests that failed: malformed, routing failure, timeout, refused (see
    /// [`Self::failures`]).
    pub failed_requests: u64,
    /// Parsed requests of type CoE.
    pub coe_count: u64,
    /// Parsed requests of type SoE.
    pub soe_count: u64,
    /// Parsed requests of type FoE.
    pub foe_count: u64,
    /// Parsed requests of type VoE.
    pub voe_count: u64,
    /// When the gateway was started, Unix milliseconds; 0 if it is not running.
    pub started_at_ms: u64,
    /// Failed requests by reason.
    pub failures: FailureCounts,
    /// Parsed requests of type EoE.
    pub eoe_count: u64,
    /// Requests being worked on now.
    pub in_flight: u64,
    /// UDP port bound; 0 if not running.
    pub port: u16,
    /// Time from receiving a request to sending its (first) reply, for answered requests.
    pub latency: HistogramSnapshot,
    /// Time from receiving a request to its failure (the gateway's error answer sent, if
    /// any), for failed requests: a failure that takes a slave's timeout shows here. A
    /// connection refused before any message was read counts as zero.
    pub failed_latency: HistogramSnapshot,
    /// Repeated UDP requests answered from the stored reply (or left to the original still
    /// being worked on) instead of being executed again; neither forwarded nor failed.
    pub retries_answered: u64,
}

impl Default for MailboxGatewayStats {
    fn default() -> MailboxGatewayStats {
        Stats::default().snapshot()
    }
}

/// The live counters.
#[derive(Debug)]
pub(crate) struct Stats {
    total: AtomicU64,
    forwarded: AtomicU64,
    failed: AtomicU64,
    coe: AtomicU64,
    soe: AtomicU64,
    foe: AtomicU64,
    voe: AtomicU64,
    eoe: AtomicU64,
    retries: AtomicU64,
    started_at_ms: AtomicU64,
    in_flight: AtomicU64,
    port: AtomicU64,
    failures: [AtomicU64; FailureReason::ALL.len()],
    latency: Histogram,
    failed_latency: Histogram,
}

impl Default for Stats {
    fn default() -> Stats {
        Stats {
            total: AtomicU64::new(0),
            forwarded: AtomicU64::new(0),
            failed: AtomicU64::new(0),
            coe: AtomicU64::new(0),
            soe: AtomicU64::new(0),
            foe: AtomicU64::new(0),
            voe: AtomicU64::new(0),
            eoe: AtomicU64::new(0),
            retries: AtomicU64::new(0),
            started_at_ms: AtomicU64::new(0),
            in_flight: AtomicU64::new(0),
            port: AtomicU64::new(0),
            failures: std::array::from_fn(|_| AtomicU64::new(0)),
            latency: Histogram::new(),
            failed_latency: Histogram::new(),
        }
    }
}

fn inc(counter: &AtomicU64) {
    counter.fetch_add(1, Ordering::Relaxed);
}

fn get(counter: &AtomicU64) -> u64 {
    counter.load(Ordering::Relaxed)
}

impl Stats {
    /// A datagram arrived.
    pub fn received(&self) {
        inc(&self.total);
    }

    /// A request of `mailbox_type` was parsed.
    pub fn parsed(&self, mailbox_type: MailboxType) {
        match mailbox_type {
            MailboxType::Coe => inc(&self.coe),
            MailboxType::Soe => inc(&self.soe),
            MailboxType::Foe => inc(&self.foe),
            MailboxType::Voe => inc(&self.voe),
            MailboxType::Eoe => inc(&self.eoe),
            _ => {}
        }
    }

    /// A request was answered (or, for messages that get none, delivered) after `latency`.
    pub fn forwarded(&self, latency: Duration) {
        inc(&self.forwarded);
        self.latency.record(latency);
    }

    /// A request failed for `reason`, `latency` after it was received.
    pub fn failed(&self, reason: FailureReason, latency: Duration) {
        inc(&self.failed);
        inc(&self.failures[reason.slot()]);
        self.failed_latency.record(latency);
    }

    /// A repeated request was answered without executing it again.
    pub fn retry_answered(&self) {
        inc(&self.retries);
    }

    pub fn in_flight_add(&self) {
        inc(&self.in_flight);
    }

    pub fn in_flight_sub(&self) {
        self.in_flight.fetch_sub(1, Ordering::Relaxed);
    }

    /// Zeroes every counter and records the start.
    pub fn start(&self, port: u16) {
        for counter in [
            &self.total,
            &self.forwarded,
            &self.failed,
            &self.coe,
            &self.soe,
            &self.foe,
            &self.voe,
            &self.eoe,
            &self.retries,
        ] {
            counter.store(0, Ordering::Relaxed);
        }
        for counter in &self.failures {
            counter.store(0, Ordering::Relaxed);
        }
        self.latency.reset();
        self.failed_latency.reset();
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_millis()).unwrap_or(u64::MAX));
        self.started_at_ms.store(now.max(1), Ordering::Relaxed);
        self.port.store(u64::from(port), Ordering::Relaxed);
    }

    /// Records the stop (the counters stay readable).
    pub fn stop(&self) {
        self.started_at_ms.store(0, Ordering::Relaxed);
        self.port.store(0, Ordering::Relaxed);
    }

    pub fn snapshot(&self) -> MailboxGatewayStats {
        let f = |reason: FailureReason| get(&self.failures[reason.slot()]);
        MailboxGatewayStats {
            total_requests: get(&self.total),
            forwarded_requests: get(&self.forwarded),
            failed_requests: get(&self.failed),
            coe_count: get(&self.coe),
            soe_count: get(&self.soe),
            foe_count: get(&self.foe),
            voe_count: get(&self.voe),
            started_at_ms: get(&self.started_at_ms),
            failures: FailureCounts {
                malformed: f(FailureReason::Malformed),
                unknown_address: f(FailureReason::UnknownAddress),
                unsupported_protocol: f(FailureReason::UnsupportedProtocol),
                timeout: f(FailureReason::Timeout),
                denied: f(FailureReason::Denied),
                busy: f(FailureReason::Busy),
                oversized: f(FailureReason::Oversized),
                other: f(FailureReason::Other),
            },
            eoe_count: get(&self.eoe),
            in_flight: get(&self.in_flight),
            port: u16::try_from(get(&self.port)).unwrap_or(0),
            latency: self.latency.snapshot(),
            failed_latency: self.failed_latency.snapshot(),
            retries_answered: get(&self.retries),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failures_add_up_and_a_start_zeroes() {
        let stats = Stats::default();
        stats.start(4000);
        stats.received();
        stats.received();
        stats.parsed(MailboxType::Coe);
        stats.forwarded(Duration::from_micros(100));
        stats.failed(FailureReason::Malformed, Duration::from_millis(30));
        let s = stats.snapshot();
        assert_eq!(
            (s.total_requests, s.forwarded_requests, s.failed_requests),
            (2, 1, 1)
        );
        assert_eq!((s.coe_count, s.failures.malformed, s.port), (1, 1, 4000));
        assert_eq!(s.latency.count(), 1);
        assert_eq!(s.latency.sum(), Duration::from_micros(100));
        // The failed request is timed apart from the answered one.
        assert_eq!(s.failed_latency.count(), 1);
        assert_eq!(s.failed_latency.sum(), Duration::from_millis(30));
        assert!(s.started_at_ms > 0);
        let by_reason: u64 = FailureReason::ALL.iter().map(|r| s.failures.get(*r)).sum();
        assert_eq!(by_reason, s.failed_requests);
        stats.stop();
        assert_eq!(stats.snapshot().started_at_ms, 0);
        stats.start(4001);
        assert_eq!(stats.snapshot().total_requests, 0);
        assert_eq!(stats.snapshot().latency.count(), 0);
        assert_eq!(stats.snapshot().failed_latency.count(), 0);
    }
}
