//! The HTTP server's accept loop: every connection is admitted against `[limits]`
//! ([`super::connections`]) and served by hyper-util's HTTP/1.1 + HTTP/2 builder with a timer,
//! so that hyper's header-read timeout runs (`axum::serve` builds hyper without a timer,
//! and then hyper never ends a connection that sends half a request line).

use std::convert::Infallible;
use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;

use axum::Router;
use axum::body::Body;
use axum::extract::ConnectInfo;
use axum::http::{Request, StatusCode};
use axum::serve::Listener;
use hyper::body::Incoming;
use hyper_util::rt::{TokioExecutor, TokioIo, TokioTimer};
use hyper_util::server::conn::auto::Builder;
use tokio::sync::watch;
use tower::ServiceExt;

use super::error::{ErrorBody, PROBLEM_JSON};
use crate::config::limits::LimitSettings;
use crate::connections::{ConnectionStats, Limiter, Refusal, Timeout, Tracked};
use crate::service::ApiError;

/// HTTP/2 streams one connection may have open at once (the dashboard's requests, an event
/// stream); beyond, the client waits for one to end.
const MAX_STREAMS: u32 = 64;

/// Serves `app` on `listener` under `limits` until `shutdown` completes, then lets the
/// connections finish their requests. A connection over a limit is handed to `refuse` with
/// the answer it may be sent.
pub(super) async fn serve<L>(
    app: Router,
    mut listener: L,
    limits: &LimitSettings,
    stats: Arc<ConnectionStats>,
    refuse: fn(L::Io, &[u8]),
    shutdown: impl Future<Output = ()> + Send + 'static,
) where
    L: Listener<Addr = SocketAddr>,
{
    let limiter = Limiter::new(limits, Arc::clone(&stats));
    let builder = builder(limits);
    let answers = [Refusal::Total, Refusal::Peer].map(|r| (r, refusal_answer(r)));
    // Connections watch `stop` to shut down gracefully and hold `open` until they end.
    let (stop, stopped) = watch::channel(false);
    let (open, all_closed) = watch::channel(());
    tokio::pin!(shutdown);
    loop {
        let (io, peer) = tokio::select! {
            accepted = listener.accept() => accepted,
            () = &mut shutdown => break,
        };
        let io = match limiter.accept(io, peer) {
            Ok(io) => io,
            Err((io, refusal)) => {
                if let Some((_, answer)) = answers.iter().find(|(r, _)| *r == refusal) {
                    refuse(io, answer);
                }
                continue;
            }
        };
        // Each request carries the client's address and is in flight on its connection
        // until its response body has been sent.
        let (app, info) = (app.clone(), io.info());
        let service = hyper::service::service_fn(move |mut request: Request<Incoming>| {
            let in_flight = info.activity.begin();
            request.extensions_mut().insert(ConnectInfo(info.peer));
            let call = app.clone().oneshot(request.map(Body::new));
            async move {
                let response = call
                    .await
                    .unwrap_or_else(|never: Infallible| match never {});
                Ok::<_, Infallible>(response.map(|body| Tracked::new(body, Some(in_flight))))
            }
        });
        let connection = builder
            .serve_connection(TokioIo::new(io), service)
            .into_owned();
        let (mut stopped, all_closed, stats) =
            (stopped.clone(), all_closed.clone(), Arc::clone(&stats));
        tokio::spawn(async move {
            tokio::pin!(connection);
            let result = tokio::select! {
                result = connection.as_mut() => result,
                () = async { let _ = stopped.wait_for(|stop| *stop).await; } => {
                    connection.as_mut().graceful_shutdown();
                    connection.await
                }
            };
            if let Err(err) = result {
                // hyper's own header-read timeout (HTTP/1.1); the I/O's deadlines count
                // themselves.
                if err
                    .downcast_ref::<hyper::Error>()
                    .is_some_and(hyper::Error::is_timeout)
                {
                    stats.timed_out(Timeout::HeaderRead);
                }
                tracing::trace!(%err, "HTTP connection ended");
            }
            drop(all_closed);
        });
    }
    drop(listener);
    let _ = stop.send(true);
    drop((stopped, all_closed));
    open.closed().await;
}

/// hyper's server for both protocols, with a timer (without one hyper runs no timeouts).
fn builder(limits: &LimitSettings) -> Builder<TokioExecutor> {
    let mut builder = Builder::new(TokioExecutor::new());
    builder
        .http1()
        .timer(TokioTimer::new())
        .header_read_timeout(limits.header_read_timeout)
        .keep_alive(true);
    builder
        .http2()
        .timer(TokioTimer::new())
        .keep_alive_interval(limits.keepalive_interval)
        .keep_alive_timeout(limits.keepalive_timeout)
        .max_concurrent_streams(MAX_STREAMS);
    builder
}

/// The answer a connection over a limit gets before it is closed: 503 with a problem
/// details body, as every other refusal of the API.
fn refusal_answer(refusal: Refusal) -> Vec<u8> {
    let (reason, detail) = refusal.text();
    let err = ApiError::too_many_connections(format!("{detail} ([limits] {reason})"));
    let body = ErrorBody::new(err, StatusCode::SERVICE_UNAVAILABLE);
    let body = serde_json::to_string(&body).unwrap_or_default();
    format!(
        "HTTP/1.1 503 Service Unavailable\r\ncontent-type: {PROBLEM_JSON}\r\ncontent-length: {}\r\nretry-after: 1\r\nconnection: close\r\n\r\n{body}",
        body.len()
    )
    .into_bytes()
}

/// Refuses a plain-TCP connection: the 503 goes out in one non-blocking write (it fits any
/// socket's send buffer, so a refusal never waits on the client) and the socket is closed.
pub(super) fn refuse_tcp(io: tokio::net::TcpStream, answer: &[u8]) {
    let _ = io.try_write(answer);
}

/// Refuses a TLS connection: closed as it is (its handshake is done, but writing an answer
/// through TLS would need a task per refusal, which an attacker could multiply).
pub(super) fn refuse_tls(
    _io: tokio_rustls::server::TlsStream<tokio::net::TcpStream>,
    _answer: &[u8],
) {
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refusal_is_a_whole_problem_details_answer() {
        let answer = String::from_utf8(refusal_answer(Refusal::Peer)).unwrap();
        let (head, body) = answer.split_once("\r\n\r\n").unwrap();
        assert!(head.starts_with("HTTP/1.1 503 "), "{head}");
        assert!(head.contains("content-type: application/problem+json"));
        assert!(head.contains(&format!("content-length: {}", body.len())));
        let body: serde_json::Value = serde_json::from_str(body).unwrap();
        assert_eq!(body["status"], 503);
        assert_eq!(body["reason"], "TOO_MANY_CONNECTIONS");
        assert!(
            body["detail"]
                .as_str()
                .unwrap()
                .contains("max_connections_per_peer"),
            "{body}"
        );
    }
}
