//! SDO upload latency and throughput through ecatd's APIs (gRPC, REST, the ETG.8200 gateway)
//! next to the direct API on the same simulated segment, and ecatd's resident memory with 5
//! and 64 simulated slaves.
//!
//! ```text
//! cargo bench -p ecat-tests --bench server_api
//! ```
//!
//! Every row uploads 0x1018:01 (an expedited upload) from CoE slaves of `ecatd --simulate`:
//! - direct API: `SlaveMailbox::sdo_upload` on an in-process master over the same built-in
//!   segment (no process boundary, no serialisation): the floor of every other row. Its
//!   master is set up as ecatd's (`server::segment::open`): `MasterConfig::default()`, so
//!   every slave in OP, the 1 ms cyclic exchange running, the SM1 "mailbox full" bits mapped
//!   into the cyclic frame and idle polling off, the topology watch every 100 ms; the row
//!   checks the slaves are in OP and cycles run. Awaited once from the bench thread
//!   (current-thread runtime) and once from a task on a multi-thread runtime, where ecatd's
//!   handlers run (the second adds the cross-thread wake-ups of a runtime worker);
//! - ecatd gateway, gRPC (tonic client, one HTTP/2 connection), REST (ureq, HTTP/1.1 with
//!   keep-alive): one client in sequence, then `PARALLEL` clients at once, spread over the
//!   segment's CoE slaves.
//!
//! Then ecatd's VmRSS (from `/proc`) idle and after `PARALLEL` × `EACH` uploads, with the
//! built-in 5-slave segment and with 64 slaves (the built-in slaves repeated).
//! `SERVER_API_COUNT` (default 2000) sets the sequential uploads per row. Not part of CI.
//!
//! ecatd is built in release for this bench (`server_support::bin_dir` builds release
//! binaries for an optimised caller); a debug ecatd is 3-4 times slower on every row.

#![allow(missing_docs)]

#[path = "support/latency.rs"]
#[allow(dead_code)]
mod latency;

#[path = "../tests/server_support/mod.rs"]
mod server_support;

#[path = "support/api_clients.rs"]
mod api_clients;

use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::sync::Barrier;
use std::time::{Duration, Instant};

use api_clients::{GrpcClient, RestClient};
use latency::{Row, row};
use master_core::bus::{Bus, BusConfig};
use master_core::master::{Master, MasterConfig, SlaveAddress};
use master_core::wire::Emit;
use master_core::wire::coe::{CoeRepr, SdoFrame, SdoPayload, SdoRequest, SdoResponse};
use master_core::wire::gateway::{GatewayMessage, GatewayRepr};
use master_core::wire::mailbox::{MailboxHeader, MailboxType};
use master_core::wire::register::AlState;
use server_support::Ecatd;
use sim::link::InProcessLink;
use sim::topology::{Protocol, SIM_VENDOR_ID, Topology, build};

/// Concurrent clients in the parallel rows.
const PARALLEL: usize = 16;
/// Uploads per client in the parallel rows.
const EACH: usize = 200;

/// Positions of the CoE slaves of a segment (the drive and the CoE store in the built-in one).
fn coe_positions(topology: &Topology) -> Vec<u16> {
    topology
        .slaves
        .iter()
        .enumerate()
        .filter(|(_, s)| s.protocols.contains(&Protocol::Coe))
        .map(|(p, _)| p as u16)
        .collect()
}

/// Runs `op` `count` times after a warm-up of a tenth, timing each.
fn sequential(count: usize, mut op: impl FnMut(usize)) -> Row {
    for i in 0..count / 10 {
        op(i);
    }
    let mut samples = Vec::with_capacity(count);
    let start = Instant::now();
    for i in 0..count {
        let t = Instant::now();
        op(i);
        samples.push(t.elapsed());
    }
    row(samples, start.elapsed())
}

/// `PARALLEL` threads, each with its own client from `make`, `EACH` timed uploads each,
/// started together.
fn parallel<C, F>(make: impl Fn(usize) -> C, op: F) -> Row
where
    C: Send,
    F: Fn(&mut C, usize) + Sync,
{
    let barrier = Barrier::new(PARALLEL + 1);
    let (samples, elapsed) = std::thread::scope(|scope| {
        let threads: Vec<_> = (0..PARALLEL)
            .map(|t| {
                let mut client = make(t);
                let (barrier, op) = (&barrier, &op);
                scope.spawn(move || {
                    barrier.wait();
                    (0..EACH)
                        .map(|_| {
                            let t0 = Instant::now();
                            op(&mut client, t);
                            t0.elapsed()
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        barrier.wait();
        let start = Instant::now();
        let samples: Vec<Duration> = threads
            .into_iter()
            .flat_map(|t| t.join().expect("client thread"))
            .collect();
        (samples, start.elapsed())
    });
    row(samples, elapsed)
}

/// An ETG.8200 client on its own UDP socket.
struct GatewayClient {
    socket: UdpSocket,
    gateway: SocketAddr,
    counter: u8,
    request: Vec<u8>,
    reply: Vec<u8>,
}

impl GatewayClient {
    fn new(gateway: SocketAddr) -> GatewayClient {
        let socket = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).expect("client socket");
        socket
            .set_read_timeout(Some(Duration::from_secs(5)))
            .expect("timeout");
        let sdo = CoeRepr::SdoRequest(SdoRequest::InitiateUpload {
            index: 0x1018,
            subindex: 1,
            complete_access: false,
        });
        let request = sdo.to_vec().expect("emit");
        GatewayClient {
            socket,
            gateway,
            counter: 0,
            request,
            reply: vec![0u8; 2048],
        }
    }

    /// Uploads 0x1018:01 from the slave at station `address`; returns the vendor id.
    fn upload(&mut self, address: u16) -> u32 {
        self.counter = self.counter % 7 + 1;
        let repr = GatewayRepr {
            header: MailboxHeader {
                length: self.request.len() as u16,
                address,
                channel: 0,
                priority: 0,
                mailbox_type: MailboxType::Coe,
                counter: self.counter,
            },
            data: &self.request,
        };
        let out = repr.to_vec().expect("emit");
        self.socket.send_to(&out, self.gateway).expect("send");
        let (len, _) = self.socket.recv_from(&mut self.reply).expect("a reply");
        let message = GatewayMessage::new_checked(&self.reply[..len]).expect("reply parses");
        let reply = GatewayRepr::parse(&message).expect("reply parses");
        let sdo = SdoFrame::new_checked(reply.data).expect("SDO frame");
        match SdoResponse::parse(&sdo).expect("SDO response") {
            SdoResponse::InitiateUpload {
                payload: SdoPayload::Expedited(data),
                ..
            } => u32::from_le_bytes(data.try_into().expect("4 bytes")),
            other => panic!("unexpected reply {other:?}"),
        }
    }
}

/// ecatd's resident set size in KiB.
fn rss_kib(ecatd: &Ecatd) -> u64 {
    let status =
        std::fs::read_to_string(format!("/proc/{}/status", ecatd.pid())).expect("/proc status");
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next()?.parse().ok())
        .expect("VmRSS")
}

/// The direct rows: awaited on the bench thread, then from tasks on a multi-thread runtime.
fn direct_rows(count: usize) -> (Row, Row) {
    let topology = Topology::default_segment();
    let segment = build(&topology).expect("segment");
    let (bus, thread) = Bus::start(InProcessLink::new(segment), BusConfig::default()).expect("bus");
    // As `server::segment::open` starts ecatd's master.
    let master = Master::start(bus.clone(), MasterConfig::default()).expect("master");
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .expect("runtime");
    let report = runtime.block_on(master.scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    assert!(master.slaves().iter().all(|s| s.al_state == AlState::Op));
    let position = coe_positions(&topology)[1];
    let mailbox = master
        .mailbox(SlaveAddress::Position(position))
        .expect("mailbox");
    let before = master.cycle_stats();
    let local = sequential(count, |_| {
        let data = runtime
            .block_on(mailbox.sdo_upload(0x1018, 1))
            .expect("upload");
        assert_eq!(data, SIM_VENDOR_ID.to_le_bytes());
    });
    let workers = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .expect("runtime");
    let spawned = sequential(count, |_| {
        let mailbox = mailbox.clone();
        let data = workers
            .block_on(workers.spawn(async move { mailbox.sdo_upload(0x1018, 1).await }))
            .expect("task")
            .expect("upload");
        assert_eq!(data, SIM_VENDOR_ID.to_le_bytes());
    });
    let after = master.cycle_stats();
    assert!(
        after.completed > before.completed,
        "the cyclic exchange runs"
    );
    assert!(
        after.mailbox_status_slaves > 0,
        "mailbox status bits mapped"
    );
    drop(workers);
    drop(mailbox);
    drop(master);
    bus.shutdown();
    let _ = thread.join();
    (local, spawned)
}

/// The load whose memory is measured: `PARALLEL` gRPC clients over every CoE slave.
fn grpc_load(ecatd: &Ecatd, positions: &[u16]) {
    parallel(
        |_| GrpcClient::new(&ecatd.grpc),
        |c, t| {
            c.upload(positions[t % positions.len()]);
        },
    );
}

fn print(name: &str, r: &Row) {
    latency::print(name, 40, r);
}

fn main() {
    let count: usize = std::env::var("SERVER_API_COUNT")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2000)
        .max(10);
    let topology = Topology::default_segment();
    let positions = coe_positions(&topology);
    let store = positions[1];
    let station = |p: u16| 1001 + p;
    println!(
        "SDO upload of 0x1018:01, ecatd --simulate (built-in segment), {count} sequential, \
         {PARALLEL} x {EACH} parallel"
    );
    println!();
    println!(
        "{:<40} {:>10} {:>10} {:>12}",
        "path", "p50 µs", "p99 µs", "uploads/s"
    );
    let (local, spawned) = direct_rows(count);
    print("direct API (in-process master)", &local);
    print("direct API, from a runtime worker", &spawned);

    let ecatd = Ecatd::start(&[]);
    let gateway = ecatd.gateway_addr();
    let vendor = SIM_VENDOR_ID;
    let mut gw = GatewayClient::new(gateway);
    print(
        "ecatd gateway (UDP), 1 client",
        &sequential(count, |_| assert_eq!(gw.upload(station(store)), vendor)),
    );
    let mut grpc = GrpcClient::new(&ecatd.grpc);
    print(
        "ecatd gRPC, 1 client",
        &sequential(count, |_| {
            assert_eq!(grpc.upload(store), vendor.to_le_bytes())
        }),
    );
    print(
        "ecatd gRPC, 1 client, no slave (GetLogFilter)",
        &sequential(count, |_| assert!(!grpc.floor().is_empty())),
    );
    let mut rest = RestClient::new(&ecatd.http);
    print(
        "ecatd REST, 1 client",
        &sequential(count, |_| assert!(!rest.upload(store).is_empty())),
    );
    print(
        "ecatd REST, 1 client, no slave (/healthz)",
        &sequential(count, |_| assert_eq!(rest.floor(), "ok\n")),
    );
    print(
        &format!("ecatd gateway (UDP), {PARALLEL} clients"),
        &parallel(
            |_| GatewayClient::new(gateway),
            |c, t| {
                let p = positions[t % positions.len()];
                assert_eq!(c.upload(station(p)), vendor);
            },
        ),
    );
    print(
        &format!("ecatd gRPC, {PARALLEL} clients"),
        &parallel(
            |_| GrpcClient::new(&ecatd.grpc),
            |c, t| {
                let p = positions[t % positions.len()];
                assert_eq!(c.upload(p), vendor.to_le_bytes());
            },
        ),
    );
    print(
        &format!("ecatd REST, {PARALLEL} clients"),
        &parallel(
            |_| RestClient::new(&ecatd.http),
            |c, t| {
                assert!(!c.upload(positions[t % positions.len()]).is_empty());
            },
        ),
    );
    drop(ecatd);

    println!();
    println!(
        "{:<40} {:>12} {:>16}",
        "ecatd", "idle RSS MiB", "after load MiB"
    );
    let mib = |kib: u64| kib as f64 / 1024.0;
    for slaves in [topology.slaves.len(), 64] {
        let file = std::env::temp_dir().join(format!(
            "ecatd-server-bench-{}-{slaves}.toml",
            std::process::id()
        ));
        let repeated = Topology::repeated(slaves);
        std::fs::write(&file, repeated.to_toml().expect("toml")).expect("topology file");
        let path = file.to_str().expect("utf-8 path");
        let ecatd = Ecatd::start_with(&["--simulate", path], &[]);
        let idle = rss_kib(&ecatd);
        grpc_load(&ecatd, &coe_positions(&repeated));
        let loaded = rss_kib(&ecatd);
        println!(
            "{:<40} {:>12.1} {:>16.1}",
            format!("--simulate, {slaves} slaves"),
            mib(idle),
            mib(loaded)
        );
        drop(ecatd);
        let _ = std::fs::remove_file(&file);
    }
}
