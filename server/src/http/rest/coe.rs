//! CoE: SDO upload and download (bytes or typed values) and SDO Information.

use axum::extract::State;
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::{DONE, Done, Result, num, unhex};
use crate::http::extract::{Admit, Json, Path, Query};
use crate::service::{Core, EntryView, ObjectView, SdoPayload};
use crate::service::{op, parse_name};

/// The routes, each declared once (method and path come from the handler's annotation).
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new()
        .routes(routes!(coe_upload, coe_download))
        .routes(routes!(coe_object_list))
        .routes(routes!(coe_object))
        .routes(routes!(coe_entry))
}

/// What to write: bytes as hex, or a value as text with its type.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SdoWrite {
    /// The bytes, hex (when no `type` is given).
    #[serde(default)]
    pub data: String,
    /// The value as text (with `type`).
    #[serde(default)]
    pub value: String,
    /// `auto` (the slave's SDO Information type) or a type name (`u8` … `u64`, `i8` … `i64`,
    /// `f32`, `f64`, `bool`, `string`, `hex`).
    #[serde(default, rename = "type")]
    pub value_type: Option<String>,
    /// Complete access from the subindex on.
    #[serde(default)]
    pub complete_access: bool,
}

/// An object list.
#[derive(Debug, Serialize, ToSchema)]
pub struct ObjectList {
    /// Object indices.
    pub indices: Vec<u16>,
}

/// CoE upload options.
#[derive(Debug, Deserialize, IntoParams)]
pub struct UploadQuery {
    /// Complete access from the subindex on.
    #[serde(default)]
    pub complete_access: bool,
    /// Also decode the value: `auto` (the slave's SDO Information type) or a type name.
    #[serde(rename = "type")]
    pub value_type: Option<String>,
}

/// Uploaded bytes, and the value when a type was asked for.
#[derive(Debug, Serialize, ToSchema)]
pub struct Upload {
    /// The bytes, hex.
    pub data: String,
    /// The value as text.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<String>,
}

/// Object list type.
#[derive(Debug, Deserialize, IntoParams)]
pub struct ListQuery {
    /// 1 all (default), 2 RxPDO-mappable, 3 TxPDO-mappable, 4 backup, 5 settings.
    pub list: Option<u16>,
}

#[utoipa::path(get, path = "/slaves/{slave}/coe/sdo/{index}/{subindex}", tag = "coe",
    params(("slave" = String, Path), ("index" = String, Path), ("subindex" = String, Path), UploadQuery),
    responses((status = 200, body = Upload), (status = 409, description = "SDO abort", body = crate::http::error::ErrorBody)))]
/// SDO upload.
pub async fn coe_upload(
    State(core): State<Core>,
    Path((slave, index, subindex)): Path<(String, String, String)>,
    Query(q): Query<UploadQuery>,
) -> Result<Json<Upload>> {
    let (index, subindex) = (num(&index, "index")?, num(&subindex, "subindex")?);
    let read = core
        .coe_read(
            parse_name(&slave)?,
            index,
            subindex,
            q.complete_access,
            q.value_type.as_deref().map(str::parse).transpose()?,
        )
        .await?;
    Ok(Json(Upload {
        data: hex::encode(read.data),
        value: read.value,
    }))
}

#[utoipa::path(put, path = "/slaves/{slave}/coe/sdo/{index}/{subindex}", tag = "coe", request_body = SdoWrite,
    params(("slave" = String, Path), ("index" = String, Path), ("subindex" = String, Path)),
    responses((status = 200, body = Done)))]
/// SDO download.
pub async fn coe_download(
    Admit(ticket, _): Admit<op::CoeDownload>,
    State(core): State<Core>,
    Path((slave, index, subindex)): Path<(String, String, String)>,
    Json(body): Json<SdoWrite>,
) -> Result<Json<Done>> {
    let (index, subindex) = (num(&index, "index")?, num(&subindex, "subindex")?);
    let bytes;
    let payload = match &body.value_type {
        None => {
            bytes = unhex(&body.data)?;
            SdoPayload::Bytes {
                data: &bytes,
                complete: body.complete_access,
            }
        }
        Some(ty) => SdoPayload::Value {
            text: &body.value,
            typing: ty.parse()?,
            complete: body.complete_access,
        },
    };
    core.coe_write(ticket, parse_name(&slave)?, index, subindex, payload)
        .await?;
    Ok(DONE)
}

#[utoipa::path(get, path = "/slaves/{slave}/coe/od", tag = "coe",
    params(("slave" = String, Path), ListQuery), responses((status = 200, body = ObjectList)))]
/// The object list (SDO Information).
pub async fn coe_object_list(
    State(core): State<Core>,
    Path(slave): Path<String>,
    Query(q): Query<ListQuery>,
) -> Result<Json<ObjectList>> {
    core.coe_object_list(parse_name(&slave)?, q.list.unwrap_or(1))
        .await
        .map(|indices| Json(ObjectList { indices }))
}

#[utoipa::path(get, path = "/slaves/{slave}/coe/od/{index}", tag = "coe",
    params(("slave" = String, Path), ("index" = String, Path)), responses((status = 200, body = ObjectView)))]
/// An object description.
pub async fn coe_object(
    State(core): State<Core>,
    Path((slave, index)): Path<(String, String)>,
) -> Result<Json<ObjectView>> {
    core.coe_object(parse_name(&slave)?, num(&index, "index")?)
        .await
        .map(Json)
}

#[utoipa::path(get, path = "/slaves/{slave}/coe/od/{index}/{subindex}", tag = "coe",
    params(("slave" = String, Path), ("index" = String, Path), ("subindex" = String, Path)),
    responses((status = 200, body = EntryView)))]
/// An entry description.
pub async fn coe_entry(
    State(core): State<Core>,
    Path((slave, index, subindex)): Path<(String, String, String)>,
) -> Result<Json<EntryView>> {
    core.coe_entry(
        parse_name(&slave)?,
        num(&index, "index")?,
        num(&subindex, "subindex")?,
    )
    .await
    .map(Json)
}
