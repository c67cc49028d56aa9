//! The HTTP side: REST under `/api/v1`, `/metrics`, `/healthz`, `/readyz`.

pub mod health;

use std::future::Future;

use axum::Router;

use crate::core::Core;
use crate::security::Tokens;

/// Every HTTP route.
pub fn router(core: Core, _tokens: Tokens) -> Router {
    Router::new().merge(health::routes(core))
}

/// Serves the HTTP routes on `listener` until `shutdown` completes.
pub async fn serve(
    core: Core,
    tokens: Tokens,
    listener: tokio::net::TcpListener,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), String> {
    axum::serve(listener, router(core, tokens))
        .with_graceful_shutdown(shutdown)
        .await
        .map_err(|err| format!("HTTP server: {err}"))
}
