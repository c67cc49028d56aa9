//! REST handlers under `/api/v1`: the same operations as gRPC, one core call each, one file
//! per resource as in `grpc/` (`slaves`, `events` (the history and the live stream), `bus`
//! (counters and the caller's role), `config`,
//! `registers`, `sii`, `coe`, `soe`, `foe`, `voe`, `eoe`, `capture`, `domains`, `process_data`,
//! `log_filter`). Binary values are hex strings;
//! numbers in paths are decimal or `0x` hex; slave
//! names use the common syntax (`3`, `%231004` for `#1004`, `@0x777`).
//!
//! Each route is declared once, in its handler's `#[utoipa::path]` (method and path
//! relative to `/api/v1`): the router is built from those annotations, so the OpenAPI
//! document lists exactly the routes served.

pub mod bus;
pub mod capture;
pub mod coe;
pub mod config;
pub mod domains;
pub mod eoe;
pub mod events;
pub mod foe;
pub mod log_filter;
pub mod process_data;
pub mod registers;
pub mod sii;
pub mod slaves;
pub mod soe;
pub mod voe;

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;
use utoipa_axum::router::OpenApiRouter;

use crate::http::extract::Json;
use crate::input::value::parse_number;
use crate::service::{ApiError, Core};

type Result<T> = std::result::Result<T, ApiError>;

fn num<T: TryFrom<u64>>(text: &str, field: &str) -> Result<T> {
    parse_number(text, field)
}

fn unhex(text: &str) -> Result<Vec<u8>> {
    hex::decode(text.trim()).map_err(|_| ApiError::invalid_field("data", "data must be hex"))
}

/// Bytes as hex.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Data {
    /// The bytes, hex (`"0100e0"`).
    pub data: String,
}

fn data(bytes: Vec<u8>) -> Json<Data> {
    Json(Data {
        data: hex::encode(bytes),
    })
}

/// A done write.
#[derive(Debug, Serialize, ToSchema)]
pub struct Done {
    /// Always true.
    pub ok: bool,
}

const DONE: Json<Done> = Json(Done { ok: true });

/// The routes that run under the request time limit: every resource's but FoE's.
pub fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new()
        .merge(slaves::routes())
        .merge(bus::routes())
        .merge(registers::routes())
        .merge(sii::routes())
        .merge(coe::routes())
        .merge(soe::routes())
        .merge(voe::routes())
        .merge(eoe::routes())
        .merge(config::routes())
        .merge(domains::routes())
        .merge(process_data::routes())
        .merge(log_filter::routes())
}

/// The routes of transfers that take as long as the slave needs (no request time limit:
/// their deadlines follow their progress).
pub fn transfer_routes() -> OpenApiRouter<Core> {
    foe::routes()
}

/// The routes that stream or run for as long as asked (no request time limit): events and
/// captures.
pub fn stream_routes() -> OpenApiRouter<Core> {
    events::routes()
        .merge(capture::routes())
        .merge(process_data::stream_routes())
}
