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
//!
//! Beside each row, the CPU one request costs each side: the scheduler's run time
//! (`/proc/self/task/*/schedstat`, exact, not sampled) of the client's thread and of the
//! server's threads (named `floor-server` and `udp-echo`), system calls and the loopback
//! stack run in their context included, divided by the requests made (warm-up included).
//! Under `taskset -c 0` both ends share one CPU, so no wake-up crosses CPUs: the
//! difference to an unpinned run is what the cross-CPU wake-ups cost.

// Only the CPU time is used here, not the context switches.
#[allow(dead_code)]
#[path = "support/thread_cpu.rs"]
mod thread_cpu;

#[path = "support/udp_echo.rs"]
mod udp_echo;

#[path = "support/latency.rs"]
#[allow(dead_code)]
mod latency;

#[path = "support/api_clients.rs"]
#[allow(dead_code)]
mod api_clients;

use std::net::UdpSocket;
use std::time::Duration;

use tonic_health::pb::HealthCheckRequest;
use tonic_health::pb::health_client::HealthClient;

const WIDTH: usize = 58;

/// The name of the servers' runtime threads; the UDP echo's thread is `ECHO_THREAD`.
const SERVER_THREAD: &str = "floor-server";
const ECHO_THREAD: &str = udp_echo::THREAD;

/// CPU time (ns) run so far by this process's threads: (the clients' side, the servers').
/// The servers' threads are the ones named `SERVER_THREAD` or `ECHO_THREAD`; every other
/// thread is the client's (the clients run on this thread; tonic's runtime is
/// current-thread).
fn cpu_ns_by_side() -> (u64, u64) {
    thread_cpu::threads("self")
        .into_iter()
        .fold((0, 0), |(client, server), (name, ns)| match name.as_str() {
            SERVER_THREAD | ECHO_THREAD => (client, server + ns),
            _ => (client + ns, server),
        })
}

/// Times `count` requests made by `op` (`latency::sequential`) and prints the row with
/// the CPU each request cost the client's side and the server's.
fn measure(name: &str, count: usize, op: impl FnMut()) {
    let before = cpu_ns_by_side();
    let r = latency::sequential(count, op);
    let after = cpu_ns_by_side();
    // `sequential` makes a tenth more requests as its warm-up.
    let requests = (count + count / 10) as f64;
    let per = |a: u64, b: u64| b.saturating_sub(a) as f64 / requests / 1000.0;
    println!(
        "{name:<WIDTH$} {:>10.1} {:>10.1} {:>12.0} {:>10.1} {:>10.1}",
        r.p50,
        r.p99,
        r.per_second,
        per(before.0, after.0),
        per(before.1, after.1)
    );
}

/// A multi-thread runtime (as ecatd's) serving a bare tonic health service and a bare axum
/// `/healthz`; returns their addresses. The runtime lives as long as the process.
fn servers() -> (std::net::SocketAddr, std::net::SocketAddr) {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .thread_name(SERVER_THREAD)
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

fn main() {
    let count: usize = std::env::var("TRANSPORT_FLOOR_COUNT")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5000);
    let (grpc, http) = servers();
    let echo = udp_echo::start();
    println!("one request at a time on loopback, nothing behind the server, {count} per row");
    println!("CPU: µs of CPU per request on each side (the scheduler's run time of its threads)");
    println!();
    println!(
        "{:<WIDTH$} {:>10} {:>10} {:>12} {:>10} {:>10}",
        "transport", "p50 µs", "p99 µs", "per second", "client CPU", "server CPU"
    );

    let client = UdpSocket::bind("127.0.0.1:0").expect("bind");
    client
        .set_read_timeout(Some(Duration::from_secs(5)))
        .expect("timeout");
    let request = [0u8; 32];
    let mut reply = [0u8; 1500];
    measure("UDP datagram echo (the gateway's transport)", count, || {
        client.send_to(&request, echo).expect("send");
        assert_eq!(client.recv(&mut reply).expect("echo"), request.len());
    });

    let agent = ureq::Agent::new_with_defaults();
    let url = format!("http://{http}/healthz");
    measure(
        "axum GET /healthz, HTTP/1.1 keep-alive, ureq",
        count,
        || {
            let body = agent
                .get(&url)
                .call()
                .expect("GET")
                .body_mut()
                .read_to_string()
                .expect("body");
            assert_eq!(body, "ok\n");
        },
    );

    let (runtime, channel) = api_clients::grpc_channel(&grpc.to_string());
    let mut health = HealthClient::new(channel);
    measure("tonic grpc.health.v1 Check, HTTP/2, tonic", count, || {
        let status = runtime
            .block_on(health.check(HealthCheckRequest::default()))
            .expect("Check")
            .into_inner()
            .status;
        assert_eq!(status, 1, "SERVING");
    });
}
