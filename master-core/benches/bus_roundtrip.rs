//! Round-trip latency and throughput of the bus over a veth pair, next to the physical
//! floor: a plain raw-socket ping-pong of the same frame.
//!
//! Run as root (it makes a network namespace with a veth pair, deleted again at the end):
//!
//! ```text
//! cargo bench -p master-core --bench bus_roundtrip
//! ```
//!
//! `BUS_BENCH_ROUNDS` (default 20000) sets the round trips per latency row,
//! `BUS_BENCH_SECONDS` (default 2) the length of each throughput run. An echo thread on the
//! far end of the pair sends every frame straight back, so the bus sees each datagram return
//! unchanged (working counter 0), which it accepts like any reply.
//!
//! Not part of CI: numbers depend on the machine and its load.

#![allow(missing_docs)]

#[path = "../tests/bus_support/netns.rs"]
#[allow(dead_code)]
mod netns;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use master_core::bus::{Bus, BusConfig, WaitMode};
use master_core::link::{Link, MAX_FRAME_LEN, RawSocket, RawSocketOptions, Wait};
use master_core::wire::command::{Command, DatagramAddress};
use master_core::wire::datagram::{DatagramRepr, FrameBuilder};

use netns::NetNs;

/// Data bytes of the one datagram (an AL status read).
const DATA_LEN: usize = 2;

fn env_or(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Sends every frame it receives straight back, until stopped.
struct Echo {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Echo {
    fn spawn(mut socket: RawSocket) -> Echo {
        let stop = Arc::new(AtomicBool::new(false));
        let thread = std::thread::spawn({
            let stop = Arc::clone(&stop);
            move || {
                let mut buf = vec![0u8; MAX_FRAME_LEN];
                while !stop.load(Ordering::Relaxed) {
                    let wait = Wait::Until(Instant::now() + Duration::from_millis(20));
                    if let Ok(Some(len)) = socket.recv(&mut buf, wait) {
                        let _ = socket.send(&buf[..len]);
                    }
                }
            }
        });
        Echo {
            stop,
            thread: Some(thread),
        }
    }
}

impl Drop for Echo {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// The two ends of the veth pair, opened for `mode`.
fn sockets(ns: &NetNs, mode: WaitMode) -> (RawSocket, RawSocket) {
    let options = RawSocketOptions {
        busy_poll: mode == WaitMode::BusyPoll,
        qdisc_bypass: true,
        ..RawSocketOptions::default()
    };
    ns.run_inside(|| {
        (
            RawSocket::open("master", options).expect("open master end"),
            RawSocket::open("echo", options).expect("open echo end"),
        )
    })
}

/// p50 and p99 of `samples`, in microseconds.
fn percentiles(samples: &mut [Duration]) -> (f64, f64) {
    samples.sort_unstable();
    let at = |q: f64| {
        let i = ((samples.len() as f64 * q).ceil() as usize).clamp(1, samples.len()) - 1;
        samples[i].as_secs_f64() * 1e6
    };
    (at(0.50), at(0.99))
}

fn micros(d: Option<Duration>) -> f64 {
    d.map_or(f64::NAN, |d| d.as_secs_f64() * 1e6)
}

/// The frame a one-datagram bus request makes: FPRD of `DATA_LEN` bytes, padded to 60.
fn one_datagram_frame() -> Vec<u8> {
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let mut builder = FrameBuilder::new(&mut buf).unwrap();
    let address = DatagramAddress::Node {
        station: 0x1001,
        ado: 0x0130,
    };
    builder
        .push(&DatagramRepr::request(
            Command::Fprd,
            0,
            address,
            &[0; DATA_LEN],
        ))
        .unwrap();
    let len = builder.finish([2, 0, 0, 0, 0, 1]).unwrap();
    buf.truncate(len);
    buf
}

fn raw_ping_pong(ns: &NetNs, mode: WaitMode, rounds: u64) -> (f64, f64) {
    let (mut near, far) = sockets(ns, mode);
    let _echo = Echo::spawn(far);
    let frame = one_datagram_frame();
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let mut samples = Vec::with_capacity(rounds as usize);
    for round in 0..rounds + rounds / 10 {
        let started = Instant::now();
        near.send(&frame).expect("send");
        let wait = Wait::Until(Instant::now() + Duration::from_secs(1));
        near.recv(&mut buf, wait)
            .expect("recv")
            .expect("the echo answered");
        // The first tenth warms up caches and the scheduler.
        if round >= rounds / 10 {
            samples.push(started.elapsed());
        }
    }
    percentiles(&mut samples)
}

struct BusRow {
    caller: (f64, f64),
    bus_rtt: (f64, f64),
}

fn bus_config(near: &RawSocket, mode: WaitMode) -> BusConfig {
    BusConfig {
        source_mac: near.mac_address(),
        wait_mode: mode,
        response_timeout: Duration::from_millis(100),
        ..BusConfig::default()
    }
}

fn bus_one_datagram(ns: &NetNs, mode: WaitMode, rounds: u64) -> BusRow {
    let (near, far) = sockets(ns, mode);
    let _echo = Echo::spawn(far);
    let config = bus_config(&near, mode);
    let (bus, thread) = Bus::start(near, config).expect("start the bus");
    let mut samples = Vec::with_capacity(rounds as usize);
    for round in 0..rounds + rounds / 10 {
        let started = Instant::now();
        bus.fprd(0x1001, 0x0130, DATA_LEN).wait().expect("a reply");
        if round >= rounds / 10 {
            samples.push(started.elapsed());
        }
    }
    let stats = bus.stats();
    bus.shutdown();
    let _ = thread.join();
    BusRow {
        caller: percentiles(&mut samples),
        bus_rtt: (micros(stats.rtt_p50()), micros(stats.rtt_p99())),
    }
}

struct Throughput {
    datagrams_per_second: f64,
    datagrams_per_frame: f64,
}

fn bus_throughput(ns: &NetNs, mode: WaitMode, seconds: u64) -> Throughput {
    let (near, far) = sockets(ns, mode);
    let _echo = Echo::spawn(far);
    let config = bus_config(&near, mode);
    let (bus, thread) = Bus::start(near, config).expect("start the bus");
    let done = Arc::new(AtomicU64::new(0));
    let until = Instant::now() + Duration::from_secs(seconds);
    let started = Instant::now();
    std::thread::scope(|scope| {
        for submitter in 0..8u16 {
            let bus = bus.clone();
            let done = Arc::clone(&done);
            scope.spawn(move || {
                while Instant::now() < until {
                    bus.fprd(0x1001 + submitter, 0x0130, DATA_LEN)
                        .wait()
                        .expect("a reply");
                    done.fetch_add(1, Ordering::Relaxed);
                }
            });
        }
    });
    let elapsed = started.elapsed().as_secs_f64();
    let stats = bus.stats();
    bus.shutdown();
    let _ = thread.join();
    Throughput {
        datagrams_per_second: done.load(Ordering::Relaxed) as f64 / elapsed,
        datagrams_per_frame: stats.datagrams_sent as f64 / stats.frames_sent.max(1) as f64,
    }
}

fn main() {
    let rounds = env_or("BUS_BENCH_ROUNDS", 20_000);
    let seconds = env_or("BUS_BENCH_SECONDS", 2);
    let ns = NetNs::new();
    ns.add_veth_pair("master", "echo");
    let frame_len = one_datagram_frame().len();
    println!(
        "bus round trip over veth: one {}-byte datagram in a {frame_len}-byte frame, \
         {rounds} round trips per row (after {} warm-up)",
        DATA_LEN,
        rounds / 10
    );
    println!();
    println!(
        "{:<44} {:>10} {:>10} {:>10}",
        "path", "mode", "p50 µs", "p99 µs"
    );
    for mode in [WaitMode::Poll, WaitMode::BusyPoll] {
        let name = match mode {
            WaitMode::Poll => "poll",
            WaitMode::BusyPoll => "busy-poll",
        };
        let (p50, p99) = raw_ping_pong(&ns, mode, rounds);
        println!(
            "{:<44} {:>10} {:>10.1} {:>10.1}",
            "raw socket ping-pong (physical floor)", name, p50, p99
        );
        let row = bus_one_datagram(&ns, mode, rounds);
        println!(
            "{:<44} {:>10} {:>10.1} {:>10.1}",
            "bus, submit -> result (caller's view)", name, row.caller.0, row.caller.1
        );
        println!(
            "{:<44} {:>10} {:>10.1} {:>10.1}",
            "bus, send -> receive (bus histogram, ±12%)", name, row.bus_rtt.0, row.bus_rtt.1
        );
    }
    println!();
    println!(
        "{:<44} {:>10} {:>14} {:>14}",
        "throughput, 8 submitters", "mode", "datagrams/s", "datagrams/frame"
    );
    for mode in [WaitMode::Poll, WaitMode::BusyPoll] {
        let name = match mode {
            WaitMode::Poll => "poll",
            WaitMode::BusyPoll => "busy-poll",
        };
        let result = bus_throughput(&ns, mode, seconds);
        println!(
            "{:<44} {:>10} {:>14.0} {:>14.2}",
            "bus, each submitter waits for its result",
            name,
            result.datagrams_per_second,
            result.datagrams_per_frame
        );
    }
    // `ns` is dropped here, which deletes the namespace and the veth pair (also on a panic
    // above, while unwinding).
}
