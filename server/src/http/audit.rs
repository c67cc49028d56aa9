//! The REST side of the audit trail ([`crate::audit`]): around every API call that is not
//! GET or HEAD, the request body's size and digest are noted, and once the answer is known
//! the write's audit line is logged with its outcome (`done`, or the status and the error).

use std::sync::{Arc, Mutex, PoisonError};

use axum::body::{Body, to_bytes};
use axum::extract::Request;
use axum::http::{Method, StatusCode};
use axum::middleware::Next;
use axum::response::Response;
use futures_util::StreamExt;
use sha2::{Digest, Sha256};

use crate::audit;

/// Largest error body copied into an audit line.
const MAX_ERROR_TEXT: usize = 64 << 10;

/// The middleware; it wraps the authentication layer so that the write check can note the
/// caller in the call's slot. The body is hashed as the handler reads it, never buffered
/// here: a caller the authentication layer refuses costs no body read at all. Every failed
/// call leaves a line at `debug` with its caller and error.
pub async fn record(request: Request, next: Next) -> Response {
    let operation = format!("{} {}", request.method(), request.uri().path());
    if matches!(*request.method(), Method::GET | Method::HEAD) {
        let (response, noted) = audit::Scope::default().run(next.run(request)).await;
        if response.status().is_success() {
            return response;
        }
        let (response, text) = error_text(response).await;
        log_failure(&operation, noted.caller.as_ref(), response.status(), &text);
        return response;
    }
    let (parts, body) = request.into_parts();
    let seen = Arc::new(Mutex::new((Sha256::new(), 0usize)));
    let tap = Arc::clone(&seen);
    let body = Body::from_stream(body.into_data_stream().map(move |chunk| {
        if let Ok(bytes) = &chunk {
            let mut seen = tap.lock().unwrap_or_else(PoisonError::into_inner);
            seen.0.update(bytes);
            seen.1 += bytes.len();
        }
        chunk
    }));
    let request = Request::from_parts(parts, body);
    let (response, noted) = audit::Scope::default()
        .run(async {
            let response = next.run(request).await;
            let (hash, len) =
                std::mem::take(&mut *seen.lock().unwrap_or_else(PoisonError::into_inner));
            if len > 0 {
                audit::note_described(audit::describe_hashed(len, hash));
            }
            response
        })
        .await;
    if response.status().is_success() {
        // Only a write the authentication layer let through was noted with a caller.
        if let Some(write) = noted.write.filter(|w| !w.caller.is_empty()) {
            audit::outcome(&write, Ok(()));
        }
        return response;
    }
    let (response, text) = error_text(response).await;
    let status = response.status();
    log_failure(&operation, noted.caller.as_ref(), status, &text);
    if let Some(write) = noted.write.filter(|w| !w.caller.is_empty()) {
        audit::outcome(&write, Err(&format!("{status} {text}")));
    }
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
