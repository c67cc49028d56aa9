//! The engine itself: deadlines, the "mailbox full" hook that can replace polling,
//! removing slaves and shutting down.

mod mailbox_support;

use std::net::Ipv4Addr;
use std::time::Duration;

use etherparse::PacketBuilder;
use mailbox_support::{COE_STORE, DRIVE, EOE_PORT, Rig, bus_config, station};
use master_core::link::FaultConfig;
use master_core::mailbox::{IpSettings, MailboxConfig, MailboxError};
use sim::topology::Topology;

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
    rig.engine.notify_mailbox_full(station(EOE_PORT));
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
        rig.engine.stations(),
        vec![station(DRIVE), station(COE_STORE), station(EOE_PORT)]
    );
    assert!(rig.engine.remove_slave(station(DRIVE)));
    assert!(!rig.engine.remove_slave(station(DRIVE)));
    assert_eq!(
        rig.engine.slave(station(DRIVE)).unwrap_err(),
        MailboxError::UnknownSlave(station(DRIVE))
    );
    let err = drive.sdo_upload(0x1018, 1).await.unwrap_err();
    assert_eq!(err, MailboxError::Shutdown, "the old handle");
    let store = rig.slave(COE_STORE);
    assert!(store.sdo_upload(0x2001, 0).await.is_ok());
    rig.engine.shutdown();
    assert_eq!(
        store.sdo_upload(0x2001, 0).await.unwrap_err(),
        MailboxError::Shutdown
    );
}
