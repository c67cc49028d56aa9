//! EoE fragments from a slave arrive once and in order when chosen frames of the mailbox
//! traffic are lost, the in-process simulator behind a link that drops exactly the frames
//! a test names (no timing luck, no random loss).
//!
//! The case: the read of SM1 that carried a fragment of an echo reply reached the slave but
//! never came back, and the repeat procedure that recovers it (ETG.1000.4 §6.7, spec-notes
//! §mbx.repeat) cannot be carried out at once, because its first register read gets no
//! answer within the bus's retries (on the veth rig: a simulator not scheduled for longer
//! than `frame_timeout` × (retries + 1) on a loaded machine). The slave keeps the fragment
//! as its last message only until the master reads SM1 again, so the master must finish the
//! repeat before its next read of SM1; reading on would lose the fragment for good and
//! drop the frame in reassembly.

use crate::mailbox_support;

use std::net::Ipv4Addr;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use etherparse::{Icmpv4Type, NetSlice, PacketBuilder, SlicedPacket, TransportSlice};
use mailbox_support::{DRIVE, scan_to_preop, station};
use master_core::bus::{Bus, BusConfig};
use master_core::link::{Link, Wait};
use master_core::mailbox::{IpSettings, MailboxConfig, SlaveMailbox};
use master_core::wire::command::Command;
use master_core::wire::eoe::{EoeFrameType, EoePacket, FragmentRepr};
use master_core::wire::frame::EthercatFrame;
use master_core::wire::mailbox::{HEADER_LEN, Mailbox, MailboxHeader, MailboxType};
use sim::link::{InProcessLink, SharedSegment};
use sim::topology::{Topology, build_with_handles};

const MASTER_MAC: [u8; 6] = [0x02, 0x00, 0x00, 0x00, 0x00, 0x01];
const MASTER_IP: Ipv4Addr = Ipv4Addr::new(192, 168, 100, 1);
/// SM1 status and activate: the first register the repeat procedure reads.
const SM1_STATUS: u16 = 0x080D;
/// SM1 PDI control: the repeat acknowledge the procedure waits for.
const SM1_PDI_CONTROL: u16 = 0x080F;
/// Tries of a frame on the bus: the first and [`BusConfig::retries`] more.
const RETRIES: u32 = 3;

/// How the first try of the repeat procedure fails, each time on every try of the bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RepeatLoss {
    /// Its first read (0x080D) never reaches the slave: nothing was asked.
    StartNeverArrives,
    /// The slave toggles its acknowledge and re-posts the message, but no read of the
    /// acknowledge (0x080F) comes back: the next try asks a second time, and the slave
    /// posts the same message again.
    AckNeverReturns,
}

/// What the link does to the frames, step by step.
#[derive(Debug)]
struct Script {
    /// The station whose mailbox is watched, and its SM1 start.
    target: Option<(u16, u16)>,
    /// Step 1: the reply to the read of SM1 that brought this EoE fragment number is lost.
    lose_read_of_fragment: u8,
    /// Step 2: how the repeat that follows fails.
    repeat_loss: RepeatLoss,
    /// The EoE fragment numbers the slave was read out with, in the order read.
    read_fragments: Vec<u8>,
    /// What was done: replies of SM1 reads lost, frames of the repeat procedure lost.
    lost_reads: u32,
    lost_repeat_frames: u32,
}

/// The EoE fragment number of what a read of SM1 returned, if it is an EoE fragment.
fn fragment_number(sm1: &[u8]) -> Option<u8> {
    let header = Mailbox::new_checked(sm1)
        .and_then(|m| MailboxHeader::parse(&m))
        .ok()?;
    if header.mailbox_type != MailboxType::Eoe {
        return None;
    }
    let data = sm1.get(HEADER_LEN..HEADER_LEN + usize::from(header.length))?;
    let packet = EoePacket::new_checked(data).ok()?;
    if packet.frame_type() != EoeFrameType::Fragment {
        return None;
    }
    FragmentRepr::parse(&packet).ok().map(|f| f.fragment_number)
}

impl Script {
    fn new(lose_read_of_fragment: u8, repeat_loss: RepeatLoss) -> Script {
        Script {
            target: None,
            lose_read_of_fragment,
            repeat_loss,
            read_fragments: Vec::new(),
            lost_reads: 0,
            lost_repeat_frames: 0,
        }
    }

    /// Whether `frame` carries a read of register `register` of the watched slave, while
    /// step 2 has tries left to lose.
    fn repeat_frame_to_lose(&self, frame: &[u8], register: u16) -> bool {
        let Some((target, _)) = self.target else {
            return false;
        };
        self.lost_reads == 1
            && self.lost_repeat_frames <= RETRIES
            && datagrams(frame).iter().any(|(command, adp, ado, _, _)| {
                *command == Command::Fprd && *adp == target && *ado == register
            })
    }

    /// Whether the outgoing `frame` is lost on its way to the slave.
    fn lose_outgoing(&mut self, frame: &[u8]) -> bool {
        let lose = self.repeat_loss == RepeatLoss::StartNeverArrives
            && self.repeat_frame_to_lose(frame, SM1_STATUS);
        self.lost_repeat_frames += u32::from(lose);
        lose
    }

    /// Whether the returning `frame` is lost on its way back to the master.
    fn lose_returning(&mut self, frame: &[u8]) -> bool {
        let Some((target, sm1)) = self.target else {
            return false;
        };
        if self.repeat_loss == RepeatLoss::AckNeverReturns
            && self.repeat_frame_to_lose(frame, SM1_PDI_CONTROL)
        {
            self.lost_repeat_frames += 1;
            return true;
        }
        let mut lose = false;
        for (command, adp, ado, data, wkc) in datagrams(frame) {
            if command != Command::Fprd || adp != target || ado != sm1 || wkc != 1 {
                continue;
            }
            let Some(number) = fragment_number(&data) else {
                continue;
            };
            self.read_fragments.push(number);
            if number == self.lose_read_of_fragment && self.lost_reads == 0 {
                self.lost_reads += 1;
                lose = true;
            }
        }
        lose
    }
}

/// The datagrams of an EtherCAT frame: command, ADP, ADO, data, working counter.
fn datagrams(frame: &[u8]) -> Vec<(Command, u16, u16, Vec<u8>, u16)> {
    let Ok(parsed) = EthercatFrame::parse(frame) else {
        return Vec::new();
    };
    let Ok(chain) = parsed.datagrams() else {
        return Vec::new();
    };
    chain
        .filter_map(Result::ok)
        .map(|d| {
            let adp = (d.address & 0xFFFF) as u16;
            let ado = (d.address >> 16) as u16;
            (d.command, adp, ado, d.data.to_vec(), d.wkc)
        })
        .collect()
}

fn lock(script: &Mutex<Script>) -> MutexGuard<'_, Script> {
    script.lock().unwrap_or_else(|p| p.into_inner())
}

/// The in-process link, losing what the script says.
struct Scripted {
    inner: InProcessLink,
    script: Arc<Mutex<Script>>,
}

impl Link for Scripted {
    fn send(&mut self, frame: &[u8]) -> std::io::Result<()> {
        if lock(&self.script).lose_outgoing(frame) {
            return Ok(());
        }
        self.inner.send(frame)
    }

    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> std::io::Result<Option<usize>> {
        loop {
            match self.inner.recv(buf, wait)? {
                Some(len) if lock(&self.script).lose_returning(&buf[..len]) => continue,
                other => return Ok(other),
            }
        }
    }
}

fn echo_request(to: &IpSettings, seq: u16, payload: &[u8]) -> Vec<u8> {
    let mut frame = Vec::new();
    PacketBuilder::ethernet2(MASTER_MAC, to.mac.unwrap())
        .ipv4(MASTER_IP.octets(), to.ip.unwrap().octets(), 64)
        .icmpv4_echo_request(0x4242, seq)
        .write(&mut frame, payload)
        .unwrap();
    frame
}

/// Sends an echo request through EoE; the payload of the reply, or `None` if none came.
async fn ping(slave: &SlaveMailbox, to: &IpSettings, seq: u16, payload: &[u8]) -> Option<Vec<u8>> {
    let mut frames = slave.subscribe_eoe();
    slave
        .eoe_send(&echo_request(to, seq, payload))
        .await
        .unwrap();
    loop {
        let frame = tokio::time::timeout(Duration::from_secs(3), frames.recv())
            .await
            .ok()?
            .unwrap();
        let packet = SlicedPacket::from_ethernet(&frame.frame).unwrap();
        if let (Some(NetSlice::Ipv4(_)), Some(TransportSlice::Icmpv4(icmp))) =
            (&packet.net, &packet.transport)
            && let Icmpv4Type::EchoReply(echo) = icmp.icmp_type()
            && echo.seq == seq
        {
            return Some(icmp.payload().to_vec());
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fragment_whose_read_is_lost_and_whose_repeat_never_reaches_the_slave_at_first() {
    fragment_arrives_once_and_in_order(RepeatLoss::StartNeverArrives).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fragment_whose_read_is_lost_and_whose_repeat_is_asked_for_twice() {
    fragment_arrives_once_and_in_order(RepeatLoss::AckNeverReturns).await;
}

/// The reply to a 1400-byte echo request comes back in more than a dozen fragments
/// through the drive's SM1. The read that brought its fragment 2 is lost on the way back,
/// and the first try of the repeat procedure fails as `repeat_loss` says. The echo reply
/// still arrives whole: fragment 2 read again after the repeat (once, however often the
/// slave re-posted it), then the rest in order, and no reassembly error.
async fn fragment_arrives_once_and_in_order(repeat_loss: RepeatLoss) {
    let built = build_with_handles(&Topology::default_segment()).expect("topology builds");
    let segment: SharedSegment = Arc::new(Mutex::new(built.segment));
    let script = Arc::new(Mutex::new(Script::new(2, repeat_loss)));
    let link = Scripted {
        inner: InProcessLink::shared(Arc::clone(&segment), 64),
        script: Arc::clone(&script),
    };
    let bus_config = BusConfig {
        response_timeout: Duration::from_millis(2),
        retries: RETRIES,
        ..BusConfig::default()
    };
    let (bus, _thread) = Bus::start(link, bus_config).expect("bus starts");
    let (master, slaves) = scan_to_preop(&bus, MailboxConfig::default());
    let slave = master
        .mailbox(master_core::master::SlaveAddress::Position(DRIVE as u16))
        .expect("the drive has a mailbox");
    let (_, config) = slaves
        .iter()
        .find(|(position, _)| *position == DRIVE)
        .expect("the drive");
    assert_eq!(config.station, station(DRIVE));
    let me = IpSettings {
        mac: Some([0x02, 0xEC, 0xAD, 0x00, 0x00, 0x41]),
        ip: Some(Ipv4Addr::new(192, 168, 100, 41)),
        subnet_mask: Some(Ipv4Addr::new(255, 255, 255, 0)),
        ..IpSettings::default()
    };
    slave.eoe_set_ip(&me).await.unwrap();

    // From now on the script acts.
    lock(&script).target = Some((config.station, config.read.start));
    let payload: Vec<u8> = (0..1400u32).map(|i| (i * 13) as u8).collect();
    let echo = ping(&slave, &me, 1, &payload).await;

    let script = lock(&script);
    assert_eq!(
        (script.lost_reads, script.lost_repeat_frames),
        (1, RETRIES + 1),
        "the lost read and every try of the first repeat's frame: {script:?}"
    );
    let stats = slave.stats();
    assert_eq!(stats.eoe_reassembly_errors, 0, "{stats:?} {script:?}");
    assert_eq!(echo.as_deref(), Some(&payload[..]), "{stats:?} {script:?}");
    assert_eq!(stats.eoe_frames_in, 1, "{stats:?}");
    // Read on the wire: fragment 2 lost, then re-posted by the repeat (one lost read, one
    // repeat carried out in the end, nothing the counter had to drop), and every fragment
    // read in order from then on.
    assert_eq!(
        (stats.lost_reads, stats.repeats, stats.duplicates),
        (1, 1, 0),
        "{stats:?}"
    );
    let fragments = &script.read_fragments;
    let last = *fragments.last().expect("fragments were read");
    assert!(last > 2, "fragment 2 is not the last: {fragments:?}");
    let expected: Vec<u8> = (0..=2).chain(2..=last).collect();
    assert_eq!(fragments, &expected, "fragment numbers read from SM1");
    drop(script);
    master.mailbox_engine().shutdown();
    bus.shutdown();
}
