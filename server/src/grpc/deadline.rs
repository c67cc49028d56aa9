//! The server's time limit on a call, which FoE transfers do not get: a file of several
//! MiB takes as long as the slave needs, and the mailbox engine's deadlines (a window per
//! exchange that restarts on progress, a cap from the size) end a stalled transfer instead.
//! A client's own `grpc-timeout` still applies to every call (tonic's).

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use tonic::codegen::http;

/// The method paths exempt from the limit.
const EXEMPT: &str = "/ecat.v1.FoeService/";

/// Ends calls other than FoE transfers after the limit with `DEADLINE_EXCEEDED`.
#[derive(Debug, Clone, Copy)]
pub struct DeadlineLayer {
    limit: Duration,
}

impl DeadlineLayer {
    /// A limit of `limit` per call.
    pub fn new(limit: Duration) -> DeadlineLayer {
        DeadlineLayer { limit }
    }
}

impl<S> tower_layer::Layer<S> for DeadlineLayer {
    type Service = Deadline<S>;

    fn layer(&self, inner: S) -> Deadline<S> {
        Deadline {
            inner,
            limit: self.limit,
        }
    }
}

/// The service of [`DeadlineLayer`].
#[derive(Debug, Clone)]
pub struct Deadline<S> {
    inner: S,
    limit: Duration,
}

impl<S, B, R> tower_service::Service<http::Request<B>> for Deadline<S>
where
    S: tower_service::Service<http::Request<B>, Response = http::Response<R>>,
    S::Future: Send + 'static,
    S::Error: Send + 'static,
    R: Default + Send + 'static,
{
    type Response = http::Response<R>;
    type Error = S::Error;
    type Future = Pin<Box<dyn Future<Output = Result<Self::Response, S::Error>> + Send>>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), S::Error>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, request: http::Request<B>) -> Self::Future {
        let limited = !request.uri().path().starts_with(EXEMPT);
        let call = self.inner.call(request);
        let limit = self.limit;
        Box::pin(async move {
            if !limited {
                return call.await;
            }
            match tokio::time::timeout(limit, call).await {
                Ok(result) => result,
                Err(_) => Ok(tonic::Status::deadline_exceeded(format!(
                    "the call took longer than the server's limit of {} s",
                    limit.as_secs()
                ))
                .into_http()),
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tower_service::Service;

    /// A service that answers after `delay`.
    #[derive(Clone)]
    struct Slow(Duration);

    impl tower_service::Service<http::Request<()>> for Slow {
        type Response = http::Response<String>;
        type Error = std::convert::Infallible;
        type Future = Pin<Box<dyn Future<Output = Result<Self::Response, Self::Error>> + Send>>;

        fn poll_ready(&mut self, _: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
            Poll::Ready(Ok(()))
        }

        fn call(&mut self, _: http::Request<()>) -> Self::Future {
            let delay = self.0;
            Box::pin(async move {
                tokio::time::sleep(delay).await;
                Ok(http::Response::new("answer".to_owned()))
            })
        }
    }

    fn request(path: &str) -> http::Request<()> {
        http::Request::builder().uri(path).body(()).unwrap()
    }

    #[tokio::test]
    async fn foe_calls_are_exempt_and_others_are_cut() {
        let limit = DeadlineLayer::new(Duration::from_millis(50));
        let mut slow = tower_layer::Layer::layer(&limit, Slow(Duration::from_secs(30)));
        let cut = slow
            .call(request("/ecat.v1.CoeService/Upload"))
            .await
            .unwrap();
        assert_eq!(cut.headers()["grpc-status"], "4");
        assert_eq!(cut.body(), "");
        // Three times the limit, and still answered.
        let mut transfer = tower_layer::Layer::layer(&limit, Slow(Duration::from_millis(150)));
        let foe = transfer
            .call(request("/ecat.v1.FoeService/Write"))
            .await
            .unwrap();
        assert_eq!(foe.body(), "answer");
    }
}
