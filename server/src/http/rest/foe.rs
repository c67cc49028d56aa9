//! FoE: reading and writing files (raw bodies). These routes have no request time limit:
//! the transfer's own deadlines follow its progress (`service::transfer`), and a client
//! that disconnects drops the call, which ends the transfer towards the slave.

use axum::body::Bytes;
use axum::extract::State;
use serde::Deserialize;
use utoipa::IntoParams;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::{DONE, Done, Result};
use crate::http::extract::{Admit, Json, Path, Query};
use crate::service::Core;
use crate::service::{op, parse_name};

/// The routes, each declared once (method and path come from the handler's annotation).
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new().routes(routes!(foe_read, foe_write))
}

/// FoE password.
#[derive(Debug, Deserialize, IntoParams)]
pub struct PasswordQuery {
    /// Password (default 0).
    pub password: Option<u32>,
}

#[utoipa::path(get, path = "/slaves/{slave}/foe/{name}", tag = "foe",
    params(("slave" = String, Path), ("name" = String, Path), PasswordQuery),
    responses((status = 200, description = "The file", content_type = "application/octet-stream", body = Vec<u8>)))]
/// Reads a file.
pub async fn foe_read(
    State(core): State<Core>,
    Path((slave, name)): Path<(String, String)>,
    Query(q): Query<PasswordQuery>,
) -> Result<Vec<u8>> {
    core.foe_read(parse_name(&slave)?, &name, q.password.unwrap_or(0), None)
        .await
}

#[utoipa::path(put, path = "/slaves/{slave}/foe/{name}", tag = "foe",
    request_body(content = Vec<u8>, content_type = "application/octet-stream"),
    params(("slave" = String, Path), ("name" = String, Path), PasswordQuery),
    responses((status = 200, body = Done)))]
/// Writes a file (the raw request body).
pub async fn foe_write(
    Admit(ticket, _): Admit<op::FoeWrite>,
    State(core): State<Core>,
    Path((slave, name)): Path<(String, String)>,
    Query(q): Query<PasswordQuery>,
    body: Bytes,
) -> Result<Json<Done>> {
    core.foe_write(
        ticket,
        parse_name(&slave)?,
        &name,
        q.password.unwrap_or(0),
        &body,
        None,
    )
    .await
    .map(|()| DONE)
}
