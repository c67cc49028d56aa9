//! Mailbox gateway latency and throughput against the simulator in-process, next to the
//! direct API and the raw frame round trip: what UDP, routing and sessions add.
//!
//! Rows: one register read (FPRD, one frame round trip); SDO upload of 0x1018:01 through
//! `SlaveMailbox::sdo_upload` by 1 and by 64 callers; the same upload as an ETG.8200
//! datagram over loopback UDP by 1 and by 64 clients; a read of the master's dictionary
//! (address 0) by one client; the same upload over the optional TCP transport; and, as the
//! floor of what any UDP request/reply costs here, a loopback UDP echo between two threads
//! (the gateway's row minus the direct row minus this one is the gateway's own work). The
//! 64-caller rows spread over the segment's two CoE slaves.
//!
//! Run with `cargo bench -p master-core --bench gateway`; `GATEWAY_BENCH_WORKERS=N` sets
//! the gateway's receive workers (default: `GatewayConfig::default()`'s, the cores up to 4).

#[path = "../tests/gateway_support/mod.rs"]
mod gateway_support;

use std::io::{Read, Write};
use std::net::{Ipv4Addr, TcpStream, UdpSocket};
use std::sync::Barrier;
use std::time::{Duration, Instant};

use gateway_support::{
    COE_STORE, Client, DRIVE, GwRig, block_on, datagram, sdo, station, test_config,
};
use master_core::gateway::GatewayConfig;
use master_core::master::SlaveAddress;
use master_core::wire::coe::{SdoRequest, SdoResponse};
use master_core::wire::mailbox::MailboxType;

const WARMUP: usize = 200;
const SINGLE: usize = 3000;
const CLIENTS: usize = 64;
const EACH: usize = 150;

fn percentile(sorted: &[Duration], p: f64) -> Duration {
    let at = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[at.min(sorted.len() - 1)]
}

fn print(name: &str, mut samples: Vec<Duration>, elapsed: Duration) {
    samples.sort_unstable();
    let rate = samples.len() as f64 / elapsed.as_secs_f64();
    println!(
        "{:<40} {:>10.1} {:>10.1} {:>12.0}",
        name,
        percentile(&samples, 0.50).as_secs_f64() * 1e6,
        percentile(&samples, 0.99).as_secs_f64() * 1e6,
        rate
    );
}

/// Runs `op` `count` times; its latencies and the wall time.
fn timed(count: usize, mut op: impl FnMut(usize)) -> (Vec<Duration>, Duration) {
    let start = Instant::now();
    let samples = (0..count)
        .map(|n| {
            let t = Instant::now();
            op(n);
            t.elapsed()
        })
        .collect();
    (samples, start.elapsed())
}

/// Runs `op` on `threads` threads at once, `count` times each.
fn parallel(
    threads: usize,
    count: usize,
    op: impl Fn(usize) -> Box<dyn FnMut(usize) + Send> + Sync,
) -> (Vec<Duration>, Duration) {
    let start_line = Barrier::new(threads + 1);
    let mut all = Vec::new();
    let start = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                let mut work = op(t);
                let start_line = &start_line;
                s.spawn(move || {
                    start_line.wait();
                    timed(count, &mut work).0
                })
            })
            .collect();
        start_line.wait();
        let start = Instant::now();
        for h in handles {
            all.extend(h.join().expect("worker"));
        }
        start
    });
    (all, start.elapsed())
}

fn gateway_upload(client: &mut Client, address: u16) {
    let reply = client.request(
        address,
        MailboxType::Coe,
        &sdo(SdoRequest::InitiateUpload {
            index: 0x1018,
            subindex: 1,
            complete_access: false,
        }),
    );
    assert!(matches!(reply.sdo(), SdoResponse::InitiateUpload { .. }));
}

/// Request/reply over loopback UDP with a thread that echoes: two syscalls and a thread
/// wake-up each way, nothing else.
fn udp_echo_row() {
    let server = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).expect("echo socket");
    let addr = server.local_addr().expect("echo address");
    let echo = std::thread::spawn(move || {
        let mut buf = [0u8; 64];
        for _ in 0..WARMUP + SINGLE {
            let (len, from) = server.recv_from(&mut buf).expect("echo recv");
            server.send_to(&buf[..len], from).expect("echo send");
        }
    });
    let client = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).expect("client socket");
    let message = [0u8; 24];
    let mut buf = [0u8; 64];
    let mut round_trip = |_| {
        client.send_to(&message, addr).expect("send");
        client.recv_from(&mut buf).expect("recv");
    };
    timed(WARMUP, &mut round_trip);
    let (s, e) = timed(SINGLE, &mut round_trip);
    print("loopback UDP echo (transport floor)", s, e);
    echo.join().expect("echo thread");
}

/// The gateway upload over a TCP connection.
fn tcp_upload(stream: &mut TcpStream, request: &[u8], reply: &mut Vec<u8>) {
    stream.write_all(request).expect("TCP write");
    let mut header = [0u8; 2];
    stream.read_exact(&mut header).expect("TCP header");
    reply.resize(usize::from(u16::from_le_bytes(header) & 0x07FF), 0);
    stream.read_exact(reply).expect("TCP body");
}

fn main() {
    let defaults = test_config();
    let workers = std::env::var("GATEWAY_BENCH_WORKERS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(defaults.workers);
    println!("gateway receive workers: {workers}");
    let rig = GwRig::start(GatewayConfig {
        tcp: true,
        workers,
        ..defaults
    });
    let master = rig.master();
    let store = master
        .mailbox(SlaveAddress::Station(station(COE_STORE)))
        .expect("mailbox");
    let coe_slaves = [station(DRIVE), station(COE_STORE)];

    println!(
        "{:<40} {:>10} {:>10} {:>12}",
        "operation", "p50 µs", "p99 µs", "per second"
    );
    let read = |_| {
        block_on(master.read_register(SlaveAddress::Position(0), 0x0130, 2)).expect("FPRD");
    };
    timed(WARMUP, read);
    let (s, e) = timed(SINGLE, read);
    print("register read (one frame round trip)", s, e);

    let direct = |_| {
        block_on(store.sdo_upload(0x1018, 1)).expect("upload");
    };
    timed(WARMUP, direct);
    let (s, e) = timed(SINGLE, direct);
    print("direct SDO upload, 1 caller", s, e);

    let (s, e) = parallel(CLIENTS, EACH, |t| {
        let slave = master
            .mailbox(SlaveAddress::Station(coe_slaves[t % 2]))
            .expect("mailbox");
        Box::new(move |_| {
            block_on(slave.sdo_upload(0x1018, 1)).expect("upload");
        })
    });
    print("direct SDO upload, 64 callers", s, e);

    let mut client = rig.client();
    timed(WARMUP, |_| gateway_upload(&mut client, station(COE_STORE)));
    let (s, e) = timed(SINGLE, |_| gateway_upload(&mut client, station(COE_STORE)));
    print("gateway SDO upload, 1 client", s, e);
    // The gateway's own view of those requests: from receipt to the reply handed to the
    // socket (its histogram has 25 % buckets).
    let own = rig.gateway().stats().latency;
    let own_p50 = own.p50().unwrap_or_default();

    let addr = rig.addr();
    let (s, e) = parallel(CLIENTS, EACH, |t| {
        let mut client = Client::new(addr);
        let address = coe_slaves[t % 2];
        Box::new(move |_| gateway_upload(&mut client, address))
    });
    print("gateway SDO upload, 64 clients", s, e);

    let (s, e) = timed(SINGLE / 3, |_| gateway_upload(&mut client, 0));
    print("gateway master dictionary 0x1018:01", s, e);

    let mut stream = TcpStream::connect(addr).expect("TCP connect");
    stream.set_nodelay(true).expect("nodelay");
    let request = datagram(
        station(COE_STORE),
        MailboxType::Coe,
        1,
        &sdo(SdoRequest::InitiateUpload {
            index: 0x1018,
            subindex: 1,
            complete_access: false,
        }),
    );
    let mut reply = Vec::new();
    timed(WARMUP, |_| tcp_upload(&mut stream, &request, &mut reply));
    let (s, e) = timed(SINGLE, |_| tcp_upload(&mut stream, &request, &mut reply));
    print("gateway SDO upload over TCP, 1 client", s, e);

    udp_echo_row();

    println!(
        "\ngateway SDO upload, 1 client, inside the gateway (receipt to reply): p50 {own_p50:?}"
    );
    let stats = rig.gateway().stats();
    println!(
        "\ngateway: {} requests, {} failed; its own latency histogram p50 {:?}, p99 {:?}",
        stats.total_requests,
        stats.failed_requests,
        stats.latency.p50().unwrap_or_default(),
        stats.latency.p99().unwrap_or_default()
    );
}
