//! SoE: reading and writing IDNs.

use axum::extract::State;
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::{DONE, Done, Result, num, unhex};
use crate::http::extract::{Admit, Json, Path, Query};
use crate::input::soe_value;
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

/// SoE read options.
#[derive(Debug, Deserialize, IntoParams)]
pub struct ReadQuery {
    /// Element flags (default 0x40, the value).
    pub elements: Option<u8>,
    /// Also decode the value as this type (`u16`, `u32`, `i32`, `string`, `hex`, ... as
    /// CoE's, without `auto`); a string is read without its length header.
    #[serde(rename = "type")]
    pub value_type: Option<String>,
}

/// The element read, and the value when a type was asked for.
#[derive(Debug, Serialize, ToSchema)]
pub struct SoeRead {
    /// The bytes, hex.
    pub data: String,
    /// The value as text.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<String>,
}

/// What to write: bytes as hex, or a value as text with its type.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SoeWrite {
    /// The bytes, hex (when no `type` is given).
    #[serde(default)]
    pub data: String,
    /// The value as text (with `type`).
    #[serde(default)]
    pub value: String,
    /// A type name, as for reading; a string gets its length header.
    #[serde(default, rename = "type")]
    pub value_type: Option<String>,
}

#[utoipa::path(get, path = "/slaves/{slave}/soe/{drive}/{idn}", tag = "soe",
    params(("slave" = String, Path), ("drive" = String, Path), ("idn" = String, Path, description = "P-0-0100, S-0-0011 or a number (0x8064)"), ReadQuery),
    responses((status = 200, body = SoeRead)))]
/// Reads an IDN.
pub async fn soe_read(
    State(core): State<Core>,
    Path((slave, drive, idn)): Path<(String, String, String)>,
    Query(q): Query<ReadQuery>,
) -> Result<Json<SoeRead>> {
    let (data, value) = core
        .soe_read_as(
            parse_name(&slave)?,
            num(&drive, "drive")?,
            crate::input::value::parse_idn(&idn, "idn")?,
            q.elements.unwrap_or(0),
            soe_value::parse_type(q.value_type.as_deref().unwrap_or(""))?,
        )
        .await?;
    Ok(Json(SoeRead {
        data: hex::encode(data),
        value,
    }))
}

#[utoipa::path(put, path = "/slaves/{slave}/soe/{drive}/{idn}", tag = "soe", request_body = SoeWrite,
    params(("slave" = String, Path), ("drive" = String, Path), ("idn" = String, Path), ElementsQuery),
    responses((status = 200, body = Done)))]
/// Writes an IDN.
pub async fn soe_write(
    Admit(ticket, _): Admit<op::SoeWrite>,
    State(core): State<Core>,
    Path((slave, drive, idn)): Path<(String, String, String)>,
    Query(q): Query<ElementsQuery>,
    Json(body): Json<SoeWrite>,
) -> Result<Json<Done>> {
    let data = match soe_value::parse_type(body.value_type.as_deref().unwrap_or(""))? {
        Some(ty) => soe_value::encode(ty, &body.value)?,
        None => unhex(&body.data)?,
    };
    core.soe_write(
        ticket,
        parse_name(&slave)?,
        num(&drive, "drive")?,
        crate::input::value::parse_idn(&idn, "idn")?,
        q.elements.unwrap_or(0),
        &data,
    )
    .await
    .map(|()| DONE)
}
