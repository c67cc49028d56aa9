//! The gRPC side of the call log ([`crate::audit`]): a layer around every service that
//! opens the call's slot (the interceptor notes the caller there, for the core's audit
//! lines) and, once the answer's headers are known, logs a failed call at `debug`. The
//! audit line of a write is the core's ([`crate::service::admission`]).

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};

use tonic::codegen::http;

use crate::audit;

/// The layer; see the [module documentation](self).
#[derive(Debug, Clone, Copy, Default)]
pub struct CallLayer;

impl<S> tower_layer::Layer<S> for CallLayer {
    type Service = Audited<S>;

    fn layer(&self, inner: S) -> Audited<S> {
        Audited { inner }
    }
}

/// A service whose calls run in a slot of their own.
#[derive(Debug, Clone)]
pub struct Audited<S> {
    inner: S,
}

impl<S, B, R> tower_service::Service<http::Request<B>> for Audited<S>
where
    S: tower_service::Service<http::Request<B>, Response = http::Response<R>>,
    S::Future: Send + 'static,
    S::Error: std::fmt::Display + Send + 'static,
    R: Send + 'static,
{
    type Response = http::Response<R>;
    type Error = S::Error;
    type Future = Pin<Box<dyn Future<Output = Result<Self::Response, S::Error>> + Send>>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), S::Error>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, request: http::Request<B>) -> Self::Future {
        let path = request.uri().path().to_owned();
        // The interceptor authenticates while the call is made: the slot must exist then.
        let scope = audit::Scope::default();
        let call = scope.make(|| self.inner.call(request));
        Box::pin(async move {
            let (result, noted) = scope.run(call).await;
            let error = match &result {
                Ok(response) => error_of(response.headers()),
                Err(err) => Some(err.to_string()),
            };
            if let Some(error) = &error {
                // Every failed call, at debug: what failed for whom is in the log when asked
                // for, and only then. (A streamed answer carries its status in its
                // trailers, past this layer.)
                let caller = noted.caller.as_ref().map(|c| c.caller.as_str());
                tracing::debug!(caller, operation = %path, error = %error, "gRPC call failed");
            }
            result
        })
    }
}

/// The error of a trailers-only answer (how a failed unary call ends): code and message.
/// A call whose status comes in the trailers has answered, so it is done.
fn error_of(headers: &http::HeaderMap) -> Option<String> {
    let code = headers.get("grpc-status")?.to_str().ok()?;
    if code == "0" {
        return None;
    }
    let code = code
        .parse::<i32>()
        .map(tonic::Code::from_i32)
        .map_or_else(|_| code.to_owned(), |c| format!("{c:?}"));
    let message = headers
        .get("grpc-message")
        .and_then(|m| m.to_str().ok())
        .map(percent_decode)
        .unwrap_or_default();
    Some(format!("{code}: {message}"))
}

/// gRPC percent-encodes its message header (gRPC over HTTP/2, "Responses").
fn percent_decode(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| char::from(b).to_digit(16);
        if bytes[i] == b'%'
            && i + 2 < bytes.len()
            && let (Some(hi), Some(lo)) = (hex(bytes[i + 1]), hex(bytes[i + 2]))
        {
            out.push((hi * 16 + lo) as u8);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trailers_only_errors_are_read() {
        let mut headers = http::HeaderMap::new();
        assert_eq!(error_of(&headers), None);
        headers.insert("grpc-status", "7".parse().unwrap());
        headers.insert("grpc-message", "needs%20a write".parse().unwrap());
        assert_eq!(
            error_of(&headers).unwrap(),
            "PermissionDenied: needs a write"
        );
        headers.insert("grpc-status", "0".parse().unwrap());
        assert_eq!(error_of(&headers), None);
    }
}
