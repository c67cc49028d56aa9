//! Soak: a million ETG.8200 gateway requests against one `ecatd --simulate`, with ecatd's
//! resident memory sampled along the way. Memory must stay flat: every request's buffers
//! are given back, nothing grows per request (no queue, map or log that keeps something
//! for each one).
//!
//! ```text
//! cargo bench -p ecat-tests --bench gateway_soak
//! GATEWAY_SOAK_COUNT=100000 GATEWAY_SOAK_CLIENTS=2 cargo bench -p ecat-tests --bench gateway_soak
//! ```
//!
//! Each request is an SDO upload of 0x1018:01 (expedited) through the gateway's UDP port,
//! spread over the segment's CoE slaves by `GATEWAY_SOAK_CLIENTS` clients (default 4) in
//! parallel, `GATEWAY_SOAK_COUNT` requests in all (default 1,000,000). Printed: VmRSS
//! (from `/proc`) after a warm-up of 20,000 requests and at every tenth of the run, the
//! requests per second, and the growth from the warm-up to the end; the bench fails if
//! memory grew by more than `FLAT_KIB` (a leak of even 16 bytes per request would be 15
//! MiB here). Every answer is checked (the vendor ID). Not part of CI.
//!
//! ecatd is built in release for this bench (`server_support::bin_dir` builds release
//! binaries for an optimised caller).

#![allow(missing_docs)]

#[path = "../tests/server_support/mod.rs"]
mod server_support;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use master_core::wire::coe::{CoeRepr, SdoFrame, SdoPayload, SdoRequest, SdoResponse};
use master_core::wire::mailbox::MailboxType;
use server_support::Ecatd;
use server_support::gateway_client::{GatewayClient, coe_bytes};
use sim::topology::{Protocol, SIM_VENDOR_ID, Topology};

/// Requests before the first memory sample (allocator pools and caches filled).
const WARM_UP: usize = 20_000;
/// Growth of the resident set from the warm-up to the end that still counts as flat.
const FLAT_KIB: u64 = 4 << 10;

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

fn env(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
        .max(1)
}

/// Uploads 0x1018:01 from the slave at station `address` through the gateway; the value
/// of the expedited answer.
fn upload(client: &mut GatewayClient, address: u16, request: &[u8]) -> u32 {
    let reply = client.exchange(address, MailboxType::Coe, request);
    let sdo = SdoFrame::new_checked(&reply.data[..]).expect("an SDO frame");
    match SdoResponse::parse(&sdo).expect("an SDO response") {
        SdoResponse::InitiateUpload {
            payload: SdoPayload::Expedited(data),
            ..
        } => u32::from_le_bytes(data.try_into().expect("4 bytes")),
        other => panic!("unexpected answer {other:?}"),
    }
}

fn main() {
    let count = env("GATEWAY_SOAK_COUNT", 1_000_000);
    let clients = env("GATEWAY_SOAK_CLIENTS", 4);
    let topology = Topology::default_segment();
    let stations: Vec<u16> = topology
        .slaves
        .iter()
        .enumerate()
        .filter(|(_, s)| s.protocols.contains(&Protocol::Coe))
        .map(|(p, _)| 1001 + p as u16)
        .collect();
    let request = coe_bytes(&CoeRepr::SdoRequest(SdoRequest::InitiateUpload {
        index: 0x1018,
        subindex: 1,
        complete_access: false,
    }));
    let ecatd = Ecatd::start(&[]);
    let gateway = ecatd.gateway_addr();
    println!(
        "gateway soak: {count} SDO uploads of 0x1018:01 through the ETG.8200 gateway, \
         {clients} clients, ecatd --simulate (built-in segment)"
    );
    println!("ecatd VmRSS at start: {} KiB", rss_kib(&ecatd));

    let mut warm = GatewayClient::new(gateway);
    for i in 0..WARM_UP {
        assert_eq!(
            upload(&mut warm, stations[i % stations.len()], &request),
            SIM_VENDOR_ID
        );
    }
    let before = rss_kib(&ecatd);
    println!("ecatd VmRSS after {WARM_UP} warm-up requests: {before} KiB");

    let done = AtomicUsize::new(0);
    let tenth = (count / 10).max(1);
    let start = Instant::now();
    let mut samples = Vec::new();
    std::thread::scope(|scope| {
        for c in 0..clients {
            let (done, stations, request) = (&done, &stations, &request);
            scope.spawn(move || {
                let mut client = GatewayClient::new(gateway);
                let mut i = c;
                loop {
                    let n = done.fetch_add(1, Ordering::Relaxed);
                    if n >= count {
                        break;
                    }
                    let station = stations[i % stations.len()];
                    assert_eq!(upload(&mut client, station, request), SIM_VENDOR_ID);
                    i += 1;
                }
            });
        }
        // The sampler: this thread, at every tenth of the run.
        let mut next = tenth;
        while next <= count {
            let seen = done.load(Ordering::Relaxed).min(count);
            if seen >= next {
                let rss = rss_kib(&ecatd);
                let rate = seen as f64 / start.elapsed().as_secs_f64();
                println!("  {seen:>9} requests  VmRSS {rss:>7} KiB  {rate:>8.0} requests/s");
                samples.push(rss);
                next += tenth;
            } else {
                // Sampling period; the loop ends when the run does.
                std::thread::sleep(std::time::Duration::from_millis(50));
            }
        }
    });
    let elapsed = start.elapsed();
    let after = rss_kib(&ecatd);
    println!(
        "{count} requests in {:.1} s: {:.0} requests/s",
        elapsed.as_secs_f64(),
        count as f64 / elapsed.as_secs_f64()
    );
    println!(
        "ecatd VmRSS before {before} KiB, after {after} KiB ({:+} KiB), highest sample {} KiB",
        after as i64 - before as i64,
        samples.iter().max().copied().unwrap_or(after)
    );
    assert!(
        after <= before + FLAT_KIB,
        "ecatd's memory grew by {} KiB over {count} requests",
        after - before
    );
}
