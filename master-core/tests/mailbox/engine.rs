//! The engine itself: deadlines, the "mailbox full" hook that can replace polling,
//! removing slaves and shutting down.

use crate::mailbox_support;

use std::net::Ipv4Addr;
use std::time::Duration;

use etherparse::PacketBuilder;
use mailbox_support::{COE_STORE, DRIVE, EOE_PORT, Rig, bus_config, station};
use master_core::bus::Bus;
use master_core::link::FaultConfig;
use master_core::link::{Link, Wait};
use master_core::mailbox::{IpSettings, MailboxConfig, MailboxError};
use master_core::wire::command::Command;
use master_core::wire::datagram::Datagram;
use sim::device::coe::lock_dictionary;
use sim::device::eoe::{EoeService, IpConfig};
use sim::device::{MailboxStack, SlaveDevice};
use sim::link::InProcessLink;
use sim::topology::{Topology, build_with_handles};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

#[tokio::test]
async fn a_slave_that_is_gone_ends_in_a_timeout_not_a_hang() {
    let rig = Rig::default_segment();
    // The last slave: frames still come back through the others, its datagrams with
    // working counter 0.
    rig.segment().set_plugged(EOE_PORT, false);
    let slave = rig.slave(EOE_PORT).with_timeout(Duration::from_millis(300));
    let err = slave.eoe_get_ip().await.unwrap_err();
    assert!(
        matches!(err, MailboxError::Timeout { station: s, .. } if s == station(EOE_PORT)),
        "{err}"
    );
    assert_eq!(slave.stats().failed, 1);
    // The others are not held up.
    assert_eq!(
        rig.slave(COE_STORE).sdo_upload(0x2001, 0).await.unwrap(),
        0x1234_5678u32.to_le_bytes()
    );
}

#[tokio::test]
async fn a_mailbox_full_notification_replaces_polling() {
    let config = MailboxConfig {
        idle_poll: None,
        ..MailboxConfig::default()
    };
    let rig = Rig::start_with(
        &Topology::default_segment(),
        FaultConfig::default(),
        1,
        bus_config(),
        config,
        |_, _| {},
    );
    let slave = rig.slave(EOE_PORT);
    let me = IpSettings {
        mac: Some([2, 0, 0, 0, 0, 0x44]),
        ip: Some(Ipv4Addr::new(192, 168, 100, 44)),
        ..IpSettings::default()
    };
    slave.eoe_set_ip(&me).await.unwrap();
    let mut frames = slave.subscribe_eoe();
    let mut ping = Vec::new();
    PacketBuilder::ethernet2([2, 0, 0, 0, 0, 1], me.mac.unwrap())
        .ipv4([192, 168, 100, 1], me.ip.unwrap().octets(), 64)
        .icmpv4_echo_request(1, 1)
        .write(&mut ping, &[0x5A; 1000])
        .unwrap();
    slave.eoe_send(&ping).await.unwrap();
    // The answer's first fragment was read right behind the request's last one; the rest
    // wait in the slave's send mailbox: nobody polls.
    assert_eq!(slave.stats().eoe_frames_in, 0);
    rig.engine().notify_mailbox_full(station(EOE_PORT));
    let reply = tokio::time::timeout(Duration::from_secs(5), frames.recv())
        .await
        .expect("read on notification")
        .unwrap();
    assert_eq!(reply.station, station(EOE_PORT));
    assert_eq!(slave.stats().eoe_frames_in, 1);
}

#[tokio::test]
async fn removed_slaves_and_a_stopped_engine_refuse_requests() {
    let rig = Rig::default_segment();
    let drive = rig.slave(DRIVE);
    assert_eq!(
        rig.engine().stations(),
        vec![station(DRIVE), station(COE_STORE), station(EOE_PORT)]
    );
    assert!(rig.engine().remove_slave(station(DRIVE)));
    assert!(!rig.engine().remove_slave(station(DRIVE)));
    assert_eq!(
        rig.engine().slave(station(DRIVE)).unwrap_err(),
        MailboxError::UnknownSlave(station(DRIVE))
    );
    let err = drive.sdo_upload(0x1018, 1).await.unwrap_err();
    assert_eq!(err, MailboxError::Shutdown, "the old handle");
    let store = rig.slave(COE_STORE);
    assert!(store.sdo_upload(0x2001, 0).await.is_ok());
    rig.engine().shutdown();
    assert_eq!(
        store.sdo_upload(0x2001, 0).await.unwrap_err(),
        MailboxError::Shutdown
    );
}

/// A full-size Ethernet frame with a number in it.
fn numbered_frame(n: u8) -> Vec<u8> {
    let mut frame = vec![0xFF; 6];
    frame.extend_from_slice(&[2, 0, 0, 0, 0, 0x14, 0x88, 0xB5]);
    frame.extend((0..1486).map(|i| (i as u8) ^ n));
    frame
}

#[tokio::test]
async fn an_answer_behind_hundreds_of_unsolicited_messages_is_found_and_nothing_is_lost() {
    // The EoE port starts with 20 full-size frames to send (13 fragments each): far more
    // than its outbox holds, so a request's answer queues up behind them. Nothing reads
    // them before the test has subscribed: no idle polls, no "mailbox full" bits.
    let config = MailboxConfig {
        idle_poll: None,
        ..MailboxConfig::default()
    };
    let rig = Rig::start_without_status_bits(&Topology::default_segment(), config, |segment, _| {
        let mut eoe = EoeService::new(IpConfig::default());
        for n in 0..20 {
            eoe.queue_frame(numbered_frame(n)).unwrap();
        }
        segment
            .slave_mut(EOE_PORT)
            .unwrap()
            .replace_device(Box::new(
                SlaveDevice::new().with_mailbox(MailboxStack::new().with(eoe)),
            ));
    });
    let slave = rig.slave(EOE_PORT);
    let mut frames = slave.subscribe_eoe();
    assert_eq!(
        slave.stats().eoe_frames_in,
        0,
        "frames read before subscribing"
    );
    // A short frame to the slave, then a request: its answer comes after the fragments
    // queued before it, which go to the EoE receiver meanwhile.
    slave.eoe_send(&numbered_frame(99)[..60]).await.unwrap();
    assert_eq!(slave.eoe_get_ip().await.unwrap(), IpSettings::default());
    assert!(slave.stats().eoe_frames_in > 0);
    // The rest is read on notification; every frame arrives whole and in order.
    let mut received = Vec::new();
    while received.len() < 20 {
        slave.notify_mailbox_full();
        let frame = tokio::time::timeout(Duration::from_secs(5), frames.recv())
            .await
            .expect("the next frame")
            .unwrap();
        received.push(frame.frame);
    }
    for (n, frame) in received.iter().enumerate() {
        assert_eq!(*frame, numbered_frame(n as u8), "frame {n}");
    }
    let stats = slave.stats();
    assert_eq!(stats.eoe_frames_in, 20);
    assert_eq!((stats.unexpected, stats.eoe_reassembly_errors), (0, 0));
}

/// A link that makes a slave look as if its receive mailbox stayed full: the first
/// `stalls` writes to SM0 of `station` are turned into NOPs on the way out (so the slave
/// ignores them and the working counter stays 0) and turned back on the way in (so the bus
/// sees its own datagram come back).
struct StalledSm0<L: Link> {
    inner: L,
    station: u16,
    sm0: u16,
    stalls: Arc<AtomicUsize>,
}

impl<L: Link> StalledSm0<L> {
    /// Offsets of the datagrams with `command` to the store's SM0.
    fn sm0_datagrams(&self, frame: &[u8], command: Command) -> Vec<usize> {
        let mut found = Vec::new();
        let mut at = 16;
        while let Ok(datagram) = Datagram::new_checked(&frame[at.min(frame.len())..]) {
            if datagram.command() == command
                && datagram.adp() == self.station
                && datagram.ado() == self.sm0
            {
                found.push(at);
            }
            let more = datagram.more();
            at += datagram.total_len();
            if !more {
                break;
            }
        }
        found
    }
}

impl<L: Link> Link for StalledSm0<L> {
    fn send(&mut self, frame: &[u8]) -> std::io::Result<()> {
        let mut frame = frame.to_vec();
        let mut writes = self.sm0_datagrams(&frame, Command::Fpwr);
        writes.retain(|_| {
            self.stalls
                .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |n| n.checked_sub(1))
                .is_ok()
        });
        for &at in &writes {
            Datagram::new_unchecked(&mut frame[at..]).set_command(Command::Nop);
        }
        self.inner.send(&frame)
    }

    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> std::io::Result<Option<usize>> {
        // Whichever frame comes back: the stalled writes return as writes with WKC 0, what a
        // full mailbox answers, so the bus matches them to what it sent.
        let got = self.inner.recv(buf, wait)?;
        if let Some(len) = got {
            for at in self.sm0_datagrams(&buf[..len], Command::Nop) {
                Datagram::new_unchecked(&mut buf[at..]).set_command(Command::Fpwr);
            }
        }
        Ok(got)
    }
}

#[tokio::test]
async fn a_full_receive_mailbox_is_written_again_until_the_slave_takes_the_request() {
    let built = build_with_handles(&Topology::default_segment()).unwrap();
    let dict = built.slaves[COE_STORE].dictionary.clone().unwrap();
    let stalls = Arc::new(AtomicUsize::new(0));
    let link = StalledSm0 {
        inner: InProcessLink::new(built.segment),
        station: station(COE_STORE),
        sm0: 0x1000,
        stalls: Arc::clone(&stalls),
    };
    let (bus, _thread) = Bus::start(link, bus_config()).unwrap();
    let (master, slaves) = mailbox_support::scan_to_preop(&bus, MailboxConfig::default());
    let engine = master.mailbox_engine();
    let (_, config) = slaves.iter().find(|(p, _)| *p == COE_STORE).unwrap();
    assert_eq!(config.write.start, 0x1000);
    let store = engine.add_slave(*config);
    let before = lock_dictionary(&dict).write_count(0x2001);
    stalls.store(5, Ordering::Relaxed);
    store
        .sdo_download(0x2001, 0, &0xCAFE_BABEu32.to_le_bytes())
        .await
        .unwrap();
    assert_eq!(stalls.load(Ordering::Relaxed), 0);
    let stats = store.stats();
    assert_eq!(stats.write_full, 5, "{stats:?}");
    assert_eq!(stats.writes, 1);
    assert_eq!(lock_dictionary(&dict).write_count(0x2001), before + 1);
    assert_eq!(
        lock_dictionary(&dict).get::<u32>(0x2001, 0).unwrap(),
        0xCAFE_BABE
    );
    // With the mailbox full for longer than the deadline: a timeout, not a hang.
    stalls.store(usize::MAX, Ordering::Relaxed);
    let err = store
        .with_timeout(Duration::from_millis(100))
        .sdo_upload(0x2001, 0)
        .await
        .unwrap_err();
    assert!(matches!(err, MailboxError::Timeout { .. }), "{err}");
    engine.shutdown();
    bus.shutdown();
}

/// The CoE store's mailbox behind a [`StalledSm0`] link, scanned to PREOP with a request
/// queue of `queue_len` and no idle polling; `stalls` stalls its SM0 writes.
struct Stallable {
    bus: master_core::bus::BusHandle,
    master: master_core::master::Master,
    store: master_core::mailbox::SlaveMailbox,
    stalls: Arc<AtomicUsize>,
}

/// With the stall lifted, the store answers again; then the engine and the bus stop.
async fn recovers_then_stops(
    bus: &master_core::bus::BusHandle,
    engine: &master_core::mailbox::MailboxEngine,
    store: &master_core::mailbox::SlaveMailbox,
) {
    assert!(
        store
            .with_timeout(Duration::from_secs(5))
            .sdo_upload(0x2001, 0)
            .await
            .is_ok()
    );
    engine.shutdown();
    bus.shutdown();
}

fn stallable_store(queue_len: usize) -> Stallable {
    let built = build_with_handles(&Topology::default_segment()).unwrap();
    let stalls = Arc::new(AtomicUsize::new(0));
    let link = StalledSm0 {
        inner: InProcessLink::new(built.segment),
        station: station(COE_STORE),
        sm0: 0x1000,
        stalls: Arc::clone(&stalls),
    };
    // The bus thread ends with the bus's shutdown; its handle is not needed.
    let (bus, _thread) = Bus::start(link, bus_config()).unwrap();
    let config = MailboxConfig {
        queue_len,
        idle_poll: None,
        ..MailboxConfig::default()
    };
    let (master, slaves) = mailbox_support::scan_to_preop(&bus, config);
    let (_, slave_config) = slaves.iter().find(|(p, _)| *p == COE_STORE).unwrap();
    let store = master.mailbox_engine().add_slave(*slave_config);
    Stallable {
        bus,
        master,
        store,
        stalls,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_request_queue_refuses_at_once() {
    let Stallable {
        bus,
        master,
        store,
        stalls,
    } = stallable_store(1);
    let engine = master.mailbox_engine();
    let store = store.with_timeout(Duration::from_secs(1));
    // The first request is taken up and stuck writing; the second waits in the queue.
    stalls.store(usize::MAX, Ordering::Relaxed);
    let first = tokio::spawn({
        let store = store.clone();
        async move { store.sdo_upload(0x2001, 0).await }
    });
    mailbox_support::wait_until("the first request taken", Duration::from_secs(5), || {
        store.stats().requests == 1
    });
    let second = tokio::spawn({
        let store = store.clone();
        async move { store.sdo_upload(0x2001, 0).await }
    });
    mailbox_support::wait_until("the second request queued", Duration::from_secs(5), || {
        store.queued() == 1
    });
    let third = store.sdo_upload(0x2001, 0).await.unwrap_err();
    assert_eq!(third, MailboxError::QueueFull(station(COE_STORE)));
    assert!(matches!(
        first.await.unwrap(),
        Err(MailboxError::Timeout { .. })
    ));
    stalls.store(0, Ordering::Relaxed);
    // The queued one runs after the first gave up (its own deadline may have passed too).
    let _ = second.await.unwrap();
    recovers_then_stops(&bus, engine, &store).await;
}

#[tokio::test]
async fn an_owner_that_replaces_another_continues_its_counter() {
    let rig = Rig::default_segment();
    let first = rig.slave(COE_STORE);
    let config = *first.config();
    // Round r makes r + 1 requests, so the slave's last counter when the owner is replaced
    // differs from round to round; an owner that started at 1 again would sooner or later
    // send the slave's last counter, and the slave would discard it as a repetition.
    for round in 0..7u32 {
        let owner = rig.engine().add_slave(config);
        let value = 0x0101_0101u32.wrapping_mul(round + 1);
        owner
            .sdo_download(0x2001, 0, &value.to_le_bytes())
            .await
            .unwrap_or_else(|err| panic!("round {round}: {err}"));
        for _ in 0..round {
            assert_eq!(
                owner.sdo_upload(0x2001, 0).await.unwrap(),
                value.to_le_bytes()
            );
        }
        assert_eq!(owner.stats().failed, 0, "round {round}");
    }
}

/// Issue 35: a request whose deadline passes while a stalled request ahead of it holds the
/// slave is never sent, and says so (not a timeout of the slave's answer).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_request_whose_time_runs_out_in_the_queue_is_not_sent_and_says_so() {
    let Stallable {
        bus,
        master,
        store,
        stalls,
    } = stallable_store(MailboxConfig::default().queue_len);
    let engine = master.mailbox_engine();
    stalls.store(usize::MAX, Ordering::Relaxed);
    let first = tokio::spawn({
        let store = store.with_timeout(Duration::from_millis(800));
        async move { store.sdo_upload(0x2001, 0).await }
    });
    mailbox_support::wait_until("the first request taken", Duration::from_secs(5), || {
        store.stats().requests == 1
    });
    let second = tokio::spawn({
        let store = store.with_timeout(Duration::from_millis(200));
        async move { store.sdo_upload(0x2001, 0).await }
    });
    assert!(matches!(
        first.await.unwrap(),
        Err(MailboxError::Timeout { .. })
    ));
    let err = second.await.unwrap().unwrap_err();
    assert!(
        matches!(err, MailboxError::NotSent { station: s, waited_ms } if s == station(COE_STORE) && waited_ms >= 200),
        "{err}"
    );
    assert!(err.to_string().contains("not sent"), "{err}");
    stalls.store(0, Ordering::Relaxed);
    recovers_then_stops(&bus, engine, &store).await;
}
