//! Mailbox requests ecatd makes (its APIs and watched values) per slave and protocol:
//! requests, errors, timeouts, and a duration histogram per protocol. Recorded by the core
//! around each mailbox call; the engine's own counters (`mailbox`) are per slave only.

use std::collections::BTreeMap;
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use prometheus::proto::{MetricFamily, MetricType};

use super::family::Family;

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
    const ALL: [Protocol; 5] = [
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
const BOUNDS: [f64; 11] = [
    0.5e-3, 1e-3, 2.5e-3, 5e-3, 10e-3, 25e-3, 50e-3, 100e-3, 250e-3, 1.0, 5.0,
];

#[derive(Debug, Default, Clone, Copy)]
struct Counts {
    requests: u64,
    errors: u64,
    timeouts: u64,
}

#[derive(Debug, Default, Clone, Copy)]
struct Durations {
    /// Non-cumulative counts per bound (the last slot: above every bound).
    buckets: [u64; BOUNDS.len() + 1],
    count: u64,
    sum: f64,
}

#[derive(Debug, Default)]
struct Inner {
    per_slave: BTreeMap<(u16, Protocol), Counts>,
    durations: BTreeMap<Protocol, Durations>,
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

    /// The families.
    pub fn collect(&self) -> Vec<Option<MetricFamily>> {
        let (per_slave, durations) = {
            let inner = self.lock();
            (inner.per_slave.clone(), inner.durations.clone())
        };
        type Field = fn(&Counts) -> u64;
        let counters: [(&str, &str, Field); 3] = [
            (
                "ecat_mailbox_protocol_requests_total",
                "Mailbox requests ecatd made (APIs, watched values) by slave and protocol.",
                |c| c.requests,
            ),
            (
                "ecat_mailbox_protocol_errors_total",
                "Of those, requests that failed (timeouts included).",
                |c| c.errors,
            ),
            (
                "ecat_mailbox_protocol_timeouts_total",
                "Of those, requests that got no answer in time.",
                |c| c.timeouts,
            ),
        ];
        let mut out: Vec<Option<MetricFamily>> = counters
            .iter()
            .map(|(name, help, field)| {
                per_slave
                    .iter()
                    .fold(
                        Family::new(name, help, MetricType::COUNTER),
                        |family, ((station, protocol), counts)| {
                            family.counter(
                                &[
                                    ("station", &station.to_string()),
                                    ("protocol", protocol.label()),
                                ],
                                field(counts) as f64,
                            )
                        },
                    )
                    .done()
            })
            .collect();
        let mut histogram = Family::new(
            "ecat_mailbox_protocol_request_duration_seconds",
            "Duration of the mailbox requests ecatd made, by protocol.",
            MetricType::HISTOGRAM,
        );
        for protocol in Protocol::ALL {
            let Some(d) = durations.get(&protocol) else {
                continue;
            };
            let mut cumulative = 0;
            let buckets: Vec<(f64, u64)> = BOUNDS
                .iter()
                .zip(d.buckets)
                .map(|(&bound, n)| {
                    cumulative += n;
                    (bound, cumulative)
                })
                .collect();
            histogram =
                histogram.histogram(&[("protocol", protocol.label())], &buckets, d.count, d.sum);
        }
        out.push(histogram.done());
        out
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
