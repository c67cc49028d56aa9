//! The request body limit, enforced outside every other layer: a body whose declared length
//! (`Content-Length`) is over the limit is refused before a byte of it is read, and one that
//! streams past the limit (chunked) is cut there. Both get 413 with a problem details body.
//!
//! It has to be the outermost layer that sees the body: the audit layer hashes the body as
//! it streams and hands the handler a new body without the declared size, so axum's own
//! limit (`DefaultBodyLimit`, checked by the extractors) could only count the bytes as they
//! came, and a 100 MB upload was read up to the limit before it was refused.

use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::task::{Context, Poll};

use axum::body::{Body, Bytes, HttpBody};
use axum::extract::{Request, State};
use axum::http::header::{CONNECTION, CONTENT_LENGTH};
use axum::http::{HeaderValue, StatusCode};
use axum::middleware::Next;
use axum::response::Response;

use super::error::problem;
use crate::service::ApiError;

/// The middleware (`from_fn_with_state(limit, enforce)`): `limit` is the largest body in
/// bytes.
pub async fn enforce(State(limit): State<usize>, request: Request, next: Next) -> Response {
    let declared = request
        .headers()
        .get(CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok()?.trim().parse::<u64>().ok())
        .unwrap_or(0)
        .max(request.body().size_hint().lower());
    if declared > limit as u64 {
        return too_large(limit, &format!("declared {declared} bytes"));
    }
    let cut = Arc::new(AtomicBool::new(false));
    let request = request.map(|body| {
        Body::new(Capped {
            inner: body,
            left: limit,
            cut: Arc::clone(&cut),
        })
    });
    let response = next.run(request).await;
    // Whatever the handler made of its cut body (a 400 from the extractor, an error of its
    // own), the client is told what happened.
    if cut.load(Ordering::Relaxed) {
        return too_large(limit, "sent more");
    }
    response
}

/// 413 with the problem details every API error has; the connection is closed after it, as
/// the rest of the body is not read.
fn too_large(limit: usize, what: &str) -> Response {
    let err = ApiError::too_large(format!(
        "request body too large: {what}; the limit is {limit} bytes"
    ));
    let mut response = problem(err, StatusCode::PAYLOAD_TOO_LARGE);
    response
        .headers_mut()
        .insert(CONNECTION, HeaderValue::from_static("close"));
    response
}

/// The error a body past the limit ends with.
#[derive(Debug)]
struct TooLarge;

impl std::fmt::Display for TooLarge {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("request body over the limit")
    }
}

impl std::error::Error for TooLarge {}

/// A body that fails once more than `left` bytes have come, and says so in `cut`.
struct Capped {
    inner: Body,
    left: usize,
    cut: Arc<AtomicBool>,
}

impl HttpBody for Capped {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<http_body::Frame<Bytes>, axum::Error>>> {
        let this = self.get_mut();
        if this.cut.load(Ordering::Relaxed) {
            return Poll::Ready(Some(Err(axum::Error::new(TooLarge))));
        }
        let frame = match Pin::new(&mut this.inner).poll_frame(cx) {
            Poll::Ready(Some(Ok(frame))) => frame,
            other => return other,
        };
        if let Some(data) = frame.data_ref() {
            match this.left.checked_sub(data.len()) {
                Some(left) => this.left = left,
                None => {
                    this.cut.store(true, Ordering::Relaxed);
                    return Poll::Ready(Some(Err(axum::Error::new(TooLarge))));
                }
            }
        }
        Poll::Ready(Some(Ok(frame)))
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.inner.size_hint()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::http::error::PROBLEM_JSON;
    use crate::http::test_support::answer;
    use axum::Router;
    use axum::routing::put;

    fn app() -> Router {
        Router::new()
            .route(
                "/",
                put(|body: Bytes| async move { body.len().to_string() }),
            )
            .layer(axum::middleware::from_fn_with_state(16usize, enforce))
    }

    async fn send(request: axum::http::Request<Body>) -> (StatusCode, String, Option<String>) {
        answer(app(), request).await
    }

    #[tokio::test]
    async fn a_declared_length_over_the_limit_is_refused_unread() {
        let read = Arc::new(AtomicBool::new(false));
        let seen = Arc::clone(&read);
        // A body that records being read: the refusal must not touch it.
        let body = Body::from_stream(futures_util::stream::once(async move {
            seen.store(true, Ordering::Relaxed);
            Ok::<_, std::io::Error>(Bytes::from_static(b"x"))
        }));
        let request = axum::http::Request::put("/")
            .header(CONTENT_LENGTH, "104857600")
            .body(body)
            .unwrap();
        let (status, text, kind) = send(request).await;
        assert_eq!(status, StatusCode::PAYLOAD_TOO_LARGE);
        assert_eq!(kind.as_deref(), Some(PROBLEM_JSON));
        assert!(text.contains("declared 104857600 bytes"), "{text}");
        assert!(!read.load(Ordering::Relaxed), "the body was read");
    }

    #[tokio::test]
    async fn a_streamed_body_past_the_limit_is_cut_with_413() {
        let chunks = (0..4).map(|_| Ok::<_, std::io::Error>(Bytes::from_static(b"0123456789")));
        let request = axum::http::Request::put("/")
            .body(Body::from_stream(futures_util::stream::iter(chunks)))
            .unwrap();
        let (status, text, kind) = send(request).await;
        assert_eq!(status, StatusCode::PAYLOAD_TOO_LARGE, "{text}");
        assert_eq!(kind.as_deref(), Some(PROBLEM_JSON));
        let body: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(body["reason"], "TOO_LARGE");
        assert_eq!(body["status"], 413);
    }

    #[tokio::test]
    async fn bodies_within_the_limit_pass_whole() {
        let request = axum::http::Request::put("/")
            .header(CONTENT_LENGTH, "16")
            .body(Body::from("0123456789abcdef"))
            .unwrap();
        let (status, text, _) = send(request).await;
        assert_eq!(status, StatusCode::OK);
        assert_eq!(text, "16");
    }
}
