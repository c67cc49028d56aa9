//! The slaves and the segment: list, one slave, AL state, rescan.

use axum::extract::State;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::Result;
use crate::http::extract::{Admit, Json, Path};
use crate::service::{Core, MasterView, SlaveView};
use crate::service::{op, parse_name};

/// The routes, each declared once (method and path come from the handler's annotation).
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new()
        .routes(routes!(list_slaves))
        .routes(routes!(get_slave))
        .routes(routes!(request_state))
        .routes(routes!(rescan))
        .routes(routes!(get_master))
}

#[utoipa::path(get, path = "/master", tag = "bus", responses((status = 200, body = MasterView)))]
/// The master: link, MAC, cycle, DC reference clock, frame counters, version, readiness.
pub async fn get_master(State(core): State<Core>) -> Json<MasterView> {
    Json(core.master_view())
}

/// The event stream: open for as long as the client listens, so outside the request time
/// limit.
/// A requested AL state.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct StateBody {
    /// `INIT`, `PREOP`, `BOOT`, `SAFEOP` or `OP`.
    pub state: String,
}

/// The result of a rescan.
#[derive(Debug, Serialize, ToSchema)]
pub struct RescanBody {
    /// Every slave.
    pub slaves: Vec<SlaveView>,
    /// One message per slave that refused a state.
    pub failures: Vec<String>,
}

#[utoipa::path(get, path = "/slaves", tag = "bus", responses((status = 200, body = [SlaveView])))]
/// Every slave of the last scan.
pub async fn list_slaves(State(core): State<Core>) -> Json<Vec<SlaveView>> {
    Json(core.list_slaves())
}

#[utoipa::path(get, path = "/slaves/{slave}", tag = "bus",
    params(("slave" = String, Path, description = "pos:3, station:1004, alias:0x777, alias:0x777+2 (or 3, %231004, @0x777)")),
    responses((status = 200, body = SlaveView), (status = 404, body = crate::http::error::ErrorBody)))]
/// One slave.
pub async fn get_slave(
    State(core): State<Core>,
    Path(slave): Path<String>,
) -> Result<Json<SlaveView>> {
    core.get_slave(parse_name(&slave)?).map(Json)
}

#[utoipa::path(put, path = "/slaves/{slave}/state", tag = "bus", request_body = StateBody,
    params(("slave" = String, Path)), responses((status = 200, body = SlaveView)))]
/// Moves a slave to a state.
pub async fn request_state(
    Admit(ticket, _): Admit<op::RequestState>,
    State(core): State<Core>,
    Path(slave): Path<String>,
    Json(body): Json<StateBody>,
) -> Result<Json<SlaveView>> {
    let state = crate::input::state::parse_state(&body.state)?;
    core.request_state(ticket, parse_name(&slave)?, state)
        .await
        .map(Json)
}

#[utoipa::path(post, path = "/rescan", tag = "bus", responses((status = 200, body = RescanBody)))]
/// Scans the segment again.
pub async fn rescan(
    Admit(ticket, _): Admit<op::Rescan>,
    State(core): State<Core>,
) -> Result<Json<RescanBody>> {
    let (slaves, failures) = core.rescan(ticket).await?;
    Ok(Json(RescanBody { slaves, failures }))
}
