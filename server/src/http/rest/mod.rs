//! REST handlers under `/api/v1`: the same operations as gRPC, one core call each. Binary
//! values are hex strings; numbers in paths are decimal or `0x` hex; slave names use the
//! common syntax (`3`, `%231004` for `#1004`, `@0x777`).

use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, Query, State};
use axum::response::sse::{Event, KeepAlive, Sse};
use futures_util::Stream;
use serde::{Deserialize, Serialize};
use tokio_stream::StreamExt;
use tokio_stream::wrappers::BroadcastStream;
use tokio_stream::wrappers::errors::BroadcastStreamRecvError;
use utoipa::{IntoParams, ToSchema};

use crate::service::value::parse_number;
use crate::service::{
    ApiError, Core, EntryView, EventView, IpView, ObjectView, SlaveView, VoeView,
};

type Result<T> = std::result::Result<T, ApiError>;

fn num<T: TryFrom<u64>>(text: &str, field: &str) -> Result<T> {
    parse_number(text, field)
}

fn unhex(text: &str) -> Result<Vec<u8>> {
    hex::decode(text.trim()).map_err(|_| ApiError::invalid("data must be hex"))
}

/// Bytes as hex.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct Data {
    /// The bytes, hex (`"0100e0"`).
    pub data: String,
}

fn data(bytes: Vec<u8>) -> Json<Data> {
    Json(Data {
        data: hex::encode(bytes),
    })
}

/// What to write: bytes as hex, or a value as text with its type.
#[derive(Debug, Deserialize, ToSchema)]
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

/// A requested AL state.
#[derive(Debug, Deserialize, ToSchema)]
pub struct StateBody {
    /// `INIT`, `PREOP`, `BOOT`, `SAFEOP` or `OP`.
    pub state: String,
}

/// A station alias.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct AliasBody {
    /// The alias (the answer: the alias register read back).
    pub alias: u16,
}

/// The result of a rescan.
#[derive(Debug, Serialize, ToSchema)]
pub struct RescanBody {
    /// Every slave.
    pub slaves: Vec<SlaveView>,
    /// One message per slave that refused a state.
    pub failures: Vec<String>,
}

/// An object list.
#[derive(Debug, Serialize, ToSchema)]
pub struct ObjectList {
    /// Object indices.
    pub indices: Vec<u16>,
}

/// Register read length.
#[derive(Debug, Deserialize, IntoParams)]
pub struct LengthQuery {
    /// Bytes to read (default 1).
    pub length: Option<usize>,
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

/// SoE elements.
#[derive(Debug, Deserialize, IntoParams)]
pub struct ElementsQuery {
    /// Element flags (default 0x40, the value).
    pub elements: Option<u8>,
}

/// FoE password.
#[derive(Debug, Deserialize, IntoParams)]
pub struct PasswordQuery {
    /// Password (default 0).
    pub password: Option<u32>,
}

/// A VoE message to send.
#[derive(Debug, Deserialize, ToSchema)]
pub struct VoeBody {
    /// Vendor id.
    pub vendor_id: u32,
    /// Vendor type.
    pub vendor_type: u16,
    /// Payload, hex.
    pub data: String,
}

/// A done write.
#[derive(Debug, Serialize, ToSchema)]
pub struct Done {
    /// Always true.
    pub ok: bool,
}

const DONE: Json<Done> = Json(Done { ok: true });

#[utoipa::path(get, path = "/api/v1/slaves", tag = "bus", responses((status = 200, body = [SlaveView])))]
/// Every slave of the last scan.
pub async fn list_slaves(State(core): State<Core>) -> Json<Vec<SlaveView>> {
    Json(core.list_slaves())
}

#[utoipa::path(get, path = "/api/v1/slaves/{slave}", tag = "bus",
    params(("slave" = String, Path, description = "3, %231004, @0x777")),
    responses((status = 200, body = SlaveView), (status = 404, body = super::error::ErrorBody)))]
/// One slave.
pub async fn get_slave(
    State(core): State<Core>,
    Path(slave): Path<String>,
) -> Result<Json<SlaveView>> {
    core.get_slave(&slave).map(Json)
}

#[utoipa::path(put, path = "/api/v1/slaves/{slave}/state", tag = "bus", request_body = StateBody,
    params(("slave" = String, Path)), responses((status = 200, body = SlaveView)))]
/// Moves a slave to a state.
pub async fn request_state(
    State(core): State<Core>,
    Path(slave): Path<String>,
    Json(body): Json<StateBody>,
) -> Result<Json<SlaveView>> {
    core.request_state(&slave, &body.state).await.map(Json)
}

#[utoipa::path(post, path = "/api/v1/rescan", tag = "bus", responses((status = 200, body = RescanBody)))]
/// Scans the segment again.
pub async fn rescan(State(core): State<Core>) -> Result<Json<RescanBody>> {
    let (slaves, failures) = core.rescan().await?;
    Ok(Json(RescanBody { slaves, failures }))
}

#[utoipa::path(get, path = "/api/v1/events", tag = "bus",
    responses((status = 200, description = "Server-sent events, one EventView as JSON each", content_type = "text/event-stream", body = EventView)))]
/// Topology and state events and CoE emergencies as server-sent events.
pub async fn events(
    State(core): State<Core>,
) -> Sse<impl Stream<Item = std::result::Result<Event, std::convert::Infallible>>> {
    let stream = BroadcastStream::new(core.events()).map(|item| {
        let view = match item {
            Ok(view) => view,
            Err(BroadcastStreamRecvError::Lagged(missed)) => EventView::lagged(missed),
        };
        let event = Event::default().event(view.kind.clone());
        Ok(event
            .json_data(&view)
            .unwrap_or_else(|_| Event::default().comment("unencodable")))
    });
    Sse::new(stream).keep_alive(KeepAlive::default())
}

#[utoipa::path(get, path = "/api/v1/slaves/{slave}/registers/{address}", tag = "registers",
    params(("slave" = String, Path), ("address" = String, Path, description = "register address"), LengthQuery),
    responses((status = 200, body = Data)))]
/// Reads ESC registers.
pub async fn read_register(
    State(core): State<Core>,
    Path((slave, address)): Path<(String, String)>,
    Query(q): Query<LengthQuery>,
) -> Result<Json<Data>> {
    core.read_register(&slave, num(&address, "address")?, q.length.unwrap_or(1))
        .await
        .map(data)
}

#[utoipa::path(put, path = "/api/v1/slaves/{slave}/registers/{address}", tag = "registers", request_body = Data,
    params(("slave" = String, Path), ("address" = String, Path)), responses((status = 200, body = Done)))]
/// Writes ESC registers.
pub async fn write_register(
    State(core): State<Core>,
    Path((slave, address)): Path<(String, String)>,
    Json(body): Json<Data>,
) -> Result<Json<Done>> {
    core.write_register(&slave, num(&address, "address")?, &unhex(&body.data)?)
        .await
        .map(|()| DONE)
}

#[utoipa::path(get, path = "/api/v1/slaves/{slave}/sii", tag = "sii",
    params(("slave" = String, Path)), responses((status = 200, body = Data)))]
/// Reads the whole SII image.
pub async fn read_sii(State(core): State<Core>, Path(slave): Path<String>) -> Result<Json<Data>> {
    core.read_sii(&slave).await.map(data)
}

#[utoipa::path(put, path = "/api/v1/slaves/{slave}/sii/{word}", tag = "sii", request_body = Data,
    params(("slave" = String, Path), ("word" = String, Path, description = "first word address")),
    responses((status = 200, body = Done)))]
/// Writes SII words (little-endian bytes).
pub async fn write_sii(
    State(core): State<Core>,
    Path((slave, word)): Path<(String, String)>,
    Json(body): Json<Data>,
) -> Result<Json<Done>> {
    core.write_sii(&slave, num(&word, "word")?, &unhex(&body.data)?)
        .await
        .map(|()| DONE)
}

#[utoipa::path(put, path = "/api/v1/slaves/{slave}/alias", tag = "sii", request_body = AliasBody,
    params(("slave" = String, Path)), responses((status = 200, body = AliasBody)))]
/// Sets the station alias.
pub async fn set_alias(
    State(core): State<Core>,
    Path(slave): Path<String>,
    Json(body): Json<AliasBody>,
) -> Result<Json<AliasBody>> {
    core.set_alias(&slave, body.alias)
        .await
        .map(|alias| Json(AliasBody { alias }))
}

#[utoipa::path(get, path = "/api/v1/slaves/{slave}/coe/sdo/{index}/{subindex}", tag = "coe",
    params(("slave" = String, Path), ("index" = String, Path), ("subindex" = String, Path), UploadQuery),
    responses((status = 200, body = Upload), (status = 409, description = "SDO abort", body = super::error::ErrorBody)))]
/// SDO upload.
pub async fn coe_upload(
    State(core): State<Core>,
    Path((slave, index, subindex)): Path<(String, String, String)>,
    Query(q): Query<UploadQuery>,
) -> Result<Json<Upload>> {
    let (index, subindex) = (num(&index, "index")?, num(&subindex, "subindex")?);
    let (bytes, value) = match &q.value_type {
        None => (
            core.coe_upload(&slave, index, subindex, q.complete_access)
                .await?,
            None,
        ),
        Some(ty) => {
            let (bytes, value) = core
                .coe_upload_value(&slave, index, subindex, q.complete_access, ty)
                .await?;
            (bytes, Some(value))
        }
    };
    Ok(Json(Upload {
        data: hex::encode(bytes),
        value,
    }))
}

#[utoipa::path(put, path = "/api/v1/slaves/{slave}/coe/sdo/{index}/{subindex}", tag = "coe", request_body = SdoWrite,
    params(("slave" = String, Path), ("index" = String, Path), ("subindex" = String, Path)),
    responses((status = 200, body = Done)))]
/// SDO download.
pub async fn coe_download(
    State(core): State<Core>,
    Path((slave, index, subindex)): Path<(String, String, String)>,
    Json(body): Json<SdoWrite>,
) -> Result<Json<Done>> {
    let (index, subindex) = (num(&index, "index")?, num(&subindex, "subindex")?);
    match &body.value_type {
        None => {
            core.coe_download(
                &slave,
                index,
                subindex,
                &unhex(&body.data)?,
                body.complete_access,
            )
            .await?
        }
        Some(ty) => {
            core.coe_download_value(&slave, index, subindex, &body.value, ty)
                .await?
        }
    }
    Ok(DONE)
}

#[utoipa::path(get, path = "/api/v1/slaves/{slave}/coe/od", tag = "coe",
    params(("slave" = String, Path), ListQuery), responses((status = 200, body = ObjectList)))]
/// The object list (SDO Information).
pub async fn coe_object_list(
    State(core): State<Core>,
    Path(slave): Path<String>,
    Query(q): Query<ListQuery>,
) -> Result<Json<ObjectList>> {
    core.coe_object_list(&slave, q.list.unwrap_or(1))
        .await
        .map(|indices| Json(ObjectList { indices }))
}

#[utoipa::path(get, path = "/api/v1/slaves/{slave}/coe/od/{index}", tag = "coe",
    params(("slave" = String, Path), ("index" = String, Path)), responses((status = 200, body = ObjectView)))]
/// An object description.
pub async fn coe_object(
    State(core): State<Core>,
    Path((slave, index)): Path<(String, String)>,
) -> Result<Json<ObjectView>> {
    core.coe_object(&slave, num(&index, "index")?)
        .await
        .map(Json)
}

#[utoipa::path(get, path = "/api/v1/slaves/{slave}/coe/od/{index}/{subindex}", tag = "coe",
    params(("slave" = String, Path), ("index" = String, Path), ("subindex" = String, Path)),
    responses((status = 200, body = EntryView)))]
/// An entry description.
pub async fn coe_entry(
    State(core): State<Core>,
    Path((slave, index, subindex)): Path<(String, String, String)>,
) -> Result<Json<EntryView>> {
    core.coe_entry(&slave, num(&index, "index")?, num(&subindex, "subindex")?)
        .await
        .map(Json)
}

#[utoipa::path(get, path = "/api/v1/slaves/{slave}/soe/{drive}/{idn}", tag = "soe",
    params(("slave" = String, Path), ("drive" = String, Path), ("idn" = String, Path, description = "IDN number, e.g. 0x8064 for P-0-0100"), ElementsQuery),
    responses((status = 200, body = Data)))]
/// Reads an IDN.
pub async fn soe_read(
    State(core): State<Core>,
    Path((slave, drive, idn)): Path<(String, String, String)>,
    Query(q): Query<ElementsQuery>,
) -> Result<Json<Data>> {
    core.soe_read(
        &slave,
        num(&drive, "drive")?,
        num(&idn, "idn")?,
        q.elements.unwrap_or(0),
    )
    .await
    .map(data)
}

#[utoipa::path(put, path = "/api/v1/slaves/{slave}/soe/{drive}/{idn}", tag = "soe", request_body = Data,
    params(("slave" = String, Path), ("drive" = String, Path), ("idn" = String, Path), ElementsQuery),
    responses((status = 200, body = Done)))]
/// Writes an IDN.
pub async fn soe_write(
    State(core): State<Core>,
    Path((slave, drive, idn)): Path<(String, String, String)>,
    Query(q): Query<ElementsQuery>,
    Json(body): Json<Data>,
) -> Result<Json<Done>> {
    core.soe_write(
        &slave,
        num(&drive, "drive")?,
        num(&idn, "idn")?,
        q.elements.unwrap_or(0),
        &unhex(&body.data)?,
    )
    .await
    .map(|()| DONE)
}

#[utoipa::path(get, path = "/api/v1/slaves/{slave}/foe/{name}", tag = "foe",
    params(("slave" = String, Path), ("name" = String, Path), PasswordQuery),
    responses((status = 200, description = "The file", content_type = "application/octet-stream", body = Vec<u8>)))]
/// Reads a file.
pub async fn foe_read(
    State(core): State<Core>,
    Path((slave, name)): Path<(String, String)>,
    Query(q): Query<PasswordQuery>,
) -> Result<Vec<u8>> {
    core.foe_read(&slave, &name, q.password.unwrap_or(0), None)
        .await
}

#[utoipa::path(put, path = "/api/v1/slaves/{slave}/foe/{name}", tag = "foe",
    request_body(content = Vec<u8>, content_type = "application/octet-stream"),
    params(("slave" = String, Path), ("name" = String, Path), PasswordQuery),
    responses((status = 200, body = Done)))]
/// Writes a file (the raw request body).
pub async fn foe_write(
    State(core): State<Core>,
    Path((slave, name)): Path<(String, String)>,
    Query(q): Query<PasswordQuery>,
    body: Bytes,
) -> Result<Json<Done>> {
    core.foe_write(&slave, &name, q.password.unwrap_or(0), &body)
        .await
        .map(|()| DONE)
}

#[utoipa::path(post, path = "/api/v1/slaves/{slave}/voe", tag = "voe", request_body = VoeBody,
    params(("slave" = String, Path)), responses((status = 200, body = VoeView)))]
/// Sends one VoE message and returns the answer.
pub async fn voe(
    State(core): State<Core>,
    Path(slave): Path<String>,
    Json(body): Json<VoeBody>,
) -> Result<Json<VoeView>> {
    let answer = core
        .voe(
            &slave,
            body.vendor_id,
            body.vendor_type,
            &unhex(&body.data)?,
        )
        .await?;
    Ok(Json(VoeView {
        vendor_id: answer.vendor_id,
        vendor_type: answer.vendor_type,
        data: hex::encode(answer.data),
    }))
}

#[utoipa::path(get, path = "/api/v1/slaves/{slave}/eoe/ip", tag = "eoe",
    params(("slave" = String, Path)), responses((status = 200, body = IpView)))]
/// Reads the EoE IP parameters.
pub async fn eoe_get_ip(
    State(core): State<Core>,
    Path(slave): Path<String>,
) -> Result<Json<IpView>> {
    core.eoe_get_ip(&slave).await.map(Json)
}

#[utoipa::path(put, path = "/api/v1/slaves/{slave}/eoe/ip", tag = "eoe", request_body = IpView,
    params(("slave" = String, Path)), responses((status = 200, body = Done)))]
/// Sets the EoE IP parameters.
pub async fn eoe_set_ip(
    State(core): State<Core>,
    Path(slave): Path<String>,
    Json(body): Json<IpView>,
) -> Result<Json<Done>> {
    core.eoe_set_ip(&slave, &body).await.map(|()| DONE)
}
