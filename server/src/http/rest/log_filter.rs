//! `GET`/`PUT /api/v1/log-filter`: ecatd's runtime log filter (`ecat debug`).

use axum::extract::State;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::Result;
use crate::http::extract::Admit;
use crate::http::extract::Json;
use crate::service::Core;
use crate::service::op;

/// The routes.
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new().routes(routes!(get_log_filter, set_log_filter))
}

/// A log filter in tracing's `EnvFilter` syntax.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LogFilter {
    /// `"info"`, `"debug"`, `"info,master_core::bus=trace"`.
    pub filter: String,
}

#[utoipa::path(get, path = "/log-filter", tag = "bus", responses((status = 200, body = LogFilter)))]
/// The log filter in force.
pub async fn get_log_filter(State(core): State<Core>) -> Result<Json<LogFilter>> {
    Ok(Json(LogFilter {
        filter: core.log_filter()?,
    }))
}

#[utoipa::path(put, path = "/log-filter", tag = "bus", request_body = LogFilter,
    responses((status = 200, body = LogFilter)))]
/// Replaces the log filter; a bad one is refused and the old one stays.
pub async fn set_log_filter(
    Admit(ticket, _): Admit<op::SetLogFilter>,
    State(core): State<Core>,
    Json(body): Json<LogFilter>,
) -> Result<Json<LogFilter>> {
    Ok(Json(LogFilter {
        filter: core.set_log_filter(ticket, &body.filter)?,
    }))
}
