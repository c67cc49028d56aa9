//! Process data over REST: the layout a control program attaches to
//! (docs/application.md), the values of the last completed cycle decoded by type, forcing
//! outputs (write role, audited; refused while an application owns the outputs unless
//! `override`), and a server-sent stream of changed values. Values come from the cycle's
//! snapshot: reading them sends no frame.

use axum::extract::State;
use axum::response::sse::{Event, KeepAlive, Sse};
use futures_util::Stream;
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::{DONE, Done, Result, num};
use crate::http::extract::{Admit, Json, Path, Query};
use crate::service::pd_stream::PdChanges;
use crate::service::process_data::{
    ForceView, LayoutView, PdEntryView, PdInput, PdValue, PdValueView, ProcessDataView,
};
use crate::service::{ApiError, Core, op, parse_name};

/// The routes under the request time limit.
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new()
        .routes(routes!(layout))
        .routes(routes!(values))
        .routes(routes!(slave_values))
        .routes(routes!(force, release))
        .routes(routes!(forced))
}

/// The stream (no request time limit).
pub(super) fn stream_routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new().routes(routes!(stream))
}

/// One mapped entry.
#[derive(Debug, Serialize, ToSchema)]
pub struct PdEntryJson {
    /// Ring position of its slave.
    pub slave: u16,
    /// The slave's station address.
    pub station: u16,
    /// The PDO mapping it.
    pub pdo: u16,
    /// Object index.
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// Its name (from the SII).
    pub name: String,
    /// Its CoE data type (`UNSIGNED16`; empty when not known).
    #[serde(rename = "type")]
    pub data_type: String,
    /// First bit in the image (bit 0 = least significant bit of byte 0).
    pub bit_offset: u32,
    /// Bits it takes.
    pub bit_length: u16,
    /// `in` (slave to master) or `out`.
    pub direction: String,
}

impl From<PdEntryView> for PdEntryJson {
    fn from(e: PdEntryView) -> PdEntryJson {
        PdEntryJson {
            slave: e.slave,
            station: e.station,
            pdo: e.pdo,
            index: e.index,
            subindex: e.subindex,
            name: e.name,
            data_type: e.data_type,
            bit_offset: e.bit_offset,
            bit_length: e.bit_length,
            direction: e.direction.into(),
        }
    }
}

/// The process image's layout.
#[derive(Debug, Serialize, ToSchema)]
pub struct LayoutJson {
    /// The application interface's layout generation (0 when it does not serve); a scan
    /// that changes the image starts a new one.
    pub generation: u32,
    /// Bytes of the image.
    pub image_len: usize,
    /// The cycle period in ns.
    pub period_ns: u64,
    /// Every entry, slave by slave.
    pub entries: Vec<PdEntryJson>,
}

impl From<LayoutView> for LayoutJson {
    fn from(v: LayoutView) -> LayoutJson {
        LayoutJson {
            generation: v.generation,
            image_len: v.image_len,
            period_ns: v.period_ns,
            entries: v.entries.into_iter().map(PdEntryJson::from).collect(),
        }
    }
}

/// The process image's layout.
#[utoipa::path(get, path = "/process-data/layout", tag = "process-data",
    responses((status = 200, body = LayoutJson)))]
async fn layout(State(core): State<Core>) -> Result<Json<LayoutJson>> {
    Ok(Json(core.process_data_layout(None)?.into()))
}

/// `?raw=true` adds each value's bytes.
#[derive(Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct ValuesQuery {
    /// Add each entry's bytes (hex).
    #[serde(default)]
    pub raw: bool,
}

/// One entry with its value.
#[derive(Debug, Serialize, ToSchema)]
pub struct PdValueJson {
    /// The entry.
    #[serde(flatten)]
    pub entry: PdEntryJson,
    /// Its value: an integer, a boolean (bits), a number (REAL32/64) or hex (others).
    #[schema(value_type = Object)]
    pub value: serde_json::Value,
    /// Its bytes, hex (with `?raw=true`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub raw: Option<String>,
    /// Who forced it, when it is forced.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub forced_by: Option<String>,
}

/// The values of one completed cycle.
#[derive(Debug, Serialize, ToSchema)]
pub struct ProcessDataJson {
    /// The cycle the values belong to.
    pub cycle: u64,
    /// Its working counter.
    pub wkc: u16,
    /// The working counter it should have had.
    pub expected_wkc: u16,
    /// Every entry with its value.
    pub entries: Vec<PdValueJson>,
}

/// A value as JSON.
pub fn value_json(value: &PdValue) -> serde_json::Value {
    match value {
        PdValue::Bool(b) => (*b).into(),
        PdValue::Int(i) => (*i).into(),
        PdValue::Uint(u) => (*u).into(),
        PdValue::Real(r) => {
            serde_json::Number::from_f64(*r).map_or(serde_json::Value::Null, Into::into)
        }
        PdValue::Hex(h) => h.clone().into(),
    }
}

fn value_view_json(v: PdValueView, raw: bool) -> PdValueJson {
    PdValueJson {
        value: value_json(&v.value),
        raw: raw.then(|| hex::encode(&v.raw)),
        forced_by: v.forced_by,
        entry: v.entry.into(),
    }
}

fn data_json(view: ProcessDataView, raw: bool) -> ProcessDataJson {
    ProcessDataJson {
        cycle: view.cycle,
        wkc: view.wkc,
        expected_wkc: view.expected_wkc,
        entries: view
            .values
            .into_iter()
            .map(|v| value_view_json(v, raw))
            .collect(),
    }
}

/// Every entry's value in the last completed cycle.
#[utoipa::path(get, path = "/process-data", tag = "process-data", params(ValuesQuery),
    responses((status = 200, body = ProcessDataJson)))]
async fn values(
    State(core): State<Core>,
    Query(query): Query<ValuesQuery>,
) -> Result<Json<ProcessDataJson>> {
    Ok(Json(data_json(core.process_data(None)?, query.raw)))
}

/// One slave's entries and values in the last completed cycle.
#[utoipa::path(get, path = "/slaves/{slave}/process-data", tag = "process-data",
    params(("slave" = String, Path), ValuesQuery),
    responses((status = 200, body = ProcessDataJson), (status = 404, body = crate::http::error::ErrorBody)))]
async fn slave_values(
    State(core): State<Core>,
    Path(slave): Path<String>,
    Query(query): Query<ValuesQuery>,
) -> Result<Json<ProcessDataJson>> {
    Ok(Json(data_json(
        core.process_data(Some(parse_name(&slave)?))?,
        query.raw,
    )))
}

/// A force: the value, and whether to write over an application that owns the outputs.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ForceBody {
    /// The value: an integer, a boolean, or a number for REAL32/REAL64 entries.
    #[schema(value_type = Object)]
    pub value: serde_json::Value,
    /// Write over the outputs of an application that owns them (audited as such).
    #[serde(default, rename = "override")]
    pub over_owner: bool,
}

/// A forced output.
#[derive(Debug, Serialize, ToSchema)]
pub struct ForceJson {
    /// The entry.
    #[serde(flatten)]
    pub entry: PdEntryJson,
    /// The forced value.
    #[schema(value_type = Object)]
    pub value: serde_json::Value,
    /// Who forced it (token name).
    pub forced_by: String,
    /// Whether it was forced over an application's outputs.
    #[serde(rename = "override")]
    pub over_owner: bool,
    /// When, seconds since the Unix epoch.
    pub since: u64,
}

impl From<ForceView> for ForceJson {
    fn from(f: ForceView) -> ForceJson {
        ForceJson {
            value: value_json(&f.value),
            forced_by: f.by,
            over_owner: f.over_owner,
            since: f.since,
            entry: f.entry.into(),
        }
    }
}

pub(crate) fn input(value: &serde_json::Value) -> Result<PdInput> {
    match value {
        serde_json::Value::Bool(b) => Ok(PdInput::Int(i64::from(*b))),
        serde_json::Value::Number(n) => n
            .as_i64()
            .map(PdInput::Int)
            .or_else(|| n.as_f64().map(PdInput::Real))
            .ok_or_else(|| ApiError::invalid_field("value", format!("{n} is out of range"))),
        other => Err(ApiError::invalid_field(
            "value",
            format!("value must be a number or a boolean, not {other}"),
        )),
    }
}

/// Forces an output to a value from the next cycle on.
#[utoipa::path(put, path = "/slaves/{slave}/process-data/{index}/{subindex}", tag = "process-data",
    request_body = ForceBody,
    params(("slave" = String, Path), ("index" = String, Path), ("subindex" = String, Path)),
    responses((status = 200, body = ForceJson), (status = 409, body = crate::http::error::ErrorBody)))]
async fn force(
    Admit(ticket, _): Admit<op::ForceOutput>,
    State(core): State<Core>,
    Path((slave, index, subindex)): Path<(String, String, String)>,
    Json(body): Json<ForceBody>,
) -> Result<Json<ForceJson>> {
    let index: u16 = num(&index, "index")?;
    let subindex: u8 = num(&subindex, "subindex")?;
    let value = input(&body.value)?;
    let view = core.force_output(
        ticket,
        parse_name(&slave)?,
        index,
        subindex,
        value,
        body.over_owner,
    )?;
    Ok(Json(view.into()))
}

/// Releases a forced output.
#[utoipa::path(delete, path = "/slaves/{slave}/process-data/{index}/{subindex}", tag = "process-data",
    params(("slave" = String, Path), ("index" = String, Path), ("subindex" = String, Path)),
    responses((status = 200, body = Done), (status = 404, body = crate::http::error::ErrorBody)))]
async fn release(
    Admit(ticket, _): Admit<op::ReleaseOutput>,
    State(core): State<Core>,
    Path((slave, index, subindex)): Path<(String, String, String)>,
) -> Result<Json<Done>> {
    let index: u16 = num(&index, "index")?;
    let subindex: u8 = num(&subindex, "subindex")?;
    core.release_output(ticket, parse_name(&slave)?, index, subindex)?;
    Ok(DONE)
}

/// The forced outputs.
#[utoipa::path(get, path = "/process-data/forced", tag = "process-data",
    responses((status = 200, body = [ForceJson])))]
async fn forced(State(core): State<Core>) -> Json<Vec<ForceJson>> {
    Json(
        core.forced_outputs()
            .into_iter()
            .map(ForceJson::from)
            .collect(),
    )
}

/// `?interval=50ms` (default 100ms; not below the cycle), `slave` to follow one slave.
#[derive(Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct StreamQuery {
    /// How often changes are sent (`50ms`, `1s`); not below the cycle period.
    pub interval: Option<String>,
    /// Only this slave's entries.
    pub slave: Option<String>,
    /// Add each value's bytes (hex).
    #[serde(default)]
    pub raw: bool,
}

/// The values that changed, as server-sent events (`event: values`, `id`: the cycle): the
/// first event has every entry, later ones only the entries whose value changed since the
/// last event. A client that reconnects (`Last-Event-ID`) gets every entry again, so it
/// misses no state.
#[utoipa::path(get, path = "/process-data/stream", tag = "process-data", params(StreamQuery),
    responses((status = 200, description = "Server-sent events, one ProcessDataJson of the changed entries each", content_type = "text/event-stream", body = ProcessDataJson),
              (status = 400, body = crate::http::error::ErrorBody)))]
async fn stream(
    State(core): State<Core>,
    Query(query): Query<StreamQuery>,
) -> Result<Sse<impl Stream<Item = std::result::Result<Event, std::convert::Infallible>>>> {
    let requested = query
        .interval
        .as_deref()
        .map(|text| {
            humantime::parse_duration(text).map_err(|err| {
                ApiError::invalid_field("interval", format!("interval {text:?}: {err}"))
            })
        })
        .transpose()?;
    let interval = core.pd_stream_interval(requested)?;
    let slave = query.slave.as_deref().map(parse_name).transpose()?;
    // The slave must exist now; the stream then follows it.
    core.process_data(slave)?;
    let raw = query.raw;
    let ticks = tokio_stream::wrappers::IntervalStream::new({
        let mut ticks = tokio::time::interval(interval);
        ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        ticks
    });
    let mut changes = PdChanges::default();
    let source = core.clone();
    let stream = futures_util::StreamExt::filter_map(ticks, move |_| {
        let event = source
            .process_data(slave)
            .ok()
            .and_then(|view| changes.next(view))
            .map(|changed| event(changed, raw));
        async move { event.map(Ok) }
    });
    // Ends at shutdown, so that the server's graceful stop does not wait for it.
    let stream = futures_util::StreamExt::take_until(stream, core.stopped());
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}

/// The event of the entries that changed (`id`: the cycle).
fn event(changed: ProcessDataView, raw: bool) -> Event {
    let json = data_json(changed, raw);
    Event::default()
        .event("values")
        .id(json.cycle.to_string())
        .json_data(&json)
        .unwrap_or_else(|_| Event::default().comment("unencodable"))
}
