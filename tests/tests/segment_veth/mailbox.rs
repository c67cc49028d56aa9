//! The mailbox engine over the veth rig: ecatd's master on a raw socket, `ecat-sim` in its
//! own namespace, every protocol end to end. Expected values come from the topology the
//! simulator was started with, built again here (`build_with_handles` is deterministic).
//!
//! The simulator runs a topology file written by the test: the default segment with FoE
//! BUSY phases on the drive's `*.bin` files, and one more drive with 32-byte mailboxes so
//! that SoE values travel in several fragments.
//!
//! Needs root and `ip`; see tests/README.md.

use std::net::Ipv4Addr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ecat_tests::rig::{Rig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use ecat_tests::veth_master::{VethMaster, open_socket};
use etherparse::{Icmpv4Type, NetSlice, PacketBuilder, SlicedPacket, TransportSlice};
use master_core::bus::BusConfig;
use master_core::link::{FaultConfig, FaultInjector};
use master_core::mailbox::{FoeOptions, FoeProgress, IpSettings, MailboxError, SlaveMailbox};
use master_core::master::{MasterConfig, SlaveAddress};
use master_core::od::Dictionary;
use master_core::wire::coe::AbortCode;
use master_core::wire::coe::info::OdListType;
use master_core::wire::foe::FoeError;
use master_core::wire::soe::{ElementFlags, Idn};
use sha2::{Digest, Sha256};
use sim::device::coe::lock_dictionary;
use sim::device::soe::defaults::{MANUFACTURER_VERSION, MANUFACTURER_VERSION_TEXT};
use sim::device::voe::VoeEcho;
use sim::topology::{FoeBusySpec, Topology, build_with_handles};

const DRIVE: u16 = 0;
const COE_STORE: u16 = 3;
const EOE_PORT: u16 = 4;
/// The extra drive with 32-byte mailboxes.
const SMALL_DRIVE: u16 = 5;
const PATIENCE: Duration = Duration::from_secs(60);

fn topology() -> Topology {
    let mut topology = Topology::default_segment();
    topology.slaves[usize::from(DRIVE)].foe_busy = Some(FoeBusySpec {
        after_write_request: 3,
        after_last_packet: 5,
        file_suffix: Some(".bin".to_owned()),
    });
    let mut small = topology.slaves[usize::from(DRIVE)].clone();
    small.name = "ECATD-SIM Drive (32-byte mailbox)".to_owned();
    small.serial = 6;
    small.foe_busy = None;
    small.eoe = None;
    let mailbox = small.mailbox.as_mut().expect("the drive has a mailbox");
    mailbox.rx_size = 32;
    mailbox.tx_size = 32;
    topology.slaves.push(small);
    topology
}

/// The rig, the simulator on `topology()`, and a scanned master.
struct Session {
    master: VethMaster,
    _sim: SimProcess,
    _rig: Rig,
}

impl Session {
    fn start() -> Session {
        Session::with_faults(None)
    }

    /// With `faults` injected into the master's link (seeded), from the scan on.
    fn with_faults(faults: Option<(FaultConfig, u64)>) -> Session {
        let file = std::env::temp_dir().join(format!(
            "ecatd-mailbox-veth-{}-{:?}.toml",
            std::process::id(),
            std::thread::current().id()
        ));
        std::fs::write(&file, topology().to_toml().expect("toml")).expect("topology file");
        let rig = Rig::new();
        let sim = SimProcess::start(
            &rig.sim,
            SIM_IFACE,
            &["--topology", file.to_str().expect("utf-8 path")],
        );
        let _ = std::fs::remove_file(&file);
        let master = match faults {
            None => VethMaster::start(&rig, MasterConfig::default()),
            Some((faults, seed)) => VethMaster::on_link(
                Box::new(FaultInjector::new(open_socket(&rig), faults, seed)),
                BusConfig::default(),
                MasterConfig::default(),
            ),
        };
        let report = master.scan();
        assert!(report.failures.is_empty(), "{:?}", report.failures);
        Session {
            master,
            _sim: sim,
            _rig: rig,
        }
    }

    fn mailbox(&self, position: u16) -> SlaveMailbox {
        self.master
            .master()
            .mailbox(SlaveAddress::Position(position))
            .expect("a mailbox slave")
            .with_timeout(PATIENCE)
    }

    fn run<F: std::future::Future>(&self, future: F) -> F::Output {
        self.master.within(PATIENCE, future)
    }
}

fn pattern(len: usize, seed: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u8).wrapping_mul(31).wrapping_add(seed))
        .collect()
}

#[test]
fn coe_over_veth() {
    let s = Session::start();
    let built = build_with_handles(&topology()).expect("topology builds");
    let store = s.mailbox(COE_STORE);
    // Downloads and uploads of every size class: expedited, normal, segmented both ways.
    for (n, len) in [1usize, 2, 4, 100, 4096].into_iter().enumerate() {
        let value = pattern(len, n as u8);
        s.run(store.sdo_download(0x2000, 0, &value))
            .unwrap_or_else(|e| panic!("download of {len} bytes: {e}"));
        assert_eq!(
            s.run(store.sdo_upload(0x2000, 0)).expect("upload"),
            value,
            "{len} bytes read back"
        );
    }
    // Identity and complete access, against the dictionary the simulator built.
    let drive = s.mailbox(DRIVE);
    let dict = built.slaves[usize::from(DRIVE)]
        .dictionary
        .clone()
        .expect("CoE");
    let entry = |sub: u8| {
        lock_dictionary(&dict)
            .get_bytes(0x1018, sub)
            .expect("0x1018")
            .to_vec()
    };
    assert_eq!(
        s.run(drive.sdo_upload(0x1018, 1)).expect("0x1018:01"),
        entry(1)
    );
    let mut whole = vec![entry(0)[0], 0];
    for sub in 1..=4 {
        whole.extend(entry(sub));
    }
    assert_eq!(
        s.run(drive.sdo_upload_complete(0x1018, 0)).expect("CA"),
        whole
    );
    // An abort reaches the caller with its code.
    assert_eq!(
        s.run(drive.sdo_upload(0x5FFF, 0)).unwrap_err(),
        MailboxError::SdoAbort {
            index: 0x5FFF,
            subindex: 0,
            code: AbortCode::ObjectDoesNotExist,
        }
    );
    // SDO Information: the object list equals the dictionary's, also when it comes in
    // fragments through the 32-byte mailbox.
    for position in [DRIVE, SMALL_DRIVE] {
        let dict = built.slaves[usize::from(position)]
            .dictionary
            .clone()
            .expect("CoE");
        let expected = Dictionary::indices(&*lock_dictionary(&dict), OdListType::All);
        let listed = s
            .run(s.mailbox(position).sdo_info_od_list(OdListType::All))
            .expect("OD list");
        assert_eq!(listed, expected, "slave {position}");
    }
}

#[test]
fn soe_foe_and_voe_over_veth() {
    let s = Session::start();
    // SoE: S-0-0030 (a 58-character text) through 32-byte mailboxes, in fragments.
    let small = s.mailbox(SMALL_DRIVE);
    let text = MANUFACTURER_VERSION_TEXT.as_bytes();
    let value = s
        .run(small.soe_read(0, Idn::from_raw(MANUFACTURER_VERSION), ElementFlags::VALUE))
        .expect("S-0-0030");
    assert_eq!(&value[4..], text);
    assert_eq!(
        usize::from(u16::from_le_bytes([value[0], value[1]])),
        text.len()
    );

    // FoE: 1 MiB written through BUSY phases and read back identical.
    let drive = s.mailbox(DRIVE);
    let content = pattern(1 << 20, 7);
    let reports = Arc::new(Mutex::new(Vec::new()));
    let options = FoeOptions {
        password: 0,
        progress: Some(Arc::new({
            let reports = Arc::clone(&reports);
            move |p| reports.lock().unwrap().push(p)
        })),
    };
    s.run(drive.foe_write("firmware.bin", &content, options.clone()))
        .expect("FoE write");
    let busy = reports
        .lock()
        .unwrap()
        .iter()
        .filter(|p| matches!(p, FoeProgress::Busy { .. }))
        .count();
    assert_eq!(busy, 3 + 5, "every BUSY phase reported");
    let read = s
        .run(drive.foe_read("firmware.bin", FoeOptions::default()))
        .expect("FoE read");
    assert_eq!(Sha256::digest(&read), Sha256::digest(&content));
    // The slave's FoE error, with its code and text.
    assert_eq!(
        s.run(drive.foe_read("missing.txt", FoeOptions::default()))
            .unwrap_err(),
        MailboxError::Foe {
            code: FoeError::NotFound,
            text: FoeError::NotFound.description().to_string()
        }
    );

    // VoE: the echo service answers with the data transformed.
    let data: Vec<u8> = (0..100u8).collect();
    let answer = s.run(drive.voe(0x1164, 0x0042, &data)).expect("VoE");
    assert_eq!((answer.vendor_id, answer.vendor_type), (0x1164, 0x0042));
    assert_eq!(answer.data, VoeEcho::transform(&data));
}

const MASTER_MAC: [u8; 6] = [0x02, 0x00, 0x00, 0x00, 0x00, 0x01];
const MASTER_IP: Ipv4Addr = Ipv4Addr::new(192, 168, 100, 1);

#[test]
fn eoe_over_veth() {
    let s = Session::start();
    let port = s.mailbox(EOE_PORT);
    let me = IpSettings {
        mac: Some([0x02, 0xEC, 0xAD, 0x00, 0x00, 0x24]),
        ip: Some(Ipv4Addr::new(192, 168, 100, 24)),
        subnet_mask: Some(Ipv4Addr::new(255, 255, 255, 0)),
        default_gateway: Some(MASTER_IP),
        dns_server: Some(Ipv4Addr::new(192, 168, 100, 53)),
        dns_name: Some("eoe-port".to_owned()),
    };
    s.run(port.eoe_set_ip(&me)).expect("Set IP");
    assert_eq!(s.run(port.eoe_get_ip()).expect("Get IP"), me);

    // An ICMP echo request, larger than the mailbox: fragmented both ways.
    let payload: Vec<u8> = (0..1000u32).map(|i| (i * 7) as u8).collect();
    let mut request = Vec::new();
    PacketBuilder::ethernet2(MASTER_MAC, me.mac.unwrap())
        .ipv4(MASTER_IP.octets(), me.ip.unwrap().octets(), 64)
        .icmpv4_echo_request(0x4242, 1)
        .write(&mut request, &payload)
        .expect("echo request");
    let mut frames = port.subscribe_eoe();
    s.run(port.eoe_send(&request)).expect("EoE send");
    let reply = s.run(async {
        loop {
            let frame = frames.recv().await.expect("EoE frames");
            let Ok(packet) = SlicedPacket::from_ethernet(&frame.frame) else {
                continue;
            };
            if let (Some(NetSlice::Ipv4(ip)), Some(TransportSlice::Icmpv4(icmp))) =
                (&packet.net, &packet.transport)
                && let Icmpv4Type::EchoReply(echo) = icmp.icmp_type()
                && echo.id == 0x4242
            {
                assert_eq!(ip.header().source_addr(), me.ip.unwrap());
                return icmp.payload().to_vec();
            }
        }
    });
    assert_eq!(reply, payload);
}

/// One caller's share of the mixed load: `rounds` requests of its kind, each answer checked.
async fn caller(task: usize, rounds: usize, slaves: [SlaveMailbox; 3], identity: Vec<u8>) {
    let [drive, store, small] = slaves;
    for round in 0..rounds {
        let tag = format!("task {task} round {round}");
        match task % 4 {
            0 => {
                let target = if round % 2 == 0 { &drive } else { &store };
                let vendor = target.sdo_upload(0x1018, 1).await.expect(&tag);
                assert_eq!(vendor, identity, "{tag}");
            }
            1 => {
                let data = pattern(40 + task, round as u8);
                let answer = drive.voe(0x1164, task as u16, &data).await.expect(&tag);
                assert_eq!(answer.vendor_type, task as u16, "{tag}");
                assert_eq!(answer.data, VoeEcho::transform(&data), "{tag}");
            }
            2 => {
                let value = small
                    .soe_read(0, Idn::from_raw(MANUFACTURER_VERSION), ElementFlags::VALUE)
                    .await
                    .expect(&tag);
                assert_eq!(&value[4..], MANUFACTURER_VERSION_TEXT.as_bytes(), "{tag}");
            }
            _ => {
                let name = format!("task{task}.txt");
                let content = pattern(600 + 37 * task, round as u8);
                drive
                    .foe_write(&name, &content, FoeOptions::default())
                    .await
                    .expect(&tag);
                let read = drive
                    .foe_read(&name, FoeOptions::default())
                    .await
                    .expect(&tag);
                assert_eq!(read, content, "{tag}");
            }
        }
    }
}

/// 32 callers with mixed CoE/SoE/FoE/VoE requests on three slaves while ICMP echoes flow
/// through EoE on the EoE port; every caller checks its own answers.
fn mixed_load(s: &Session) {
    let answered = mixed_load_answers(s);
    // The mailbox carries EoE reliably: every echo request is answered.
    assert_eq!(answered, 20, "ICMP echoes answered through EoE");
}

fn mixed_load_answers(s: &Session) -> usize {
    let identity = topology().slaves[0].vendor_id.to_le_bytes().to_vec();
    let port = s.mailbox(EOE_PORT);
    let me = IpSettings {
        mac: Some([0x02, 0xEC, 0xAD, 0x00, 0x00, 0x30]),
        ip: Some(Ipv4Addr::new(192, 168, 100, 30)),
        ..IpSettings::default()
    };
    s.run(port.eoe_set_ip(&me)).expect("Set IP");
    s.run(async {
        let mut tasks = tokio::task::JoinSet::new();
        for task in 0..32 {
            let slaves = [
                s.mailbox(DRIVE),
                s.mailbox(COE_STORE),
                s.mailbox(SMALL_DRIVE),
            ];
            tasks.spawn(caller(task, 5, slaves, identity.clone()));
        }
        // EoE traffic on the side, answered by the EoE port's endpoint.
        let mut frames = port.subscribe_eoe();
        let mut answered = 0;
        for seq in 0..20u16 {
            let mut request = Vec::new();
            PacketBuilder::ethernet2(MASTER_MAC, me.mac.unwrap())
                .ipv4(MASTER_IP.octets(), me.ip.unwrap().octets(), 64)
                .icmpv4_echo_request(0x5151, seq)
                .write(&mut request, &pattern(200, seq as u8))
                .expect("echo request");
            port.eoe_send(&request).await.expect("EoE send");
            while let Ok(Ok(frame)) =
                tokio::time::timeout(Duration::from_secs(10), frames.recv()).await
            {
                if let Ok(packet) = SlicedPacket::from_ethernet(&frame.frame)
                    && let Some(TransportSlice::Icmpv4(icmp)) = &packet.transport
                    && let Icmpv4Type::EchoReply(echo) = icmp.icmp_type()
                    && echo.id == 0x5151
                    && echo.seq == seq
                {
                    assert_eq!(icmp.payload(), pattern(200, seq as u8));
                    answered += 1;
                    break;
                }
            }
        }
        while let Some(joined) = tasks.join_next().await {
            joined.expect("a caller failed");
        }
        answered
    })
}

#[test]
fn thirty_two_callers_over_veth_get_their_own_answers() {
    mixed_load(&Session::start());
}

#[test]
fn the_same_over_veth_with_five_percent_of_the_frames_lost() {
    let faults = FaultConfig {
        drop_tx: 0.025,
        drop_rx: 0.025,
        ..FaultConfig::default()
    };
    let s = Session::with_faults(Some((faults, 0x5EED)));
    mixed_load(&s);
    let stats = s.master.master().bus().stats();
    assert!(stats.frames_lost > 0, "{stats:?}");
}
