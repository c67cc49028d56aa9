//! The time limit of one REST request ([`super::TIMEOUT`]; transfers and streams run
//! outside it): past it the request is dropped and the caller gets 504 problem+json
//! (`timeout`), as for a slave that did not answer in time.

use std::time::Duration;

use axum::extract::{Request, State};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use crate::service::ApiError;

/// The middleware: runs the request for at most `limit`.
pub async fn limit(State(limit): State<Duration>, request: Request, next: Next) -> Response {
    let what = format!("{} {}", request.method(), request.uri().path());
    match tokio::time::timeout(limit, next.run(request)).await {
        Ok(response) => response,
        Err(_) => ApiError::timeout(format!(
            "{what} took longer than ecatd's {} s limit",
            limit.as_secs()
        ))
        .into_response(),
    }
}
