//! The HTTP side: REST under `/api/v1` (with its OpenAPI document), `/metrics`,
//! `/healthz`, `/readyz`.
//!
//! Files: `rest` (handlers, one file per resource), `gateway` (the gateway's handlers),
//! `openapi` (the document's frame), `error` (errors as JSON), `extract` (the handlers'
//! extractors, refusing as JSON), `unknown` (unknown routes, methods and query parameters),
//! `deadline` (the request time limit), `auth` (tokens), `health`,
//! `sim` (the simulator's debug route, `--simulate` only), `web` (the dashboard at `/`),
//! `body_limit` (the request body limit), `connections` (`[limits]`: connection caps and
//! deadlines, shared with gRPC) and `serve` (the accept loop).

pub mod audit;
pub mod auth;
pub mod body_limit;
pub mod browser;
pub mod deadline;
pub mod error;
pub mod extract;
pub mod gateway;
pub mod health;
pub mod openapi;
pub mod rest;
mod serve;
pub mod sim;
#[cfg(test)]
mod test_support;
pub mod unknown;
pub mod web;

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::extract::DefaultBodyLimit;
use axum::http::{StatusCode, header};
use axum::routing::get;
use utoipa::OpenApi;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use crate::config::limits::LimitSettings;
use crate::metrics;
use crate::security::Tokens;
use crate::service::Core;
use crate::sim_hooks::SimHooks;

/// Largest request body (an FoE file); a larger one gets 413 before it is read
/// ([`body_limit`]).
pub const MAX_BODY: usize = 16 << 20;
/// Time limit of one request (the event stream and FoE transfers excepted).
pub const TIMEOUT: Duration = Duration::from_secs(60);

/// Every HTTP route: the API over `core`, the metrics from `core` and `metrics`, and the
/// simulator's debug route when `sim` hooks are given (`--simulate`).
///
/// The API's routes come from the handlers' `#[utoipa::path]` annotations (`rest` and
/// `gateway`), and the OpenAPI document served at `/api/v1/openapi.json` is built from the
/// same router: a route cannot be served undocumented, nor documented unserved.
pub fn router(
    core: Core,
    tokens: Tokens,
    metrics: Arc<metrics::Store>,
    sim: Option<SimHooks>,
    metrics_token: bool,
) -> Router {
    let api = OpenApiRouter::new()
        .merge(rest::routes())
        .routes(routes!(gateway::get_gateway))
        .routes(routes!(gateway::start_gateway))
        .routes(routes!(gateway::stop_gateway))
        // Not documented: it does not exist on a real segment.
        .merge(OpenApiRouter::from(sim::routes(core.clone(), sim)))
        .layer(axum::middleware::from_fn_with_state(
            TIMEOUT,
            deadline::limit,
        ))
        .merge(rest::transfer_routes())
        .merge(rest::stream_routes())
        .layer(axum::middleware::from_fn_with_state(
            tokens.clone(),
            auth::authenticate,
        ))
        .layer(axum::middleware::from_fn(audit::record))
        .layer(DefaultBodyLimit::max(MAX_BODY))
        .with_state(core.clone());
    let (router, document) = OpenApiRouter::with_openapi(openapi::ApiDoc::openapi())
        .nest("/api/v1", api)
        .split_for_parts();
    let names = Arc::new(unknown::QueryNames::from_document(&document, ""));
    let document = openapi::json(&document);
    router
        .layer(axum::middleware::from_fn_with_state(
            names,
            unknown::known_query,
        ))
        .route(
            "/api/v1/openapi.json",
            get(|| async { ([(header::CONTENT_TYPE, "application/json")], document) }),
        )
        .route(
            "/metrics",
            get(render_metrics)
                .with_state(MetricsState {
                    core: core.clone(),
                    store: metrics,
                })
                .layer(axum::middleware::from_fn_with_state(
                    MetricsGuard {
                        tokens,
                        required: metrics_token,
                    },
                    metrics_guard,
                )),
        )
        .merge(health::routes(core))
        .merge(web::routes())
        .fallback(unknown::route)
        .method_not_allowed_fallback(unknown::method)
        // Outside every other layer, the audit's included: see `body_limit`.
        .layer(axum::middleware::from_fn_with_state(
            MAX_BODY,
            body_limit::enforce,
        ))
}

/// Whether `/metrics` needs a token (`metrics_token`): then any configured token (read
/// role or more) opens it, as for the API's reads; without tokens it stays open.
#[derive(Clone)]
struct MetricsGuard {
    tokens: Tokens,
    required: bool,
}

async fn metrics_guard(
    axum::extract::State(guard): axum::extract::State<MetricsGuard>,
    request: axum::extract::Request,
    next: axum::middleware::Next,
) -> axum::response::Response {
    use axum::response::IntoResponse;
    if guard.required {
        let header = request
            .headers()
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok());
        if let Err(err) = guard.tokens.authenticate(header) {
            return err.into_response();
        }
    }
    next.run(request).await
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

/// Serves `app` (the [`router`]) over TLS on `listener` under `limits` (the connections
/// counted in `stats`) until `shutdown` completes.
pub async fn serve_tls(
    app: Router,
    listener: crate::tls::TlsListener,
    limits: LimitSettings,
    stats: Arc<crate::connections::ConnectionStats>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), String> {
    let app = with_body_timeout(app, &limits);
    serve::serve(app, listener, &limits, stats, serve::refuse_tls, shutdown).await;
    Ok(())
}

/// Serves `app` (the [`router`]) on `listener` under `limits` (the connections counted in
/// `stats`) until `shutdown` completes.
pub async fn serve(
    app: Router,
    listener: tokio::net::TcpListener,
    limits: LimitSettings,
    stats: Arc<crate::connections::ConnectionStats>,
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
    let app = with_body_timeout(app, &limits);
    serve::serve(app, listener, &limits, stats, serve::refuse_tcp, shutdown).await;
    Ok(())
}

/// A request body that stops arriving for `idle_timeout` fails (the handler answers 400):
/// while a request is in flight its connection is not idle, so without this a client could
/// hold an FoE upload route (which has no request time limit) open for ever by starting a
/// body and sending no more of it.
fn with_body_timeout(app: Router, limits: &LimitSettings) -> Router {
    app.layer(tower_http::timeout::RequestBodyTimeoutLayer::new(
        limits.idle_timeout,
    ))
}
