//! The ETG.8200 mailbox gateway as an API: its state, settings and statistics, start and
//! stop. The gateway itself (`master_core::gateway::MailboxGateway`) lives in the core from
//! start-up on, running or stopped; ecatd without a gateway (`--no-gateway`) has none.

use std::net::SocketAddr;

use master_core::bus::HistogramSnapshot;
use master_core::gateway::{FailureCounts, MailboxGateway, MailboxGatewayStats};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::view::EventView;
use super::{ApiError, Core, ErrorKind, Operation, Result, Ticket};

/// The gateway: whether it runs, where, with which settings, and its statistics.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct GatewayView {
    /// Whether ecatd has a gateway at all (false with `--no-gateway`).
    pub enabled: bool,
    /// Whether it is serving.
    pub running: bool,
    /// The UDP address bound while running (after a fallback, the fallback port); empty
    /// when stopped.
    pub bound_address: String,
    /// The UDP port bound while running, else the port the next start asks for.
    pub port: u16,
    /// The configured address: the bind address and the port asked for (34980 +
    /// (master number - 1) unless a port is configured).
    pub configured_address: String,
    /// The master number (1-based).
    pub master_number: u16,
    /// Strict mode: no error replies from the gateway itself.
    pub strict: bool,
    /// Client networks allowed to send requests, each with its role (`127.0.0.0/8 write`,
    /// `10.0.0.0/8 read`).
    pub allow: Vec<String>,
    /// Statistics since the last start.
    pub stats: GatewayStatsView,
}

/// `MailboxGatewayStats`: counters since the last start.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct GatewayStatsView {
    /// Datagrams received (malformed and denied ones included).
    pub total_requests: u64,
    /// Requests answered by a slave or the master's dictionary.
    pub forwarded_requests: u64,
    /// Everything else (the sum of `failures`).
    pub failed_requests: u64,
    /// Parsed CoE requests.
    pub coe_count: u64,
    /// Parsed SoE requests.
    pub soe_count: u64,
    /// Parsed FoE requests.
    pub foe_count: u64,
    /// Parsed VoE requests.
    pub voe_count: u64,
    /// Parsed EoE requests.
    pub eoe_count: u64,
    /// Start time, Unix milliseconds; 0 when stopped.
    pub started_at_ms: u64,
    /// Failed requests by reason.
    pub failures: GatewayFailuresView,
    /// Requests being worked on now.
    pub in_flight: u64,
    /// Port bound; 0 when stopped.
    pub port: u16,
    /// Time from a request's arrival to its first reply.
    pub latency: LatencyView,
    /// Repeated UDP requests answered from the stored reply instead of running again.
    pub retries_answered: u64,
}

/// Failed requests by reason.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct GatewayFailuresView {
    /// Not an ETG.8200 message.
    pub malformed: u64,
    /// No slave at the address.
    pub unknown_address: u64,
    /// The slave does not serve the protocol (or has no mailbox running).
    pub unsupported_protocol: u64,
    /// No answer in time.
    pub timeout: u64,
    /// Client not in the allowlist, or a write from a client with the `read` role.
    pub denied: u64,
    /// Too many requests in flight, or the slave held too long.
    pub busy: u64,
    /// Larger than the slave's mailbox.
    pub oversized: u64,
    /// Anything else.
    pub other: u64,
}

/// A latency histogram, summarised.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct LatencyView {
    /// Requests measured.
    pub count: u64,
    /// Estimated median, microseconds (absent without requests).
    pub p50_us: Option<u64>,
    /// Estimated 99th percentile, microseconds (absent without requests).
    pub p99_us: Option<u64>,
    /// The non-empty buckets.
    pub buckets: Vec<LatencyBucketView>,
}

/// One histogram bucket: requests that took `[low_us, high_us)`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct LatencyBucketView {
    /// Lower bound, microseconds.
    pub low_us: u64,
    /// Upper bound (exclusive), microseconds.
    pub high_us: u64,
    /// Requests in the bucket.
    pub count: u64,
}

fn micros(d: std::time::Duration) -> u64 {
    u64::try_from(d.as_micros()).unwrap_or(u64::MAX)
}

impl From<&HistogramSnapshot> for LatencyView {
    fn from(h: &HistogramSnapshot) -> LatencyView {
        LatencyView {
            count: h.count(),
            p50_us: h.p50().map(micros),
            p99_us: h.p99().map(micros),
            buckets: h
                .buckets()
                .map(|(low, high, count)| LatencyBucketView {
                    low_us: micros(low),
                    high_us: micros(high),
                    count,
                })
                .collect(),
        }
    }
}

impl From<&MailboxGatewayStats> for GatewayStatsView {
    fn from(s: &MailboxGatewayStats) -> GatewayStatsView {
        // Whole destructuring, no `..`: a counter added to the gateway does not compile
        // until it is shown here too.
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
            // Exported as a metric only (ecat_mailbox_gateway_request_duration_seconds).
            failed_latency: _,
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
        } = *failures;
        GatewayStatsView {
            total_requests: *total_requests,
            forwarded_requests: *forwarded_requests,
            failed_requests: *failed_requests,
            coe_count: *coe_count,
            soe_count: *soe_count,
            foe_count: *foe_count,
            voe_count: *voe_count,
            eoe_count: *eoe_count,
            started_at_ms: *started_at_ms,
            failures: GatewayFailuresView {
                malformed,
                unknown_address,
                unsupported_protocol,
                timeout,
                denied,
                busy,
                oversized,
                other,
            },
            in_flight: *in_flight,
            port: *port,
            latency: LatencyView::from(latency),
            retries_answered: *retries_answered,
        }
    }
}

impl GatewayView {
    fn of(gateway: Option<&MailboxGateway>) -> GatewayView {
        let Some(gateway) = gateway else {
            return GatewayView {
                enabled: false,
                running: false,
                bound_address: String::new(),
                port: 0,
                configured_address: String::new(),
                master_number: 0,
                strict: false,
                allow: Vec::new(),
                stats: GatewayStatsView::default(),
            };
        };
        let config = gateway.config();
        let running = gateway.is_running();
        GatewayView {
            enabled: true,
            running,
            bound_address: gateway
                .local_addr()
                .filter(|_| running)
                .map(|a| a.to_string())
                .unwrap_or_default(),
            port: gateway.port(),
            configured_address: SocketAddr::new(config.bind, config.wanted_port()).to_string(),
            master_number: config.master_number,
            strict: config.strict,
            allow: config.allow.iter().map(ToString::to_string).collect(),
            stats: GatewayStatsView::from(&gateway.stats()),
        }
    }
}

fn no_gateway() -> ApiError {
    ApiError {
        kind: ErrorKind::FailedPrecondition,
        tag: "no_gateway",
        message: "ecatd runs without a mailbox gateway (--no-gateway)".into(),
        code: None,
        code_text: String::new(),
        field: None,
    }
}

impl Core {
    /// The gateway's state, settings and statistics.
    pub fn gateway(&self) -> GatewayView {
        GatewayView::of(self.gateway_slot().as_ref())
    }

    /// Starts the gateway (binding the configured port, or a free one if it is taken) and
    /// returns its state; a running gateway stays as it is. Counters restart from zero.
    pub async fn start_gateway(&self, mut ticket: Ticket) -> Result<GatewayView> {
        ticket.check(Operation::StartGateway, "gateway")?;
        ticket.finish(self.open_gateway().await)
    }

    /// [`Core::start_gateway`] for ecatd itself, at start (no caller to audit).
    pub(crate) async fn open_gateway(&self) -> Result<GatewayView> {
        let core = self.clone();
        // Starting builds the gateway's runtime and thread: not on an async worker.
        tokio::task::spawn_blocking(move || {
            let mut slot = core.gateway_slot();
            let gateway = slot.as_mut().ok_or_else(no_gateway)?;
            let wanted = gateway.config().wanted_port();
            let was_running = gateway.is_running();
            let bound = gateway.start().map_err(|err| ApiError {
                kind: ErrorKind::Unavailable,
                tag: "gateway_bind",
                message: format!(
                    "cannot serve the gateway on {}:{wanted}: {err}",
                    gateway.config().bind
                ),
                code: None,
                code_text: String::new(),
                field: None,
            })?;
            if !was_running {
                if wanted != 0 && bound.port() != wanted {
                    tracing::warn!(wanted, bound = bound.port(), "mailbox gateway port taken; fell back to a free port");
                }
                tracing::info!(gateway = %bound, master_number = gateway.config().master_number, on_bus_thread = gateway.on_bus_thread(), workers = gateway.config().workers, "mailbox gateway serving");
                core.publish_event(EventView::note(
                    "gateway_started",
                    format!("mailbox gateway serving on udp {bound}"),
                ));
            }
            Ok(GatewayView::of(Some(gateway)))
        })
        .await
        .map_err(|err| ApiError::internal(format!("gateway start: {err}")))?
    }

    /// Stops the gateway (releasing its port; requests under way are cancelled) and
    /// returns its state; a stopped gateway stays stopped.
    pub async fn stop_gateway(&self, mut ticket: Ticket) -> Result<GatewayView> {
        ticket.check(Operation::StopGateway, "gateway")?;
        let core = self.clone();
        // Stopping joins the gateway's thread: not on an async worker.
        let stopped = tokio::task::spawn_blocking(move || {
            let mut slot = core.gateway_slot();
            let gateway = slot.as_mut().ok_or_else(no_gateway)?;
            if gateway.is_running() {
                gateway.stop();
                tracing::info!("mailbox gateway stopped");
                core.publish_event(EventView::note(
                    "gateway_stopped",
                    "mailbox gateway stopped (by a request)".into(),
                ));
            }
            Ok(GatewayView::of(Some(gateway)))
        })
        .await;
        ticket.finish(
            stopped.unwrap_or_else(|err| Err(ApiError::internal(format!("gateway stop: {err}")))),
        )
    }
}
