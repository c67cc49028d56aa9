//! The gRPC API (`ecat.v1`), server reflection (v1 and v1alpha) and `grpc.health.v1`.
//!
//! Files: one per service (`bus`, `coe`, `foe`, `gateway`, `process_data`, `protocols` for
//! SoE/VoE/EoE), `auth` (the token interceptor and write check), `convert` (views to
//! messages), `status` (the error mapping).

pub mod audit;
pub mod auth;
pub mod bus;
pub mod coe;
pub mod convert;
pub mod deadline;
pub mod foe;
pub mod gateway;
pub mod process_data;
pub mod protocols;
pub mod status;

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use futures_util::{Stream, StreamExt};

use proto::v1::bus_service_server::BusServiceServer;
use proto::v1::coe_service_server::CoeServiceServer;
use proto::v1::eoe_service_server::EoeServiceServer;
use proto::v1::foe_service_server::FoeServiceServer;
use proto::v1::gateway_service_server::GatewayServiceServer;
use proto::v1::process_data_service_server::ProcessDataServiceServer;
use proto::v1::soe_service_server::SoeServiceServer;
use proto::v1::voe_service_server::VoeServiceServer;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::Server;
use tonic::transport::server::TcpIncoming;

use crate::config::limits::LimitSettings;
use crate::connections::{ConnectionStats, LimitedIo, Limiter, TrackLayer};
use crate::security::Tokens;
use crate::service::Core;
use auth::grpc_interceptor;

/// Largest request message accepted (FoE writes come in chunks below this).
pub const MAX_MESSAGE: usize = 4 << 20;
/// Time limit of one call (a streaming call counts from its start; FoE transfers are
/// exempt, see [`deadline`]).
pub const TIMEOUT: Duration = Duration::from_secs(60);

/// Serves every gRPC service on `listener` under `limits` (the connections counted in
/// `stats`) until `shutdown` completes.
pub async fn serve(
    core: Core,
    tokens: Tokens,
    listener: tokio::net::TcpListener,
    limits: LimitSettings,
    stats: Arc<ConnectionStats>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), String> {
    serve_tls(core, tokens, listener, None, limits, stats, shutdown).await
}

/// Like [`serve`], over TLS when `tls` is given.
pub async fn serve_tls(
    core: Core,
    tokens: Tokens,
    listener: tokio::net::TcpListener,
    tls: Option<tokio_rustls::TlsAcceptor>,
    limits: LimitSettings,
    stats: Arc<ConnectionStats>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), String> {
    let reflection = || {
        tonic_reflection::server::Builder::configure()
            .register_encoded_file_descriptor_set(proto::v1::FILE_DESCRIPTOR_SET)
            .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
            // google.rpc.ErrorInfo, so that clients using reflection can show error details.
            .register_encoded_file_descriptor_set(tonic_types::pb::FILE_DESCRIPTOR_SET)
    };
    let reflection_v1 = reflection().build_v1().map_err(|e| e.to_string())?;
    let reflection_v1alpha = reflection().build_v1alpha().map_err(|e| e.to_string())?;
    let (health, health_service) = tonic_health::server::health_reporter();
    // Set before the server accepts anything: the reporter starts at SERVING.
    let ready = core.readiness();
    let now = *ready.borrow();
    set_health(&health, now).await;
    tokio::spawn(follow_readiness(health, ready));
    let auth = grpc_interceptor(tokens);
    macro_rules! svc {
        ($server:ident, $inner:expr) => {
            InterceptedService::new(
                $server::new($inner).max_decoding_message_size(MAX_MESSAGE),
                auth.clone(),
            )
        };
    }
    let router = transport(Server::builder(), &limits)
        // Outermost: a call is in flight on its connection (which is then not idle) until
        // its last response message has been sent.
        .layer(TrackLayer)
        .layer(tower::util::MapRequestLayer::new(
            auth::with_path::<tonic::body::Body>,
        ))
        .layer(audit::CallLayer)
        // The time limit of each call, except FoE transfers (they have their own deadlines,
        // which follow the transfer's progress); inside the call layer, which logs the
        // timeout as a failed call (and a write's ticket, dropped, says it was cut short).
        .layer(deadline::DeadlineLayer::new(TIMEOUT))
        .add_service(reflection_v1)
        .add_service(reflection_v1alpha)
        .add_service(health_service)
        .add_service(svc!(BusServiceServer, bus::Bus { core: core.clone() }))
        .add_service(svc!(CoeServiceServer, coe::Coe { core: core.clone() }))
        .add_service(svc!(FoeServiceServer, foe::Foe { core: core.clone() }))
        .add_service(svc!(
            GatewayServiceServer,
            gateway::Gateway { core: core.clone() }
        ))
        .add_service(svc!(
            ProcessDataServiceServer,
            process_data::ProcessData { core: core.clone() }
        ))
        .add_service(svc!(
            SoeServiceServer,
            protocols::Protocols { core: core.clone() }
        ))
        .add_service(svc!(
            VoeServiceServer,
            protocols::Protocols { core: core.clone() }
        ))
        .add_service(svc!(EoeServiceServer, protocols::Protocols { core }));
    let served = match tls {
        // The certificate comes from the acceptor's resolver per handshake, so a reload
        // (SIGHUP) reaches new connections without a restart.
        Some(acceptor) => {
            let incoming = crate::tls::TlsListener::new(listener, acceptor).into_incoming();
            let incoming = limited(incoming, &limits, stats);
            router
                .serve_with_incoming_shutdown(incoming, shutdown)
                .await
        }
        None => {
            // Nagle off: a reply goes out in several small writes (HEADERS, DATA,
            // trailers) that must not wait for the client's ACK of the first.
            // `Server::tcp_nodelay` applies only to sockets tonic binds itself, so the
            // accepted ones are set here.
            let incoming = TcpIncoming::from(listener)
                .with_nodelay(Some(true))
                .with_keepalive(Some(TCP_KEEPALIVE));
            let incoming = limited(incoming, &limits, stats);
            router
                .serve_with_incoming_shutdown(incoming, shutdown)
                .await
        }
    };
    served.map_err(|err| format!("gRPC server: {err}"))
}

/// Streams one connection may have open at once: bounded, far above what a client
/// multiplexes (every request waits on a slave's mailbox anyway).
pub const MAX_STREAMS: u32 = 256;
/// HTTP/2 flow-control windows: a unary call's messages fit in the first window, so they
/// never wait for a WINDOW_UPDATE, and an FoE chunk (up to [`MAX_MESSAGE`]) streams in a
/// few round trips.
pub const STREAM_WINDOW: u32 = 1 << 20;
/// The connection's window: several streams' worth.
pub const CONNECTION_WINDOW: u32 = 4 << 20;
/// Idle time after which the kernel starts probing a plain-TCP client (TCP keep-alive, set
/// on the sockets tonic accepts): a peer that vanished is noticed even between HTTP/2 PINGs.
pub const TCP_KEEPALIVE: Duration = Duration::from_secs(60);

/// The HTTP/2 settings for small unary calls: fixed windows large enough that no call
/// waits on flow control (no adaptive window: its BDP PINGs are work per call for nothing
/// here), bounded streams per connection, keep-alive PINGs (`[limits] keepalive_interval`,
/// `keepalive_timeout`) to notice dead peers. Nagle is switched off on the accepted sockets
/// (`serve_tls`).
///
/// Tonic's own `timeout` is not used: it would cut FoE transfers, which have deadlines
/// that follow their progress; [`deadline::DeadlineLayer`] limits every other call.
/// `concurrency_limit_per_connection` is not needed either: `max_concurrent_streams`
/// already bounds the calls of one connection, and tells the client so (it queues on its
/// side instead of on ecatd's).
fn transport(builder: Server, limits: &LimitSettings) -> Server {
    builder
        .http2_adaptive_window(Some(false))
        .initial_stream_window_size(STREAM_WINDOW)
        .initial_connection_window_size(CONNECTION_WINDOW)
        .max_concurrent_streams(MAX_STREAMS)
        .http2_keepalive_interval(Some(limits.keepalive_interval))
        .http2_keepalive_timeout(Some(limits.keepalive_timeout))
}

/// A socket whose client address is known (the connection limits count per address).
trait Peer {
    fn peer(&self) -> Option<SocketAddr>;
}

impl Peer for tokio::net::TcpStream {
    fn peer(&self) -> Option<SocketAddr> {
        self.peer_addr().ok()
    }
}

impl Peer for tokio_rustls::server::TlsStream<tokio::net::TcpStream> {
    fn peer(&self) -> Option<SocketAddr> {
        self.get_ref().0.peer_addr().ok()
    }
}

/// The accepted connections under `[limits]`: one over a connection limit is closed at
/// once (the client sees UNAVAILABLE), the others are handed to tonic with their deadlines
/// (the preface and first call within `header_read_timeout`, none in flight for at most
/// `idle_timeout`), which tonic and hyper have none of for HTTP/2.
fn limited<IO: Peer>(
    incoming: impl Stream<Item = Result<IO, std::io::Error>>,
    limits: &LimitSettings,
    stats: Arc<ConnectionStats>,
) -> impl Stream<Item = Result<LimitedIo<IO>, std::io::Error>> {
    let limiter = Limiter::new(limits, stats);
    incoming.filter_map(move |accepted| {
        let admitted = match accepted {
            Err(err) => Some(Err(err)),
            // Gone before it was looked at; refused: closed as it is dropped.
            Ok(io) => io
                .peer()
                .and_then(|peer| limiter.accept(io, peer).ok())
                .map(Ok),
        };
        std::future::ready(admitted)
    })
}

/// Every service the health service reports on ("" is the server as a whole).
const HEALTH_NAMES: [&str; 9] = [
    "",
    "ecat.v1.BusService",
    "ecat.v1.CoeService",
    "ecat.v1.SoeService",
    "ecat.v1.FoeService",
    "ecat.v1.VoeService",
    "ecat.v1.EoeService",
    "ecat.v1.GatewayService",
    "ecat.v1.ProcessDataService",
];

/// Keeps `grpc.health.v1` in step with `/readyz`: NOT_SERVING until the first scan is done
/// and again from the start of the shutdown. Ends with the core (its sender dropped).
async fn follow_readiness(
    health: tonic_health::server::HealthReporter,
    mut ready: tokio::sync::watch::Receiver<bool>,
) {
    loop {
        let now = *ready.borrow_and_update();
        set_health(&health, now).await;
        if ready.changed().await.is_err() {
            return;
        }
    }
}

async fn set_health(health: &tonic_health::server::HealthReporter, ready: bool) {
    let status = if ready {
        tonic_health::ServingStatus::Serving
    } else {
        tonic_health::ServingStatus::NotServing
    };
    for name in HEALTH_NAMES {
        health.set_service_status(name, status).await;
    }
}

#[cfg(test)]
mod tests {
    use tonic_health::pb::health_server::Health;
    use tonic_health::pb::{HealthCheckRequest, health_check_response::ServingStatus};

    use super::*;

    async fn check(service: &impl Health, name: &str) -> ServingStatus {
        let answer = service
            .check(tonic::Request::new(HealthCheckRequest {
                service: name.to_owned(),
            }))
            .await
            .expect("every service is registered");
        answer.into_inner().status()
    }

    async fn until(service: &impl Health, name: &str, want: ServingStatus) {
        let deadline = tokio::time::Instant::now() + std::time::Duration::from_secs(5);
        while check(service, name).await != want {
            assert!(
                tokio::time::Instant::now() < deadline,
                "{name:?} never {want:?}"
            );
            tokio::task::yield_now().await;
        }
    }

    #[tokio::test]
    async fn health_is_not_serving_until_ready_and_again_at_shutdown() {
        let (reporter, _) = tonic_health::server::health_reporter();
        let service = tonic_health::server::HealthService::from_health_reporter(reporter.clone());
        let (ready, rx) = tokio::sync::watch::channel(false);
        set_health(&reporter, false).await;
        tokio::spawn(follow_readiness(reporter, rx));
        for name in HEALTH_NAMES {
            assert_eq!(
                check(&service, name).await,
                ServingStatus::NotServing,
                "{name:?}"
            );
        }
        ready.send_replace(true);
        until(&service, "", ServingStatus::Serving).await;
        until(&service, "ecat.v1.CoeService", ServingStatus::Serving).await;
        ready.send_replace(false);
        until(&service, "", ServingStatus::NotServing).await;
        until(&service, "ecat.v1.BusService", ServingStatus::NotServing).await;
    }
}
