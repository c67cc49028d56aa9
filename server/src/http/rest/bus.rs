//! The bus's counters and timing, and who the caller is (the dashboard hides write controls
//! from a read token).

use axum::Extension;
use axum::extract::State;
use serde::Serialize;
use utoipa::ToSchema;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use crate::http::extract::Json;
use crate::security::{Caller, Role};
use crate::service::{BusView, Core};

/// The routes, each declared once (method and path come from the handler's annotation).
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new()
        .routes(routes!(get_bus))
        .routes(routes!(get_session))
}

/// The caller as the token layer saw it.
#[derive(Debug, Serialize, ToSchema)]
pub struct SessionView {
    /// Token name (`anonymous` when ecatd has no tokens).
    pub caller: String,
    /// `read` or `write`.
    pub role: String,
}

#[utoipa::path(get, path = "/bus", tag = "bus", responses((status = 200, body = BusView)))]
/// Frame and cycle counters, working counter, cycle time and jitter since start-up.
pub async fn get_bus(State(core): State<Core>) -> Json<BusView> {
    Json(core.bus())
}

#[utoipa::path(get, path = "/session", tag = "bus", responses((status = 200, body = SessionView)))]
/// Who the token is and what it may do.
pub async fn get_session(Extension(caller): Extension<Caller>) -> Json<SessionView> {
    let role = match caller.role {
        Role::Read => "read",
        Role::Write => "write",
    };
    Json(SessionView {
        caller: caller.name,
        role: role.into(),
    })
}
