//! Many callers at once: 32 tasks issue mixed CoE/SoE/FoE/VoE requests to several slaves
//! while EoE frames flow on one of them. Every caller must get its own correct answer,
//! nothing may be lost or misrouted, and the simulator's write counters must show each SDO
//! download exactly once — on a clean wire and with 5 % of the frames lost.

use crate::mailbox_support;

use std::collections::HashMap;
use std::net::Ipv4Addr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use etherparse::{Icmpv4Type, PacketBuilder, SlicedPacket, TransportSlice};
use mailbox_support::{Rig, bus_config, station};
use master_core::link::FaultConfig;
use master_core::mailbox::{FoeOptions, IpSettings, MailboxConfig, SlaveMailbox};
use master_core::wire::soe::{ElementFlags, Idn};
use sim::device::coe::{SharedDictionary, lock_dictionary};
use sim::device::soe::defaults::{MANUFACTURER_VERSION, MANUFACTURER_VERSION_TEXT};
use sim::device::voe::VoeEcho;
use sim::topology::Topology;

/// Ten slaves: drives at 0 and 5, CoE stores at 3 and 8 (used through `OWNED`), EoE ports
/// at 4 and 9.
const SLAVES: usize = 10;
const DRIVES: [usize; 2] = [0, 5];
const TASKS: usize = 32;
const ROUNDS: usize = 10;

/// An SDO object one task owns (no other task writes it), so it can check what it reads.
#[derive(Debug, Clone, Copy)]
struct Owned {
    position: usize,
    index: u16,
    len: usize,
}

const OWNED: [Owned; 6] = [
    Owned {
        position: 3,
        index: 0x2000,
        len: 4096,
    },
    Owned {
        position: 3,
        index: 0x2001,
        len: 4,
    },
    Owned {
        position: 8,
        index: 0x2000,
        len: 300,
    },
    Owned {
        position: 8,
        index: 0x2001,
        len: 4,
    },
    Owned {
        position: 0,
        index: 0x607A,
        len: 4,
    },
    Owned {
        position: 5,
        index: 0x607A,
        len: 4,
    },
];

fn value(task: usize, round: usize, len: usize) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u8) ^ (task as u8).wrapping_mul(37) ^ (round as u8).wrapping_mul(101))
        .collect()
}

fn dictionary(rig: &Rig, position: usize) -> SharedDictionary {
    rig.handles[position].dictionary.clone().unwrap()
}

/// What one task does, by its number; returns the SDO downloads it made per object.
async fn task(
    n: usize,
    slaves: Arc<HashMap<usize, SlaveMailbox>>,
    dicts: Arc<HashMap<usize, SharedDictionary>>,
) -> Vec<((usize, u16), u32)> {
    let mut downloads = Vec::new();
    for round in 0..ROUNDS {
        match n % 8 {
            // SDO download and upload of an object of its own.
            0 | 1 if n / 8 * 2 + n % 8 < OWNED.len() => {
                let owned = OWNED[n / 8 * 2 + n % 8];
                let slave = &slaves[&owned.position];
                let data = value(n, round, owned.len);
                slave.sdo_download(owned.index, 0, &data).await.unwrap();
                downloads.push(((owned.position, owned.index), 1));
                assert_eq!(slave.sdo_upload(owned.index, 0).await.unwrap(), data);
            }
            // SDO uploads of identity entries, checked against the slave's dictionary.
            0..=2 => {
                let position = [0, 3, 5, 8][(n + round) % 4];
                let sub = (round % 4) as u8 + 1;
                let expected = lock_dictionary(&dicts[&position])
                    .get_bytes(0x1018, sub)
                    .unwrap()
                    .to_vec();
                let got = slaves[&position].sdo_upload(0x1018, sub).await.unwrap();
                assert_eq!(got, expected, "task {n}: 0x1018:{sub} of slave {position}");
            }
            // SoE: a write and read of its own IDN, and a constant one.
            3 => {
                let drive = &slaves[&DRIVES[(n / 8) % 2]];
                // S-0-0047 (4 bytes) and the default drive's S-0-0032 (4 bytes there).
                let idn = Idn::from_raw(if n / 8 < 2 { 47 } else { 32 });
                let data = if idn.raw() == 47 {
                    (n as i32 * 1000 + round as i32).to_le_bytes().to_vec()
                } else {
                    ((n * 10 + round) as u32).to_le_bytes().to_vec()
                };
                drive
                    .soe_write(0, idn, ElementFlags::VALUE, &data)
                    .await
                    .unwrap();
                assert_eq!(
                    drive.soe_read(0, idn, ElementFlags::VALUE).await.unwrap(),
                    data
                );
            }
            4 => {
                let drive = &slaves[&DRIVES[round % 2]];
                let text = drive
                    .soe_read(0, Idn::from_raw(MANUFACTURER_VERSION), ElementFlags::VALUE)
                    .await
                    .unwrap();
                assert_eq!(&text[4..], MANUFACTURER_VERSION_TEXT.as_bytes());
            }
            // FoE: a file of its own, written and read back.
            5 => {
                let drive = &slaves[&DRIVES[(n / 8) % 2]];
                let name = format!("task{n}.txt");
                let data = value(n, round, 1000 + 377 * round);
                drive
                    .foe_write(&name, &data, FoeOptions::default())
                    .await
                    .unwrap();
                assert_eq!(
                    drive.foe_read(&name, FoeOptions::default()).await.unwrap(),
                    data
                );
            }
            // VoE echo with data of its own.
            _ => {
                let drive = &slaves[&DRIVES[(n + round) % 2]];
                let data = value(n, round, 20 + n);
                let answer = drive.voe(0x1164, n as u16, &data).await.unwrap();
                assert_eq!(answer.vendor_type, n as u16);
                assert_eq!(answer.data, VoeEcho::transform(&data));
            }
        }
    }
    downloads
}

/// Pings the drive through EoE until told to stop; returns the replies matched.
async fn eoe_flow(drive: SlaveMailbox, me: IpSettings, stop: Arc<AtomicBool>) -> u64 {
    let mut frames = drive.subscribe_eoe();
    let mut seq = 0u16;
    let replies = AtomicU64::new(0);
    while !stop.load(Ordering::Relaxed) {
        seq += 1;
        let payload: Vec<u8> = (0..600u16).map(|i| (i as u8) ^ (seq as u8)).collect();
        let mut frame = Vec::new();
        PacketBuilder::ethernet2([2, 0, 0, 0, 0, 1], me.mac.unwrap())
            .ipv4([192, 168, 100, 1], me.ip.unwrap().octets(), 64)
            .icmpv4_echo_request(7, seq)
            .write(&mut frame, &payload)
            .unwrap();
        drive.eoe_send(&frame).await.unwrap();
        loop {
            let got = tokio::time::timeout(Duration::from_secs(10), frames.recv())
                .await
                .expect("the echo reply")
                .unwrap();
            let packet = SlicedPacket::from_ethernet(&got.frame).unwrap();
            if let Some(TransportSlice::Icmpv4(icmp)) = &packet.transport
                && let Icmpv4Type::EchoReply(echo) = icmp.icmp_type()
                && echo.seq == seq
            {
                assert_eq!(icmp.payload(), &payload[..]);
                replies.fetch_add(1, Ordering::Relaxed);
                break;
            }
        }
    }
    replies.load(Ordering::Relaxed)
}

async fn run_suite(faults: FaultConfig, seed: u64) -> Rig {
    let config = MailboxConfig {
        timeout: Duration::from_secs(20),
        ..MailboxConfig::default()
    };
    let rig = Rig::start_with(
        &Topology::repeated(SLAVES),
        faults,
        seed,
        bus_config(),
        config,
        |_, _| {},
    );
    let slaves: HashMap<usize, SlaveMailbox> = rig
        .slaves
        .iter()
        .map(|(position, _)| (*position, rig.slave(*position)))
        .collect();
    let dicts: HashMap<usize, SharedDictionary> = [0, 3, 5, 8]
        .into_iter()
        .map(|p| (p, dictionary(&rig, p)))
        .collect();
    let before: HashMap<(usize, u16), u32> = OWNED
        .iter()
        .map(|o| {
            let count = lock_dictionary(&dicts[&o.position]).write_count(o.index);
            ((o.position, o.index), count)
        })
        .collect();
    let drive = slaves[&0].clone();
    let me = IpSettings {
        mac: Some([2, 0xEC, 0, 0, 0, 1]),
        ip: Some(Ipv4Addr::new(192, 168, 100, 10)),
        ..IpSettings::default()
    };
    drive.eoe_set_ip(&me).await.unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let pinger = tokio::spawn(eoe_flow(drive, me, Arc::clone(&stop)));
    let slaves = Arc::new(slaves);
    let shared_dicts = Arc::new(dicts.clone());
    let tasks: Vec<_> = (0..TASKS)
        .map(|n| tokio::spawn(task(n, Arc::clone(&slaves), Arc::clone(&shared_dicts))))
        .collect();
    let mut issued: HashMap<(usize, u16), u32> = HashMap::new();
    for t in tasks {
        for (key, count) in t.await.unwrap() {
            *issued.entry(key).or_default() += count;
        }
    }
    stop.store(true, Ordering::Relaxed);
    let pings = pinger.await.unwrap();
    assert!(pings > 0, "EoE frames flowed during the run");
    for owned in OWNED {
        let key = (owned.position, owned.index);
        let now = lock_dictionary(&dicts[&owned.position]).write_count(owned.index);
        assert_eq!(
            now - before[&key],
            issued[&key],
            "downloads to {:#06x} on slave {}: each exactly once",
            owned.index,
            owned.position
        );
    }
    for (position, slave) in slaves.iter() {
        let stats = slave.stats();
        assert_eq!(stats.failed, 0, "slave {position}: {stats:?}");
        assert_eq!(stats.unexpected, 0, "slave {position}: {stats:?}");
        assert_eq!(stats.malformed, 0, "slave {position}: {stats:?}");
        assert_eq!(
            stats.eoe_reassembly_errors, 0,
            "slave {position}: {stats:?}"
        );
        assert_eq!(slave.station(), station(*position));
    }
    rig
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn thirty_two_callers_get_their_own_answers() {
    let rig = run_suite(FaultConfig::default(), 11).await;
    // Nothing is lost on this wire, but a busy machine can delay the bus thread past the
    // response timeout; a read counted lost then must have been recovered too.
    // Idle polls go on in the background: a read lost just now is recovered just after.
    for (position, _) in &rig.slaves {
        let slave = rig.slave(*position);
        mailbox_support::wait_until("lost reads recovered", Duration::from_secs(5), || {
            let stats = slave.stats();
            stats.repeats == stats.lost_reads
        });
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_same_with_five_percent_of_the_frames_lost() {
    let faults = FaultConfig {
        drop_tx: 0.025,
        drop_rx: 0.025,
        ..FaultConfig::default()
    };
    for seed in [0x5EED, 2, 3] {
        lossy_run(faults, seed).await;
    }
}

async fn lossy_run(faults: FaultConfig, seed: u64) {
    let rig = run_suite(faults, seed).await;
    let counts = rig.fault_counts();
    assert!(
        counts.tx_dropped > 20 && counts.rx_dropped > 20,
        "{counts:?}"
    );
    let totals = || {
        let stats: Vec<_> = rig
            .slaves
            .iter()
            .map(|(p, _)| rig.slave(*p).stats())
            .collect();
        let sum =
            |f: fn(&master_core::mailbox::MailboxStats) -> u64| stats.iter().map(f).sum::<u64>();
        (
            sum(|s| s.lost_reads),
            sum(|s| s.repeats),
            sum(|s| s.duplicates),
        )
    };
    // Idle polls go on in the background: a read lost just now is recovered just after.
    mailbox_support::wait_until(
        "each lost read recovered with a repeat",
        Duration::from_secs(5),
        || {
            let (lost, repeats, _) = totals();
            lost == repeats
        },
    );
    let (lost, repeats, duplicates) = totals();
    assert!(lost > 0, "reads of SM1 were lost");
    // A read lost on its way out leaves the message in SM1; the repeat then re-posts the
    // one before, which the slave's counter shows to be a duplicate.
    assert!(
        duplicates > 0 && duplicates <= repeats,
        "{duplicates} of {repeats}"
    );
}
