//! The REST side of the audit trail ([`crate::audit`]): around every API call that is not
//! GET or HEAD, the request body's size and digest are noted, and once the answer is known
//! the write's audit line is logged with its outcome (`done`, or the status and the error).

use axum::body::{Body, to_bytes};
use axum::extract::Request;
use axum::http::Method;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use crate::audit;
use crate::service::ApiError;

/// Largest error body copied into an audit line.
const MAX_ERROR_TEXT: usize = 64 << 10;

/// The middleware; it wraps the authentication layer so that the write check can note the
/// caller in the call's slot.
pub async fn record(request: Request, next: Next) -> Response {
    if matches!(*request.method(), Method::GET | Method::HEAD) {
        return next.run(request).await;
    }
    let (parts, body) = request.into_parts();
    let body = match to_bytes(body, super::MAX_BODY).await {
        Ok(body) => body,
        Err(_) => {
            return ApiError::too_large(format!("request body above {} bytes", super::MAX_BODY))
                .into_response();
        }
    };
    let has_value = !body.is_empty();
    let request = Request::from_parts(parts, Body::from(body.clone()));
    let (response, write) = audit::scoped(async {
        if has_value {
            audit::note_value(&body);
        }
        next.run(request).await
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
