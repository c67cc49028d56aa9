//! The HTTP side: REST under `/api/v1` (with its OpenAPI document), `/metrics`,
//! `/healthz`, `/readyz`.
//!
//! Files: `rest` (handlers), `gateway` (the gateway's handlers), `openapi`, `error`
//! (errors as JSON), `auth` (tokens), `health`, `sim` (the simulator's debug route,
//! `--simulate` only).

pub mod auth;
pub mod error;
pub mod gateway;
pub mod health;
pub mod openapi;
pub mod rest;
pub mod sim;

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::extract::DefaultBodyLimit;
use axum::http::{StatusCode, header};
use axum::routing::{get, post, put};
use tower_http::timeout::TimeoutLayer;

use crate::metrics;
use crate::security::Tokens;
use crate::service::Core;
use crate::sim_hooks::SimHooks;

/// Largest request body (an FoE file).
pub const MAX_BODY: usize = 16 << 20;
/// Time limit of one request (the event stream excepted).
pub const TIMEOUT: Duration = Duration::from_secs(60);

/// Every HTTP route: the API over `core`, the metrics from `core` and `metrics`, and the
/// simulator's debug route when `sim` hooks are given (`--simulate`).
pub fn router(
    core: Core,
    tokens: Tokens,
    metrics: Arc<metrics::Store>,
    sim: Option<SimHooks>,
) -> Router {
    use rest::*;
    let api = Router::new()
        .route("/slaves", get(list_slaves))
        .route("/slaves/{slave}", get(get_slave))
        .route("/slaves/{slave}/state", put(request_state))
        .route("/rescan", post(rescan))
        .route(
            "/slaves/{slave}/registers/{address}",
            get(read_register).put(write_register),
        )
        .route("/slaves/{slave}/sii", get(read_sii))
        .route("/slaves/{slave}/sii/{word}", put(write_sii))
        .route("/slaves/{slave}/alias", put(set_alias))
        .route(
            "/slaves/{slave}/coe/sdo/{index}/{subindex}",
            get(coe_upload).put(coe_download),
        )
        .route("/slaves/{slave}/coe/od", get(coe_object_list))
        .route("/slaves/{slave}/coe/od/{index}", get(coe_object))
        .route("/slaves/{slave}/coe/od/{index}/{subindex}", get(coe_entry))
        .route(
            "/slaves/{slave}/soe/{drive}/{idn}",
            get(soe_read).put(soe_write),
        )
        .route("/slaves/{slave}/foe/{name}", get(foe_read).put(foe_write))
        .route("/slaves/{slave}/voe", post(voe))
        .route("/slaves/{slave}/eoe/ip", get(eoe_get_ip).put(eoe_set_ip))
        .route("/gateway", get(gateway::get_gateway))
        .route("/gateway/start", post(gateway::start_gateway))
        .route("/gateway/stop", post(gateway::stop_gateway))
        .merge(sim::routes(core.clone(), sim))
        .layer(TimeoutLayer::with_status_code(
            StatusCode::GATEWAY_TIMEOUT,
            TIMEOUT,
        ))
        .route("/events", get(events))
        .layer(axum::middleware::from_fn_with_state(
            tokens,
            auth::authenticate,
        ))
        .layer(DefaultBodyLimit::max(MAX_BODY))
        .with_state(core.clone());
    Router::new()
        .nest("/api/v1", api)
        .route(
            "/api/v1/openapi.json",
            get(|| async {
                (
                    [(header::CONTENT_TYPE, "application/json")],
                    openapi::json(),
                )
            }),
        )
        .route(
            "/metrics",
            get(render_metrics).with_state(MetricsState {
                core: core.clone(),
                store: metrics,
            }),
        )
        .merge(health::routes(core))
}

/// What `/metrics` reads: the master through the core, and what ecatd recorded itself.
#[derive(Clone)]
struct MetricsState {
    core: Core,
    store: Arc<metrics::Store>,
}

async fn render_metrics(
    axum::extract::State(MetricsState { core, store }): axum::extract::State<MetricsState>,
) -> axum::response::Response {
    use axum::response::IntoResponse;
    match metrics::render(&core, &store) {
        Ok(text) => ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text).into_response(),
        Err(err) => (StatusCode::INTERNAL_SERVER_ERROR, err).into_response(),
    }
}

/// Serves `app` (the [`router`]) over TLS on `listener` until `shutdown` completes.
pub async fn serve_tls(
    app: Router,
    listener: crate::tls::TlsListener,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), String> {
    axum::serve(listener, app)
        .with_graceful_shutdown(shutdown)
        .await
        .map_err(|err| format!("HTTPS server: {err}"))
}

/// Serves `app` (the [`router`]) on `listener` until `shutdown` completes.
pub async fn serve(
    app: Router,
    listener: tokio::net::TcpListener,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), String> {
    use axum::serve::ListenerExt;
    // Nagle off on every accepted connection (axum leaves it on): a response written in
    // more than one piece must not wait for the client's ACK.
    let listener = listener.tap_io(|tcp| {
        if let Err(err) = tcp.set_nodelay(true) {
            tracing::debug!(%err, "cannot set TCP_NODELAY");
        }
    });
    axum::serve(listener, app)
        .with_graceful_shutdown(shutdown)
        .await
        .map_err(|err| format!("HTTP server: {err}"))
}
