//! `GET /api/v1/process-data/layout`: every mapped entry of the process image with its
//! place, as a control program attached to the application interface gets it
//! (docs/application.md).

use axum::Json;
use axum::extract::State;
use serde::Serialize;
use utoipa::ToSchema;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::Result;
use crate::service::Core;
use crate::service::process_data::{LayoutView, PdEntryView};

/// The routes.
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new().routes(routes!(layout))
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
