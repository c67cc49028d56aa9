//! EoE frames and requests to the same slave take turns in its mailbox: frames go through
//! while a stream of SDO uploads keeps the request queue full (the owner gives the EoE queue
//! a turn after every request), and the uploads keep completing meanwhile.

use crate::mailbox_support;

use std::net::Ipv4Addr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use etherparse::{Icmpv4Type, NetSlice, PacketBuilder, SlicedPacket, TransportSlice};
use mailbox_support::{DRIVE, Rig};
use master_core::mailbox::IpSettings;

const MASTER_MAC: [u8; 6] = [0x02, 0x00, 0x00, 0x00, 0x00, 0x01];
const MASTER_IP: Ipv4Addr = Ipv4Addr::new(192, 168, 100, 1);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn eoe_frames_pass_while_sdo_uploads_keep_the_queue_full() {
    let rig = Rig::default_segment();
    let slave = rig.slave(DRIVE);
    let me = IpSettings {
        mac: Some([0x02, 0xEC, 0xAD, 0x00, 0x00, 0x30]),
        ip: Some(Ipv4Addr::new(192, 168, 100, 30)),
        subnet_mask: Some(Ipv4Addr::new(255, 255, 255, 0)),
        ..IpSettings::default()
    };
    slave.eoe_set_ip(&me).await.unwrap();

    let stop = Arc::new(AtomicBool::new(false));
    let uploads = Arc::new(AtomicU64::new(0));
    let mut storm = Vec::new();
    for _ in 0..4 {
        let (slave, stop, uploads) = (slave.clone(), Arc::clone(&stop), Arc::clone(&uploads));
        storm.push(tokio::spawn(async move {
            while !stop.load(Ordering::Relaxed) {
                // The identity's vendor ID: always there.
                slave.sdo_upload(0x1018, 1).await.unwrap();
                uploads.fetch_add(1, Ordering::Relaxed);
            }
        }));
    }
    // The storm is under way before the first frame.
    while uploads.load(Ordering::Relaxed) < 20 {
        tokio::task::yield_now().await;
    }

    let mut frames = slave.subscribe_eoe();
    let payload: Vec<u8> = (0..1000u32).map(|i| (i * 13) as u8).collect();
    for seq in 0..10u16 {
        let before = uploads.load(Ordering::Relaxed);
        let mut request = Vec::new();
        PacketBuilder::ethernet2(MASTER_MAC, me.mac.unwrap())
            .ipv4(MASTER_IP.octets(), me.ip.unwrap().octets(), 64)
            .icmpv4_echo_request(7, seq)
            .write(&mut request, &payload)
            .unwrap();
        // Nine fragments each way through the 128-byte mailboxes.
        tokio::time::timeout(Duration::from_secs(5), slave.eoe_send(&request))
            .await
            .expect("the frame is not starved by the uploads")
            .unwrap();
        let echo = tokio::time::timeout(Duration::from_secs(5), async {
            loop {
                let frame = frames.recv().await.unwrap();
                let packet = SlicedPacket::from_ethernet(&frame.frame).unwrap();
                if let (Some(NetSlice::Ipv4(_)), Some(TransportSlice::Icmpv4(icmp))) =
                    (&packet.net, &packet.transport)
                    && let Icmpv4Type::EchoReply(echo) = icmp.icmp_type()
                    && echo.seq == seq
                {
                    return icmp.payload().to_vec();
                }
            }
        })
        .await
        .expect("the reply comes back while the uploads go on");
        assert_eq!(echo, payload);
        assert!(
            uploads.load(Ordering::Relaxed) > before,
            "the uploads go on while the frame is sent"
        );
    }
    stop.store(true, Ordering::Relaxed);
    for task in storm {
        task.await.unwrap();
    }
    assert_eq!(slave.stats().eoe_reassembly_errors, 0);
}
