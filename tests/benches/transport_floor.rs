//! What ecatd's three transports cost on this machine with nothing behind them: a bare
//! tonic server (`grpc.health.v1` Check, as ecatd's gRPC stack is built: HTTP/2, Nagle off),
//! a bare axum server (`GET /healthz`, HTTP/1.1 keep-alive) and a UDP echo, each in this
//! process on loopback, called one request at a time by the clients `perf_veth` uses
//! (tonic on a current-thread runtime, ureq, a std UDP socket).
//!
//! ```text
//! cargo bench -p ecat-tests --bench transport_floor
//! ```
//!
//! The floor under ecatd's rows of `perf_veth`: an API's p50 there is at least this plus
//! the direct API's (`docs/performance.md`). `TRANSPORT_FLOOR_COUNT` (default 5000) sets the
//! timed requests per row. Not part of CI.

#[path = "support/latency.rs"]
mod latency;

#[path = "support/api_clients.rs"]
#[allow(dead_code)]
mod api_clients;

use std::net::UdpSocket;
use std::time::Duration;

use tonic_health::pb::HealthCheckRequest;
use tonic_health::pb::health_client::HealthClient;

const WIDTH: usize = 58;

/// A multi-thread runtime (as ecatd's) serving a bare tonic health service and a bare axum
/// `/healthz`; returns their addresses. The runtime lives as long as the process.
fn servers() -> (std::net::SocketAddr, std::net::SocketAddr) {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .expect("runtime");
    let grpc = runtime
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .expect("bind");
    let http = runtime
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .expect("bind");
    let addrs = (
        grpc.local_addr().expect("addr"),
        http.local_addr().expect("addr"),
    );
    runtime.spawn(async move {
        let (_reporter, health) = tonic_health::server::health_reporter();
        let incoming = tonic::transport::server::TcpIncoming::from(grpc).with_nodelay(Some(true));
        tonic::transport::Server::builder()
            .add_service(health)
            .serve_with_incoming(incoming)
            .await
            .expect("tonic serves");
    });
    runtime.spawn(async move {
        let app = axum::Router::new().route("/healthz", axum::routing::get(|| async { "ok\n" }));
        axum::serve(http, app).await.expect("axum serves");
    });
    // Keeps serving on its worker threads until the process ends.
    std::mem::forget(runtime);
    addrs
}

/// A thread echoing every datagram back to its sender.
fn udp_echo() -> std::net::SocketAddr {
    let socket = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let addr = socket.local_addr().expect("addr");
    std::thread::spawn(move || {
        let mut buf = [0u8; 1500];
        while let Ok((len, from)) = socket.recv_from(&mut buf) {
            if socket.send_to(&buf[..len], from).is_err() {
                break;
            }
        }
    });
    addr
}

fn main() {
    let count: usize = std::env::var("TRANSPORT_FLOOR_COUNT")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5000);
    let (grpc, http) = servers();
    let echo = udp_echo();
    println!("one request at a time on loopback, nothing behind the server, {count} per row");
    println!();
    println!(
        "{:<WIDTH$} {:>10} {:>10} {:>12}",
        "transport", "p50 µs", "p99 µs", "per second"
    );

    let client = UdpSocket::bind("127.0.0.1:0").expect("bind");
    client
        .set_read_timeout(Some(Duration::from_secs(5)))
        .expect("timeout");
    let request = [0u8; 32];
    let mut reply = [0u8; 1500];
    let r = latency::sequential(count, || {
        client.send_to(&request, echo).expect("send");
        assert_eq!(client.recv(&mut reply).expect("echo"), request.len());
    });
    latency::print("UDP datagram echo (the gateway's transport)", WIDTH, &r);

    let agent = ureq::Agent::new_with_defaults();
    let url = format!("http://{http}/healthz");
    let r = latency::sequential(count, || {
        let body = agent
            .get(&url)
            .call()
            .expect("GET")
            .body_mut()
            .read_to_string()
            .expect("body");
        assert_eq!(body, "ok\n");
    });
    latency::print("axum GET /healthz, HTTP/1.1 keep-alive, ureq", WIDTH, &r);

    let (runtime, channel) = api_clients::grpc_channel(&grpc.to_string());
    let mut health = HealthClient::new(channel);
    let r = latency::sequential(count, || {
        let status = runtime
            .block_on(health.check(HealthCheckRequest::default()))
            .expect("Check")
            .into_inner()
            .status;
        assert_eq!(status, 1, "SERVING");
    });
    latency::print("tonic grpc.health.v1 Check, HTTP/2, tonic", WIDTH, &r);
}
