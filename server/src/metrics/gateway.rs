//! The ETG.8200 mailbox gateway's statistics (`ecat_mailbox_gateway_*`), read from its
//! lock-free snapshot (`master_core::gateway::MailboxGatewayStats`) at each scrape.

use prometheus::proto::{MetricFamily, MetricType};

use master_core::gateway::FailureReason;

use super::bus::histogram;
use super::family::Family;
use crate::service::Core;

/// Failure reasons with their label values, in the gateway's own terms.
const REASONS: [(FailureReason, &str); 8] = [
    (FailureReason::Malformed, "malformed"),
    (FailureReason::UnknownAddress, "unknown_address"),
    (FailureReason::UnsupportedProtocol, "unsupported_protocol"),
    (FailureReason::Timeout, "timeout"),
    (FailureReason::Denied, "denied"),
    (FailureReason::Busy, "busy"),
    (FailureReason::Oversized, "oversized"),
    (FailureReason::Other, "other"),
];

fn counter(name: &str, help: &str, value: u64) -> Option<MetricFamily> {
    Family::new(name, help, MetricType::COUNTER)
        .counter(&[], value as f64)
        .done()
}

fn gauge(name: &str, help: &str, value: f64) -> Option<MetricFamily> {
    Family::new(name, help, MetricType::GAUGE)
        .gauge(&[], value)
        .done()
}

/// The gateway's families (only `ecat_mailbox_gateway_up 0` when ecatd runs without one).
pub fn collect(core: &Core) -> Vec<Option<MetricFamily>> {
    let Some((s, running)) = core.gateway_stats() else {
        return vec![gauge(
            "ecat_mailbox_gateway_up",
            "Whether the ETG.8200 mailbox gateway is serving.",
            0.0,
        )];
    };
    let mut protocols = Family::new(
        "ecat_mailbox_gateway_protocol_requests_total",
        "Requests by mailbox protocol.",
        MetricType::COUNTER,
    );
    for (protocol, value) in [
        ("coe", s.coe_count),
        ("soe", s.soe_count),
        ("foe", s.foe_count),
        ("voe", s.voe_count),
        ("eoe", s.eoe_count),
    ] {
        protocols = protocols.counter(&[("protocol", protocol)], value as f64);
    }
    let mut failures = Family::new(
        "ecat_mailbox_gateway_failures_total",
        "Failed requests by reason.",
        MetricType::COUNTER,
    );
    for (reason, label) in REASONS {
        failures = failures.counter(&[("reason", label)], s.failures.get(reason) as f64);
    }
    vec![
        gauge(
            "ecat_mailbox_gateway_up",
            "Whether the ETG.8200 mailbox gateway is serving.",
            if running { 1.0 } else { 0.0 },
        ),
        counter(
            "ecat_mailbox_gateway_requests_total",
            "Datagrams received by the gateway (every one, good or not).",
            s.total_requests,
        ),
        counter(
            "ecat_mailbox_gateway_forwarded_requests_total",
            "Requests forwarded to a slave or answered by the master's dictionary.",
            s.forwarded_requests,
        ),
        counter(
            "ecat_mailbox_gateway_failed_requests_total",
            "Requests that failed (see ecat_mailbox_gateway_failures_total for why).",
            s.failed_requests,
        ),
        counter(
            "ecat_mailbox_gateway_retries_answered_total",
            "Repeated UDP requests answered from the stored reply instead of running again.",
            s.retries_answered,
        ),
        protocols.done(),
        failures.done(),
        gauge(
            "ecat_mailbox_gateway_in_flight_requests",
            "Requests being served now.",
            s.in_flight as f64,
        ),
        gauge(
            "ecat_mailbox_gateway_port",
            "The UDP port the gateway is bound to (after a fallback, the fallback port).",
            f64::from(s.port),
        ),
        gauge(
            "ecat_mailbox_gateway_start_time_seconds",
            "When the gateway started, in seconds since the Unix epoch.",
            s.started_at_ms as f64 / 1000.0,
        ),
        histogram(
            "ecat_mailbox_gateway_request_duration_seconds",
            "Time from a request's arrival to its answer (sum estimated from bucket midpoints).",
            &s.latency,
        ),
    ]
}
