//! Mailbox requests the core makes (for its APIs and watched values) per slave and
//! protocol: requests, errors, timeouts, and a duration histogram per protocol. Recorded
//! around each mailbox call; `crate::metrics::calls` renders them as metric families (the
//! engine's own counters are per slave only).

use std::collections::BTreeMap;
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::Duration;

/// A mailbox protocol, as the `protocol` label names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Protocol {
    /// CoE (SDO transfers and SDO Information).
    Coe,
    /// SoE.
    Soe,
    /// FoE.
    Foe,
    /// VoE.
    Voe,
    /// EoE (IP parameters).
    Eoe,
}

impl Protocol {
    /// Every protocol, in label order.
    pub const ALL: [Protocol; 5] = [
        Protocol::Coe,
        Protocol::Soe,
        Protocol::Foe,
        Protocol::Voe,
        Protocol::Eoe,
    ];

    /// The label value.
    pub fn label(self) -> &'static str {
        match self {
            Protocol::Coe => "coe",
            Protocol::Soe => "soe",
            Protocol::Foe => "foe",
            Protocol::Voe => "voe",
            Protocol::Eoe => "eoe",
        }
    }
}

/// How a request ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Answered.
    Ok,
    /// Failed (abort, error reply, bus failure, ...), not by a timeout.
    Error,
    /// No answer in time.
    Timeout,
}

/// Upper bounds of the duration histogram, in seconds.
pub const BOUNDS: [f64; 11] = [
    0.5e-3, 1e-3, 2.5e-3, 5e-3, 10e-3, 25e-3, 50e-3, 100e-3, 250e-3, 1.0, 5.0,
];

/// Requests to one slave with one protocol.
#[derive(Debug, Default, Clone, Copy)]
pub struct Counts {
    /// Every request.
    pub requests: u64,
    /// Those that failed (timeouts included).
    pub errors: u64,
    /// Those that got no answer in time.
    pub timeouts: u64,
}

/// The durations of one protocol's requests.
#[derive(Debug, Default, Clone, Copy)]
pub struct Durations {
    /// Non-cumulative counts per bound of [`BOUNDS`] (the last slot: above every bound).
    pub buckets: [u64; BOUNDS.len() + 1],
    /// How many.
    pub count: u64,
    /// Their sum, seconds.
    pub sum: f64,
}

#[derive(Debug, Default)]
struct Inner {
    per_slave: BTreeMap<(u16, Protocol), Counts>,
    durations: BTreeMap<Protocol, Durations>,
}

/// What [`MailboxCalls::snapshot`] copies out.
#[derive(Debug, Default, Clone)]
pub struct CallsSnapshot {
    /// Per slave (station address) and protocol.
    pub per_slave: BTreeMap<(u16, Protocol), Counts>,
    /// Per protocol.
    pub durations: BTreeMap<Protocol, Durations>,
}

/// The recorded requests.
#[derive(Debug, Default)]
pub struct MailboxCalls {
    inner: Mutex<Inner>,
}

impl MailboxCalls {
    fn lock(&self) -> MutexGuard<'_, Inner> {
        // Each update is a few additions: a poisoned lock still holds valid numbers.
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Records one request to slave `station`.
    pub fn record(&self, station: u16, protocol: Protocol, outcome: Outcome, took: Duration) {
        let seconds = took.as_secs_f64();
        let slot = BOUNDS
            .iter()
            .position(|&bound| seconds <= bound)
            .unwrap_or(BOUNDS.len());
        let mut inner = self.lock();
        let counts = inner.per_slave.entry((station, protocol)).or_default();
        counts.requests += 1;
        if outcome != Outcome::Ok {
            counts.errors += 1;
        }
        if outcome == Outcome::Timeout {
            counts.timeouts += 1;
        }
        let durations = inner.durations.entry(protocol).or_default();
        durations.buckets[slot] += 1;
        durations.count += 1;
        durations.sum += seconds;
    }

    /// A copy of the counts and durations, for the metrics.
    pub fn snapshot(&self) -> CallsSnapshot {
        let inner = self.lock();
        CallsSnapshot {
            per_slave: inner.per_slave.clone(),
            durations: inner.durations.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outcomes_count_where_they_belong() {
        let calls = MailboxCalls::default();
        let ms = Duration::from_millis(3);
        calls.record(0x1001, Protocol::Coe, Outcome::Ok, ms);
        calls.record(0x1001, Protocol::Coe, Outcome::Error, ms);
        calls.record(
            0x1001,
            Protocol::Coe,
            Outcome::Timeout,
            Duration::from_secs(9),
        );
        calls.record(0x1002, Protocol::Soe, Outcome::Ok, ms);
        let inner = calls.lock();
        let coe = inner.per_slave[&(0x1001, Protocol::Coe)];
        assert_eq!((coe.requests, coe.errors, coe.timeouts), (3, 2, 1));
        let soe = inner.per_slave[&(0x1002, Protocol::Soe)];
        assert_eq!((soe.requests, soe.errors, soe.timeouts), (1, 0, 0));
        let d = inner.durations[&Protocol::Coe];
        assert_eq!(d.count, 3);
        // 3 ms falls in the 5 ms bucket (index 3); 9 s above every bound.
        assert_eq!(d.buckets[3], 2);
        assert_eq!(d.buckets[BOUNDS.len()], 1);
    }
}
