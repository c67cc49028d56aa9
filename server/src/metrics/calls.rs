//! The core's mailbox requests per slave and protocol ([`MailboxCalls`]) as metric
//! families: requests, errors and timeouts per slave, a duration histogram per protocol.

use prometheus::proto::{MetricFamily, MetricType};

use super::family::Family;
use crate::service::calls::{BOUNDS, CallsSnapshot, Counts, MailboxCalls, Protocol};

/// The families of `calls`.
pub fn collect(calls: &MailboxCalls) -> Vec<Option<MetricFamily>> {
    let CallsSnapshot {
        per_slave,
        durations,
    } = calls.snapshot();
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
