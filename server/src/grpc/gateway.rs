//! `ecat.v1.GatewayService`: the mailbox gateway's state and statistics, start and stop.

use proto::v1 as pb;
use proto::v1::gateway_service_server::GatewayService;
use tonic::{Request, Response, Status};

use super::status::status;
use crate::security::{Caller, authorize_write};
use crate::service::Core;
use crate::service::gateway::{GatewayStatsView, GatewayView};

/// The gateway service over the core.
pub struct Gateway {
    /// The service layer.
    pub core: Core,
}

type Reply<T> = Result<Response<T>, Status>;

/// The message for a view.
pub fn gateway_status(view: &GatewayView) -> pb::GatewayStatus {
    pb::GatewayStatus {
        enabled: view.enabled,
        running: view.running,
        bound_address: view.bound_address.clone(),
        port: u32::from(view.port),
        configured_address: view.configured_address.clone(),
        master_number: u32::from(view.master_number),
        strict: view.strict,
        allow: view.allow.clone(),
        stats: Some(stats(&view.stats)),
    }
}

fn stats(s: &GatewayStatsView) -> pb::GatewayStats {
    let f = &s.failures;
    pb::GatewayStats {
        total_requests: s.total_requests,
        forwarded_requests: s.forwarded_requests,
        failed_requests: s.failed_requests,
        coe_count: s.coe_count,
        soe_count: s.soe_count,
        foe_count: s.foe_count,
        voe_count: s.voe_count,
        eoe_count: s.eoe_count,
        started_at_ms: s.started_at_ms,
        failures: Some(pb::GatewayFailures {
            malformed: f.malformed,
            unknown_address: f.unknown_address,
            unsupported_protocol: f.unsupported_protocol,
            timeout: f.timeout,
            denied: f.denied,
            busy: f.busy,
            oversized: f.oversized,
            other: f.other,
        }),
        in_flight: s.in_flight,
        port: u32::from(s.port),
        latency: Some(pb::LatencySummary {
            count: s.latency.count,
            p50_us: s.latency.p50_us,
            p99_us: s.latency.p99_us,
            buckets: s
                .latency
                .buckets
                .iter()
                .map(|b| pb::LatencyBucket {
                    low_us: b.low_us,
                    high_us: b.high_us,
                    count: b.count,
                })
                .collect(),
        }),
    }
}

fn require_write<T>(request: &Request<T>, operation: &str) -> Result<(), Status> {
    authorize_write(request.extensions().get::<Caller>(), operation, "gateway").map_err(status)
}

#[tonic::async_trait]
impl GatewayService for Gateway {
    async fn get_gateway(&self, _: Request<pb::GetGatewayRequest>) -> Reply<pb::GatewayStatus> {
        Ok(Response::new(gateway_status(&self.core.gateway())))
    }

    async fn start_gateway(
        &self,
        request: Request<pb::StartGatewayRequest>,
    ) -> Reply<pb::GatewayStatus> {
        require_write(&request, "start_gateway")?;
        let view = self.core.start_gateway().await.map_err(status)?;
        Ok(Response::new(gateway_status(&view)))
    }

    async fn stop_gateway(
        &self,
        request: Request<pb::StopGatewayRequest>,
    ) -> Reply<pb::GatewayStatus> {
        require_write(&request, "stop_gateway")?;
        let view = self.core.stop_gateway().await.map_err(status)?;
        Ok(Response::new(gateway_status(&view)))
    }
}
