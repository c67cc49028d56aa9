//! `ecat.v1.GatewayService`: the mailbox gateway's state and statistics, start and stop.

use proto::v1 as pb;
use proto::v1::gateway_service_server::GatewayService;
use tonic::{Request, Response, Status};

use super::auth::admit;
use crate::service::gateway::{
    GatewayFailuresView, GatewayStatsView, GatewayView, LatencyBucketView, LatencyView,
};
use crate::service::{Core, Operation};

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
    // Whole destructuring, no `..`: a counter added to the view does not compile until the
    // message carries it too.
    let GatewayStatsView {
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
        retries_answered,
    } = s;
    let GatewayFailuresView {
        malformed,
        unknown_address,
        unsupported_protocol,
        timeout,
        denied,
        busy,
        oversized,
        other,
    } = failures;
    let LatencyView {
        count,
        p50_us,
        p99_us,
        buckets,
    } = latency;
    pb::GatewayStats {
        total_requests: *total_requests,
        forwarded_requests: *forwarded_requests,
        failed_requests: *failed_requests,
        coe_count: *coe_count,
        soe_count: *soe_count,
        foe_count: *foe_count,
        voe_count: *voe_count,
        eoe_count: *eoe_count,
        started_at_ms: *started_at_ms,
        failures: Some(pb::GatewayFailures {
            malformed: *malformed,
            unknown_address: *unknown_address,
            unsupported_protocol: *unsupported_protocol,
            timeout: *timeout,
            denied: *denied,
            busy: *busy,
            oversized: *oversized,
            other: *other,
        }),
        in_flight: *in_flight,
        port: u32::from(*port),
        latency: Some(pb::LatencySummary {
            count: *count,
            p50_us: *p50_us,
            p99_us: *p99_us,
            buckets: buckets
                .iter()
                .map(
                    |LatencyBucketView {
                         low_us,
                         high_us,
                         count,
                     }| pb::LatencyBucket {
                        low_us: *low_us,
                        high_us: *high_us,
                        count: *count,
                    },
                )
                .collect(),
        }),
        retries_answered: *retries_answered,
    }
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
        let ticket = admit(&self.core, &request, Operation::StartGateway)?;
        let view = self.core.start_gateway(ticket).await?;
        Ok(Response::new(gateway_status(&view)))
    }

    async fn stop_gateway(
        &self,
        request: Request<pb::StopGatewayRequest>,
    ) -> Reply<pb::GatewayStatus> {
        let ticket = admit(&self.core, &request, Operation::StopGateway)?;
        let view = self.core.stop_gateway(ticket).await?;
        Ok(Response::new(gateway_status(&view)))
    }
}
