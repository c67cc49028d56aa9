//! The pcap tap: a capture read back with pcap-file holds every frame sent and received,
//! byte for byte, as Ethernet packets.

use crate::bus_support;

use std::fs::File;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use bus_support::frames::{MIN_FRAME_LEN, test_frame};
use master_core::link::{Link, MAX_FRAME_LEN, MemoryLink, PcapTap, Wait};
use pcap_file::DataLink;
use pcap_file::pcap::PcapReader;

/// A capture file in cargo's scratch folder for integration tests, removed on drop.
struct TempCapture(PathBuf);

impl TempCapture {
    fn new(tag: &str) -> TempCapture {
        static NEXT: AtomicU32 = AtomicU32::new(0);
        let name = format!(
            "link-pcap-{tag}-{}-{}.pcap",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        );
        TempCapture(PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name))
    }

    /// Every packet in the file: (data, timestamp).
    fn packets(&self) -> Vec<(Vec<u8>, Duration)> {
        let mut reader = PcapReader::new(File::open(&self.0).unwrap()).unwrap();
        assert_eq!(reader.header().datalink, DataLink::ETHERNET);
        let mut packets = Vec::new();
        while let Some(packet) = reader.next_packet() {
            let packet = packet.unwrap();
            assert_eq!(packet.orig_len as usize, packet.data.len());
            packets.push((packet.data.into_owned(), packet.timestamp));
        }
        packets
    }
}

impl Drop for TempCapture {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// The far end echoes each frame back with the source MAC's locally-administered bit
/// flipped, as the first slave may do.
fn echo(far: &mut MemoryLink) {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let len = far
        .recv(&mut buf, Wait::NoWait)
        .unwrap()
        .expect("frame at the far end");
    buf[6] ^= 0x02;
    far.send(&buf[..len]).unwrap();
}

#[test]
fn link_pcap_tap_records_every_sent_and_received_frame() {
    const N: u32 = 50;
    let capture = TempCapture::new("both-ways");
    let (near, mut far) = MemoryLink::pair(4);
    let mut tap = PcapTap::create(near, &capture.0).unwrap();
    let mut buf = [0u8; MAX_FRAME_LEN];
    let mut expected = Vec::new();
    for seq in 0..N {
        let frame = test_frame(seq, MIN_FRAME_LEN + seq as usize);
        tap.send(&frame).unwrap();
        echo(&mut far);
        let deadline = Wait::Until(Instant::now() + Duration::from_secs(5));
        let len = tap.recv(&mut buf, deadline).unwrap().expect("echo");
        expected.push(frame);
        expected.push(buf[..len].to_vec());
    }
    // An empty recv records nothing.
    assert_eq!(tap.recv(&mut buf, Wait::NoWait).unwrap(), None);
    drop(tap);

    let packets = capture.packets();
    assert_eq!(packets.len(), 2 * N as usize, "N sent + N received");
    for (i, ((data, _), want)) in packets.iter().zip(&expected).enumerate() {
        assert_eq!(data, want, "packet {i}");
    }
    // Sent and received frames differ only in the flipped bit, so the order is checked too.
    assert_eq!(packets[1].0[6], packets[0].0[6] ^ 0x02);
    assert!(
        packets.windows(2).all(|w| w[0].1 <= w[1].1),
        "timestamps in order"
    );
}

#[test]
fn link_pcap_tap_flush_makes_the_capture_readable_while_the_tap_is_open() {
    let capture = TempCapture::new("flush");
    let (near, _far) = MemoryLink::pair(4);
    let mut tap = PcapTap::create(near, &capture.0).unwrap();
    for seq in 0..3 {
        tap.send(&test_frame(seq, MIN_FRAME_LEN)).unwrap();
    }
    tap.flush().unwrap();
    assert!(tap.capture_error().is_none());
    let packets = capture.packets();
    assert_eq!(packets.len(), 3);
    assert_eq!(packets[2].0, test_frame(2, MIN_FRAME_LEN));
}

#[test]
fn link_pcap_tap_create_names_the_file_it_could_not_create() {
    let (near, _far) = MemoryLink::pair(4);
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("no-such-dir/capture.pcap");
    let err = PcapTap::create(near, &path).unwrap_err();
    assert!(err.to_string().contains("no-such-dir"), "{err}");
}
