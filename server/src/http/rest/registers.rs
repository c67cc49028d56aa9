//! ESC register access.

use axum::Extension;
use axum::extract::State;
use serde::Deserialize;
use utoipa::IntoParams;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::{DONE, Data, Done, Result, data, num, unhex};
use crate::http::extract::{Admit, Json, Path, Query};
use crate::security::Caller;
use crate::service::Core;
use crate::service::{op, parse_name};

/// The routes, each declared once (method and path come from the handler's annotation).
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new()
        .routes(routes!(read_register, write_register))
        .routes(routes!(read_write_register))
}

/// Register read length.
#[derive(Debug, Deserialize, IntoParams)]
pub struct LengthQuery {
    /// Bytes to read (default 1).
    pub length: Option<usize>,
}

#[utoipa::path(get, path = "/slaves/{slave}/registers/{address}", tag = "registers",
    params(("slave" = String, Path), ("address" = String, Path, description = "register address"), LengthQuery),
    responses((status = 200, body = Data)))]
/// Reads ESC registers.
pub async fn read_register(
    State(core): State<Core>,
    caller: Option<Extension<Caller>>,
    Path((slave, address)): Path<(String, String)>,
    Query(q): Query<LengthQuery>,
) -> Result<Json<Data>> {
    let caller = caller.map(|Extension(c)| c);
    core.read_register(
        caller.as_ref(),
        parse_name(&slave)?,
        num(&address, "address")?,
        q.length.unwrap_or(1),
    )
    .await
    .map(data)
}

#[utoipa::path(put, path = "/slaves/{slave}/registers/{address}", tag = "registers", request_body = Data,
    params(("slave" = String, Path), ("address" = String, Path)), responses((status = 200, body = Done)))]
/// Writes ESC registers.
pub async fn write_register(
    Admit(ticket, _): Admit<op::WriteRegister>,
    State(core): State<Core>,
    Path((slave, address)): Path<(String, String)>,
    Json(body): Json<Data>,
) -> Result<Json<Done>> {
    let (slave, address) = (parse_name(&slave)?, num(&address, "address")?);
    core.write_register(ticket, slave, address, &unhex(&body.data)?)
        .await
        .map(|()| DONE)
}

#[utoipa::path(post, path = "/slaves/{slave}/registers/{address}/rdwr", tag = "registers", request_body = Data,
    params(("slave" = String, Path), ("address" = String, Path)), responses((status = 200, body = Data)))]
/// Writes ESC registers and returns their contents from before the write, in one FPRW
/// datagram.
pub async fn read_write_register(
    Admit(ticket, _): Admit<op::ReadWriteRegister>,
    State(core): State<Core>,
    Path((slave, address)): Path<(String, String)>,
    Json(body): Json<Data>,
) -> Result<Json<Data>> {
    let (slave, address) = (parse_name(&slave)?, num(&address, "address")?);
    core.read_write_register(ticket, slave, address, &unhex(&body.data)?)
        .await
        .map(data)
}
