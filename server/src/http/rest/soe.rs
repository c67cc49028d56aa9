//! SoE: reading and writing IDNs.

use axum::extract::State;
use serde::Deserialize;
use utoipa::IntoParams;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::{DONE, Data, Done, Result, data, num, unhex};
use crate::http::extract::{Admit, Json, Path, Query};
use crate::service::Core;
use crate::service::{op, parse_name};

/// The routes, each declared once (method and path come from the handler's annotation).
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new().routes(routes!(soe_read, soe_write))
}

/// SoE elements.
#[derive(Debug, Deserialize, IntoParams)]
pub struct ElementsQuery {
    /// Element flags (default 0x40, the value).
    pub elements: Option<u8>,
}

#[utoipa::path(get, path = "/slaves/{slave}/soe/{drive}/{idn}", tag = "soe",
    params(("slave" = String, Path), ("drive" = String, Path), ("idn" = String, Path, description = "P-0-0100, S-0-0011 or a number (0x8064)"), ElementsQuery),
    responses((status = 200, body = Data)))]
/// Reads an IDN.
pub async fn soe_read(
    State(core): State<Core>,
    Path((slave, drive, idn)): Path<(String, String, String)>,
    Query(q): Query<ElementsQuery>,
) -> Result<Json<Data>> {
    core.soe_read(
        parse_name(&slave)?,
        num(&drive, "drive")?,
        crate::input::value::parse_idn(&idn, "idn")?,
        q.elements.unwrap_or(0),
    )
    .await
    .map(data)
}

#[utoipa::path(put, path = "/slaves/{slave}/soe/{drive}/{idn}", tag = "soe", request_body = Data,
    params(("slave" = String, Path), ("drive" = String, Path), ("idn" = String, Path), ElementsQuery),
    responses((status = 200, body = Done)))]
/// Writes an IDN.
pub async fn soe_write(
    Admit(ticket, _): Admit<op::SoeWrite>,
    State(core): State<Core>,
    Path((slave, drive, idn)): Path<(String, String, String)>,
    Query(q): Query<ElementsQuery>,
    Json(body): Json<Data>,
) -> Result<Json<Done>> {
    core.soe_write(
        ticket,
        parse_name(&slave)?,
        num(&drive, "drive")?,
        crate::input::value::parse_idn(&idn, "idn")?,
        q.elements.unwrap_or(0),
        &unhex(&body.data)?,
    )
    .await
    .map(|()| DONE)
}
