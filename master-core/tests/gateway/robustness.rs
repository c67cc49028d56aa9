//! 100,000 random and truncated datagrams against the gateway: nothing crashes, every one
//! is counted as failed (malformed), memory stays flat, and a client asking real questions
//! meanwhile gets every answer right.

use crate::gateway_support;

use std::sync::atomic::{AtomicBool, Ordering};

use gateway_support::master_support::wait_until;
use gateway_support::{COE_STORE, Client, GwRig, datagram, sdo, station, test_config};
use master_core::wire::coe::{SdoPayload, SdoRequest, SdoResponse};
use master_core::wire::gateway::GatewayMessage;
use master_core::wire::mailbox::MailboxType;

const DATAGRAMS: usize = 100_000;
/// Sent before waiting for the gateway to count them, so the socket's receive buffer (about
/// 200 KiB, some 90 small datagrams with the kernel's overhead) never overflows: a datagram
/// the kernel drops is never seen, let alone counted.
const BATCH: usize = 50;

/// Resident set size in bytes, from /proc.
fn rss() -> usize {
    let statm = std::fs::read_to_string("/proc/self/statm").expect("statm");
    let pages: usize = statm
        .split_whitespace()
        .nth(1)
        .and_then(|p| p.parse().ok())
        .expect("resident pages");
    pages * 4096
}

/// A datagram that is not a valid gateway message: random bytes, or a valid request cut
/// short, or one with a broken header field.
fn bad_datagram(rng: &mut fastrand::Rng, valid: &[Vec<u8>]) -> Vec<u8> {
    let out = match rng.u8(0..4) {
        0 => {
            let len = rng.usize(0..300);
            (0..len).map(|_| rng.u8(..)).collect()
        }
        1 => {
            let v = &valid[rng.usize(0..valid.len())];
            v[..rng.usize(0..v.len())].to_vec()
        }
        2 => {
            let mut v = valid[rng.usize(0..valid.len())].clone();
            let at = rng.usize(0..4);
            v[at] = rng.u8(..);
            v
        }
        _ => {
            let mut v = valid[rng.usize(0..valid.len())].clone();
            v[1] = (v[1] & 0x0F) | (rng.u8(0..16) << 4);
            v
        }
    };
    // Random bytes can form a valid message now and then; those are cut short.
    if GatewayMessage::new_checked(&out[..]).is_ok() {
        return out[..out.len().saturating_sub(1).min(7)].to_vec();
    }
    out
}

#[test]
fn a_flood_of_malformed_datagrams_is_counted_and_real_requests_are_still_served() {
    let rig = GwRig::start(test_config());
    let flood = Client::new(rig.addr());
    let address = station(COE_STORE);
    let request = sdo(SdoRequest::InitiateUpload {
        index: 0x1018,
        subindex: 2,
        complete_access: false,
    });
    let valid = vec![
        datagram(address, MailboxType::Coe, 1, &request),
        datagram(0, MailboxType::Coe, 2, &request),
        datagram(address, MailboxType::Foe, 3, &[1, 0, 0, 0, 0, 0, b'f']),
        datagram(address, MailboxType::Soe, 4, &[0x01, 0x40, 0x1E, 0x00]),
    ];
    let product = rig.topology.slaves[COE_STORE].product_code.to_le_bytes();
    let done = AtomicBool::new(false);
    let rss_before = rss();
    let answered = std::thread::scope(|s| {
        // Whatever happens below, the asker stops.
        struct Done<'a>(&'a AtomicBool);
        impl Drop for Done<'_> {
            fn drop(&mut self) {
                self.0.store(true, Ordering::Relaxed);
            }
        }
        let _done = Done(&done);
        let asker = s.spawn(|| {
            let mut client = rig.client();
            let mut answered = 0u64;
            while !done.load(Ordering::Relaxed) || answered == 0 {
                let reply = client.request(address, MailboxType::Coe, &request);
                assert_eq!(
                    reply.sdo(),
                    SdoResponse::InitiateUpload {
                        index: 0x1018,
                        subindex: 2,
                        complete_access: false,
                        payload: SdoPayload::Expedited(&product),
                    }
                );
                answered += 1;
            }
            answered
        });
        let mut rng = fastrand::Rng::with_seed(0x8200);
        let mut sent = 0;
        while sent < DATAGRAMS {
            for _ in 0..BATCH.min(DATAGRAMS - sent) {
                flood.send_raw(&bad_datagram(&mut rng, &valid));
                sent += 1;
            }
            let counted = sent as u64;
            assert!(
                wait_until(|| rig.gateway().stats().failures.malformed >= counted),
                "the gateway counted {:?} of {sent}",
                rig.gateway().stats().failures
            );
        }
        done.store(true, Ordering::Relaxed);
        asker.join().expect("the asker got every answer right")
    });
    let stats = rig.gateway().stats();
    assert_eq!(stats.failures.malformed, DATAGRAMS as u64);
    assert_eq!(stats.failed_requests, DATAGRAMS as u64);
    assert_eq!(stats.forwarded_requests, answered);
    assert_eq!(stats.total_requests, DATAGRAMS as u64 + answered);
    assert!(
        flood
            .recv_within(std::time::Duration::from_millis(50))
            .is_none(),
        "no malformed datagram was answered"
    );
    let growth = rss().saturating_sub(rss_before);
    assert!(growth < 16 << 20, "memory grew by {growth} bytes");
}
