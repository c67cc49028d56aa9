//! The ETG.8200 mailbox gateway's statistics (`ecat_mailbox_gateway_*`), read from its
//! lock-free snapshot (`master_core::gateway::MailboxGatewayStats`) at each scrape.

use prometheus::proto::{MetricFamily, MetricType};

use master_core::gateway::{FailureCounts, FailureReason, MailboxGatewayStats};

use super::bus::histogram_series;
use super::family::Family;
use crate::service::Core;

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
    // Whole destructuring, no `..`: a counter added to the gateway does not compile until
    // it is exported here too.
    let MailboxGatewayStats {
        total_requests,
        forwarded_requests,
        failed_requests,
        coe_count,
        soe_count,
        foe_count,
        voe_count,
        eoe_count,
        started_at_ms,
        failures,
        in_flight,
        port,
        latency,
        failed_latency,
        retries_answered,
    } = s;
    let FailureCounts {
        malformed,
        unknown_address,
        unsupported_protocol,
        timeout,
        denied,
        busy,
        oversized,
        other,
    } = failures;
    let mut protocols = Family::new(
        "ecat_mailbox_gateway_protocol_requests_total",
        "Requests by mailbox protocol.",
        MetricType::COUNTER,
    );
    for (protocol, value) in [
        ("coe", coe_count),
        ("soe", soe_count),
        ("foe", foe_count),
        ("voe", voe_count),
        ("eoe", eoe_count),
    ] {
        protocols = protocols.counter(&[("protocol", protocol)], value as f64);
    }
    let mut reasons = Family::new(
        "ecat_mailbox_gateway_failures_total",
        "Failed requests by reason.",
        MetricType::COUNTER,
    );
    for (label, value) in [
        (FailureReason::Malformed.name(), malformed),
        (FailureReason::UnknownAddress.name(), unknown_address),
        (
            FailureReason::UnsupportedProtocol.name(),
            unsupported_protocol,
        ),
        (FailureReason::Timeout.name(), timeout),
        (FailureReason::Denied.name(), denied),
        (FailureReason::Busy.name(), busy),
        (FailureReason::Oversized.name(), oversized),
        (FailureReason::Other.name(), other),
    ] {
        reasons = reasons.counter(&[("reason", label)], value as f64);
    }
    // Failed requests are timed too (a timeout costs the slave's whole deadline), apart from
    // the answered ones so that quick refusals do not flatter the latency.
    let durations = Family::new(
        "ecat_mailbox_gateway_request_duration_seconds",
        "Time from a request's arrival to its answer (outcome=\"answered\") or to its \
         failure (outcome=\"failed\").",
        MetricType::HISTOGRAM,
    );
    let durations = histogram_series(durations, &[("outcome", "answered")], &latency);
    let durations = histogram_series(durations, &[("outcome", "failed")], &failed_latency);
    vec![
        gauge(
            "ecat_mailbox_gateway_up",
            "Whether the ETG.8200 mailbox gateway is serving.",
            if running { 1.0 } else { 0.0 },
        ),
        counter(
            "ecat_mailbox_gateway_requests_total",
            "Datagrams received by the gateway (every one, good or not).",
            total_requests,
        ),
        counter(
            "ecat_mailbox_gateway_forwarded_requests_total",
            "Requests forwarded to a slave or answered by the master's dictionary.",
            forwarded_requests,
        ),
        counter(
            "ecat_mailbox_gateway_failed_requests_total",
            "Requests that failed (see ecat_mailbox_gateway_failures_total for why).",
            failed_requests,
        ),
        counter(
            "ecat_mailbox_gateway_retries_answered_total",
            "Repeated UDP requests answered from the stored reply instead of running again.",
            retries_answered,
        ),
        core.gateway_dropped_datagrams().and_then(|dropped| {
            counter(
                "ecat_mailbox_gateway_dropped_datagrams_total",
                "UDP datagrams the kernel dropped before the gateway read them (its sockets' \
                 receive queues were full), since the sockets were bound.",
                dropped,
            )
        }),
        protocols.done(),
        reasons.done(),
        gauge(
            "ecat_mailbox_gateway_in_flight_requests",
            "Requests being served now.",
            in_flight as f64,
        ),
        Family::new(
            "ecat_mailbox_gateway_info",
            "The gateway's UDP port (after a fallback, the fallback port); always 1.",
            MetricType::GAUGE,
        )
        .gauge(&[("port", &port.to_string())], 1.0)
        .done(),
        gauge(
            "ecat_mailbox_gateway_start_time_seconds",
            "When the gateway started, in seconds since the Unix epoch.",
            started_at_ms as f64 / 1000.0,
        ),
        durations.done(),
    ]
}
