//! REST handlers of the mailbox gateway: `GET /api/v1/gateway`, `POST /api/v1/gateway/start`,
//! `POST /api/v1/gateway/stop` (writes: write role, audit line, as every POST).

use axum::extract::State;

use crate::http::extract::Admit;
use crate::http::extract::Json;
use crate::service::op;
use crate::service::{ApiError, Core, GatewayView};

#[utoipa::path(get, path = "/gateway", tag = "gateway",
    responses((status = 200, body = GatewayView)))]
/// The mailbox gateway: running, address bound, settings, statistics.
pub async fn get_gateway(State(core): State<Core>) -> Json<GatewayView> {
    Json(core.gateway())
}

#[utoipa::path(post, path = "/gateway/start", tag = "gateway",
    responses((status = 200, body = GatewayView),
        (status = 409, description = "no gateway configured", body = super::error::ErrorBody),
        (status = 503, description = "cannot bind", body = super::error::ErrorBody)))]
/// Starts the mailbox gateway (a taken port falls back to a free one, reported in `port`).
pub async fn start_gateway(
    Admit(ticket, _): Admit<op::StartGateway>,
    State(core): State<Core>,
) -> Result<Json<GatewayView>, ApiError> {
    core.start_gateway(ticket).await.map(Json)
}

#[utoipa::path(post, path = "/gateway/stop", tag = "gateway",
    responses((status = 200, body = GatewayView),
        (status = 409, description = "no gateway configured", body = super::error::ErrorBody)))]
/// Stops the mailbox gateway and releases its port.
pub async fn stop_gateway(
    Admit(ticket, _): Admit<op::StopGateway>,
    State(core): State<Core>,
) -> Result<Json<GatewayView>, ApiError> {
    core.stop_gateway(ticket).await.map(Json)
}
