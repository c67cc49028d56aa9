//! `GET /api/v1/domains`: the process image by domain (slave group), as `ecat domains` and
//! `ecat data` show it.

use axum::extract::State;
use serde::Serialize;
use utoipa::ToSchema;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::Result;
use crate::http::extract::Json;
use crate::service::Core;
use crate::service::domains::DomainView;

/// The routes.
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new().routes(routes!(list_domains))
}

/// One mapped entry.
#[derive(Debug, Serialize, ToSchema)]
pub struct DomainEntryJson {
    /// Ring position of its slave.
    pub position: u16,
    /// The PDO mapping it.
    pub pdo_index: u16,
    /// Object index.
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// Bits it takes.
    pub bit_length: u8,
    /// First bit from the start of the domain.
    pub bit_offset: u32,
    /// An output (master to slave).
    pub output: bool,
    /// Its name.
    pub name: String,
}

/// One domain (slave group).
#[derive(Debug, Serialize, ToSchema)]
pub struct DomainJson {
    /// The group's number (0: the default group).
    pub index: usize,
    /// Logical address of its share of the image.
    pub logical_address: u32,
    /// Bytes of its share.
    pub size: usize,
    /// The working counter its exchange should have.
    pub expected_wkc: u16,
    /// The last working counter.
    pub last_wkc: u16,
    /// Exchanges with a wrong working counter.
    pub wrong_wkc: u64,
    /// Its period in ns (0: every cycle).
    pub period_ns: u64,
    /// Ring positions of its slaves.
    pub slaves: Vec<u16>,
    /// Its entries.
    pub entries: Vec<DomainEntryJson>,
    /// Its share of the image, hex.
    pub data: String,
}

impl From<DomainView> for DomainJson {
    fn from(d: DomainView) -> DomainJson {
        DomainJson {
            index: d.index,
            logical_address: d.logical,
            size: d.data.len(),
            expected_wkc: d.expected_wkc,
            last_wkc: d.last_wkc,
            wrong_wkc: d.wrong_wkc,
            period_ns: d.period_ns,
            slaves: d.slaves,
            entries: d
                .entries
                .into_iter()
                .map(|e| DomainEntryJson {
                    position: e.position,
                    pdo_index: e.pdo,
                    index: e.index,
                    subindex: e.subindex,
                    bit_length: e.bit_length,
                    bit_offset: e.bit_offset,
                    output: e.output,
                    name: e.name,
                })
                .collect(),
            data: hex::encode(d.data),
        }
    }
}

#[utoipa::path(get, path = "/domains", tag = "bus", responses((status = 200, body = Vec<DomainJson>)))]
/// Every domain (slave group) with its logical address, size, working counters, slaves,
/// entries and its share of the process image.
pub async fn list_domains(State(core): State<Core>) -> Result<Json<Vec<DomainJson>>> {
    Ok(Json(
        core.domains()?.into_iter().map(DomainJson::from).collect(),
    ))
}
