//! The REST side of the audit trail ([`crate::audit`]): around every API call that is not
//! GET or HEAD, the request body's size and digest are noted, and once the answer is known
//! the write's audit line is logged with its outcome (`done`, or the status and the error).

use std::sync::{Arc, Mutex, PoisonError};

use axum::body::{Body, to_bytes};
use axum::extract::Request;
use axum::http::Method;
use axum::middleware::Next;
use axum::response::Response;
use futures_util::StreamExt;
use sha2::{Digest, Sha256};

use crate::audit;

/// Largest error body copied into an audit line.
const MAX_ERROR_TEXT: usize = 64 << 10;

/// The middleware; it wraps the authentication layer so that the write check can note the
/// caller in the call's slot. The body is hashed as the handler reads it, never buffered
/// here: a caller the authentication layer refuses costs no body read at all.
pub async fn record(request: Request, next: Next) -> Response {
    if matches!(*request.method(), Method::GET | Method::HEAD) {
        return next.run(request).await;
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
    let (response, write) = audit::scoped(async {
        let response = next.run(request).await;
        let (hash, len) = std::mem::take(&mut *seen.lock().unwrap_or_else(PoisonError::into_inner));
        if len > 0 {
            audit::note_described(audit::describe_hashed(len, hash));
        }
        response
    })
    .await;
    // Only a write the authentication layer let through was noted with a caller.
    let Some(write) = write.filter(|w| !w.caller.is_empty()) else {
        return response;
    };
    if response.status().is_success() {
        audit::outcome(&write, Ok(()));
        return response;
    }
    let status = response.status();
    let (parts, body) = response.into_parts();
    let text = to_bytes(body, MAX_ERROR_TEXT).await.unwrap_or_default();
    audit::outcome(
        &write,
        Err(&format!("{status} {}", String::from_utf8_lossy(&text))),
    );
    Response::from_parts(parts, Body::from(text))
}
