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
    // Kept for the message only (cheap clones: the URI shares its bytes).
    let (method, uri) = (request.method().clone(), request.uri().clone());
    match tokio::time::timeout(limit, next.run(request)).await {
        Ok(response) => response,
        Err(_) => ApiError::timeout(format!(
            "{method} {} took longer than ecatd's {} s limit",
            uri.path(),
            limit.as_secs()
        ))
        .into_response(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::http::error::PROBLEM_JSON;
    use crate::http::test_support::answer;
    use axum::Router;
    use axum::body::Body;
    use axum::http::StatusCode;
    use axum::routing::get;

    fn app(time: Duration) -> Router {
        Router::new()
            .route("/never", get(std::future::pending::<&'static str>))
            .route("/at-once", get(|| async { "done" }))
            .layer(axum::middleware::from_fn_with_state(time, limit))
    }

    async fn get_path(path: &str, time: Duration) -> (StatusCode, String, Option<String>) {
        let request = axum::http::Request::get(path).body(Body::empty()).unwrap();
        answer(app(time), request).await
    }

    #[tokio::test]
    async fn a_request_past_the_limit_gets_504_problem_json() {
        let (status, body, kind) = get_path("/never", Duration::from_millis(20)).await;
        assert_eq!(status, StatusCode::GATEWAY_TIMEOUT);
        assert_eq!(kind.as_deref(), Some(PROBLEM_JSON));
        assert!(body.contains("urn:ecat:error:timeout"), "{body}");
        assert!(body.contains("GET /never took longer"), "{body}");
    }

    #[tokio::test]
    async fn a_request_within_the_limit_is_untouched() {
        assert_eq!(
            get_path("/at-once", Duration::from_secs(60)).await,
            (
                StatusCode::OK,
                "done".to_owned(),
                Some("text/plain; charset=utf-8".to_owned())
            )
        );
    }
}
