//! `/healthz` (the process answers) and `/readyz` (the first scan is done, not stopping).

use axum::Router;
use axum::extract::State;
use axum::http::StatusCode;
use axum::routing::get;

use crate::service::Core;

/// The health routes.
pub fn routes(core: Core) -> Router {
    Router::new()
        .route("/healthz", get(|| async { "ok\n" }))
        .route("/readyz", get(ready))
        .with_state(core)
}

async fn ready(State(core): State<Core>) -> (StatusCode, &'static str) {
    if core.ready() {
        (StatusCode::OK, "ready\n")
    } else {
        (StatusCode::SERVICE_UNAVAILABLE, "not ready\n")
    }
}
