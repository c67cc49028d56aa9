//! `GET /config`: the effective configuration (IgH's `ethercat config`).

use axum::extract::State;
use serde::Serialize;
use utoipa::ToSchema;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use crate::http::extract::Json;
use crate::service::Core;

pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new().routes(routes!(get_config))
}

/// The effective configuration.
#[derive(Debug, Serialize, ToSchema)]
pub struct ConfigView {
    /// The file, the environment and the flags together, the slaves and cycle of an ENI
    /// file included, as TOML in the configuration file's keys (token secrets masked).
    pub toml: String,
    /// The ENI file the slaves came from; empty without one.
    pub eni: String,
}

/// The configuration ecatd runs with.
#[utoipa::path(get, path = "/config", responses((status = 200, body = ConfigView)))]
pub async fn get_config(State(core): State<Core>) -> Json<ConfigView> {
    let (toml, eni) = core.effective_config();
    Json(ConfigView { toml, eni })
}
