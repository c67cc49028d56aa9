//! The SII (EEPROM) image and the station alias.

use axum::extract::State;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::{DONE, Data, Done, Result, data, num, unhex};
use crate::http::extract::{Admit, Json, Path, Query};
use crate::service::Core;
use crate::service::{op, parse_name};

/// The routes, each declared once (method and path come from the handler's annotation).
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new()
        .routes(routes!(read_sii))
        .routes(routes!(write_sii))
        .routes(routes!(set_alias))
}

/// A station alias.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct AliasBody {
    /// The alias (the answer: the alias register read back).
    pub alias: u16,
}

#[utoipa::path(get, path = "/slaves/{slave}/sii", tag = "sii",
    params(("slave" = String, Path)), responses((status = 200, body = Data)))]
/// Reads the whole SII image.
pub async fn read_sii(State(core): State<Core>, Path(slave): Path<String>) -> Result<Json<Data>> {
    core.read_sii(parse_name(&slave)?).await.map(data)
}

/// Options of an SII write.
#[derive(Debug, Default, Deserialize, utoipa::IntoParams)]
pub struct SiiWriteQuery {
    /// Write the words as given, even a checksum (word 7) that does not match words 0-6.
    #[serde(default)]
    pub force: bool,
}

#[utoipa::path(put, path = "/slaves/{slave}/sii/{word}", tag = "sii", request_body = Data,
    params(("slave" = String, Path), ("word" = String, Path, description = "first word address"),
        SiiWriteQuery),
    responses((status = 200, body = Done)))]
/// Writes SII words (little-endian bytes); the checksum of words 0-6 is kept valid unless
/// `force`.
pub async fn write_sii(
    Admit(ticket, _): Admit<op::WriteSii>,
    State(core): State<Core>,
    Path((slave, word)): Path<(String, String)>,
    Query(query): Query<SiiWriteQuery>,
    Json(body): Json<Data>,
) -> Result<Json<Done>> {
    core.write_sii(
        ticket,
        parse_name(&slave)?,
        num(&word, "word")?,
        &unhex(&body.data)?,
        query.force,
    )
    .await
    .map(|()| DONE)
}

#[utoipa::path(put, path = "/slaves/{slave}/alias", tag = "sii", request_body = AliasBody,
    params(("slave" = String, Path)), responses((status = 200, body = AliasBody)))]
/// Sets the station alias.
pub async fn set_alias(
    Admit(ticket, _): Admit<op::SetAlias>,
    State(core): State<Core>,
    Path(slave): Path<String>,
    Json(body): Json<AliasBody>,
) -> Result<Json<AliasBody>> {
    core.set_alias(ticket, parse_name(&slave)?, body.alias)
        .await
        .map(|alias| Json(AliasBody { alias }))
}
