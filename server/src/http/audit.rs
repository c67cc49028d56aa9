//! The REST side of the call log ([`crate::audit`]): every API call runs in a slot where
//! the authentication layer notes its caller (the core's audit lines and a failed transfer's
//! log line name it), and every failed call leaves a line at `debug` with its caller, status
//! and error. The audit line of a write is the core's ([`crate::service::admission`]).

use axum::body::{Body, to_bytes};
use axum::extract::Request;
use axum::http::StatusCode;
use axum::middleware::Next;
use axum::response::Response;

use crate::audit;

/// Largest error body copied into a log line.
const MAX_ERROR_TEXT: usize = 64 << 10;

/// The middleware; it wraps the authentication layer, so that the caller is noted in the
/// call's slot.
pub async fn record(request: Request, next: Next) -> Response {
    let operation = format!("{} {}", request.method(), request.uri().path());
    let (response, noted) = audit::Scope::default().run(next.run(request)).await;
    if response.status().is_success() {
        return response;
    }
    let (response, text) = error_text(response).await;
    log_failure(&operation, noted.caller.as_ref(), response.status(), &text);
    response
}

/// The body of a failed answer as text (a problem+json document, small), and the answer
/// rebuilt with it.
async fn error_text(response: Response) -> (Response, String) {
    let (parts, body) = response.into_parts();
    let bytes = to_bytes(body, MAX_ERROR_TEXT).await.unwrap_or_default();
    let text = String::from_utf8_lossy(&bytes).into_owned();
    (Response::from_parts(parts, Body::from(bytes)), text)
}

/// The `debug` line of a failed REST call: what failed for whom is in the log when asked
/// for, and only then.
fn log_failure(operation: &str, caller: Option<&audit::Call>, status: StatusCode, text: &str) {
    tracing::debug!(
        caller = caller.map(|c| c.caller.as_str()),
        operation,
        status = status.as_u16(),
        error = text,
        "REST call failed"
    );
}
