//! Issue 7's first acceptance point through the ecatd process: a plain UDP socket talks to
//! `ecatd --simulate`'s ETG.8200 gateway (messages built and parsed with
//! `master_core::wire`). Every protocol, the master's dictionary at address 0, position and
//! broadcast addressing, the error table, strict mode, the allowlist, stop and restart
//! through the API, the port of master number 2 with its fallback, and broadcasts beside
//! another client's transfer (issue 35). Expected values come
//! from `Topology::default_segment()`.

use crate::server_support;

use std::collections::BTreeMap;
use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use master_core::gateway::BROADCAST_ADDRESS;
use master_core::master_od::MasterIdentity;
use master_core::wire::Emit;
use master_core::wire::coe::{
    AbortCode, CoeRepr, DataType, ObjectCode, SdoPayload, SdoRequest, SdoResponse,
    max_initiate_data, max_segment_data,
};
use master_core::wire::foe::{self, FoePacket, FoeRepr};
use master_core::wire::mailbox::{ErrorReply, ErrorReplyRepr, MailboxErrorCode, MailboxType};
use master_core::wire::soe::{
    ElementFlags, Idn, IdnOrFragments, SoeError, SoeOpcode, SoePacket, SoeRepr,
};
use master_core::wire::voe::{VoePacket, VoeRepr};
use serde_json::Value;
use server_support::gateway_client::{
    EntrySummary, GatewayClient, Reply, coe_bytes, object_missing,
};
use server_support::{Ecatd, call, curl};
use sha2::{Digest, Sha256};
use sim::topology::{Protocol, Topology};

/// Station addresses of the default segment (1001 + position).
const DRIVE: u16 = 1001;
const COE_STORE: u16 = 1004;
const EOE_PORT: u16 = 1005;
/// The second drive of [`two_drives`], after the default segment.
const DRIVE_2: u16 = 1006;
/// The simulated slaves' mailbox size (default segment: 128/128).
const MAILBOX: usize = 128;
/// How long a test waits to be sure that no reply comes.
const SILENCE: Duration = Duration::from_secs(1);

/// The simulator's fill pattern of sized objects (byte i = i mod 251).
fn pattern(size: usize) -> Vec<u8> {
    (0..size).map(|i| (i % 251) as u8).collect()
}

/// `GET /api/v1/gateway`.
fn gateway_view(ecatd: &Ecatd) -> Value {
    let (status, body) = curl(&["-s", &format!("{}/api/v1/gateway", ecatd.http)]);
    assert_eq!(status, 200, "{body}");
    serde_json::from_str(&body).expect("JSON")
}

/// Polls the gateway's state until `done` holds (datagrams without an answer are counted
/// asynchronously) or a deadline passes; returns the last state.
fn wait_for_gateway(ecatd: &Ecatd, done: impl Fn(&Value) -> bool) -> Value {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let view = gateway_view(ecatd);
        if done(&view) || Instant::now() > deadline {
            return view;
        }
        // Poll interval; the loop ends on the condition or the deadline.
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A sample of `/metrics`.
fn metric(ecatd: &Ecatd, series: &str) -> f64 {
    let (status, text) = curl(&["-s", &format!("{}/metrics", ecatd.http)]);
    assert_eq!(status, 200);
    text.lines()
        .find_map(|line| line.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
        .unwrap_or_else(|| panic!("no sample {series} in:\n{text}"))
}

fn loopback(port: u16) -> SocketAddr {
    SocketAddr::from((Ipv4Addr::LOCALHOST, port))
}

/// Starts ecatd with a configuration file holding `toml`.
fn start_with_config(name: &str, toml: &str, extra: &[&str]) -> Ecatd {
    let file =
        std::env::temp_dir().join(format!("ecatd-gateway-{name}-{}.toml", std::process::id()));
    std::fs::write(&file, toml).unwrap();
    let mut args = vec!["--config", file.to_str().unwrap()];
    args.extend_from_slice(extra);
    let ecatd = Ecatd::start(&args);
    std::fs::remove_file(&file).unwrap();
    ecatd
}

fn abort_of(reply: &Reply) -> (u16, u8, u32) {
    match reply.coe() {
        CoeRepr::SdoResponse(SdoResponse::Abort {
            index,
            subindex,
            code,
        }) => (index, subindex, u32::from(code)),
        other => panic!("not an abort: {other:?}"),
    }
}

fn upload_request(index: u16, subindex: u8) -> CoeRepr<'static> {
    CoeRepr::SdoRequest(SdoRequest::InitiateUpload {
        index,
        subindex,
        complete_access: false,
    })
}

fn soe_bytes(repr: &SoeRepr<'_>) -> Vec<u8> {
    repr.to_vec().expect("emit SoE")
}

fn soe_of(reply: &Reply) -> SoeRepr<'_> {
    assert_eq!(reply.header.mailbox_type, MailboxType::Soe, "{reply:?}");
    SoeRepr::parse(&SoePacket::new_checked(&reply.data[..]).expect("SoE")).expect("parsable")
}

fn soe_read_request(idn: u16) -> Vec<u8> {
    soe_bytes(&SoeRepr {
        opcode: SoeOpcode::ReadRequest,
        drive: 0,
        elements: ElementFlags::VALUE,
        idn_or_fragments: IdnOrFragments::Idn(Idn::from_raw(idn)),
        error: None,
        data: &[],
    })
}

fn foe_bytes(repr: &FoeRepr<'_>) -> Vec<u8> {
    repr.to_vec().expect("emit FoE")
}

fn foe_of(reply: &Reply) -> FoeRepr<'_> {
    assert_eq!(reply.header.mailbox_type, MailboxType::Foe, "{reply:?}");
    FoeRepr::parse(&FoePacket::new_checked(&reply.data[..]).expect("FoE")).expect("parsable")
}

fn mailbox_error_of(reply: &Reply) -> MailboxErrorCode {
    assert_eq!(reply.header.mailbox_type, MailboxType::Error, "{reply:?}");
    let view = ErrorReply::new_checked(&reply.data[..]).expect("error reply");
    ErrorReplyRepr::parse(&view).expect("parsable").detail
}

/// Writes `content` as FoE file `name`, one datagram per packet; a packet shorter than a
/// full one (empty if need be) ends the file.
fn foe_write(client: &mut GatewayClient, address: u16, name: &str, content: &[u8]) {
    let request = foe_bytes(&FoeRepr::WriteRequest {
        password: 0,
        file_name: name.as_bytes(),
    });
    let reply = client.exchange(address, MailboxType::Foe, &request);
    assert_eq!(foe_of(&reply), FoeRepr::Ack { packet: 0 });
    let full = foe::max_data(MAILBOX);
    // One more packet than full ones: the last is short (possibly empty).
    for (i, start) in (0..=content.len()).step_by(full).enumerate() {
        let packet = u32::try_from(i + 1).unwrap();
        let chunk = &content[start..(start + full).min(content.len())];
        let data = foe_bytes(&FoeRepr::Data {
            packet,
            data: chunk,
        });
        let reply = client.exchange(address, MailboxType::Foe, &data);
        assert_eq!(foe_of(&reply), FoeRepr::Ack { packet });
    }
}

/// Reads FoE file `name`; the ACK of the last (short) packet gets no answer.
fn foe_read(client: &mut GatewayClient, address: u16, name: &str, limit: usize) -> Vec<u8> {
    let request = foe_bytes(&FoeRepr::ReadRequest {
        password: 0,
        file_name: name.as_bytes(),
    });
    client.send(address, MailboxType::Foe, &request);
    let first = client.recv();
    foe_read_on(client, address, &first, limit)
        .unwrap_or_else(|| panic!("{name} is longer than {limit} bytes"))
}

/// Goes on with an FoE read whose packet 1 is `first` (a reply from `address`): ACKs each
/// packet, the short one last, whose ACK gets no answer. The file, or `None` if it is
/// longer than `limit`.
fn foe_read_on(
    client: &mut GatewayClient,
    address: u16,
    first: &Reply,
    limit: usize,
) -> Option<Vec<u8>> {
    let full = foe::max_data(MAILBOX);
    let mut content = Vec::new();
    let mut reply = first.clone();
    for expected in 1..=u32::try_from(limit / full + 1).unwrap() {
        let (packet, data) = match foe_of(&reply) {
            FoeRepr::Data { packet, data } => (packet, data.to_vec()),
            other => panic!("packet {expected}: {other:?}"),
        };
        assert_eq!(packet, expected);
        content.extend_from_slice(&data);
        client.send(
            address,
            MailboxType::Foe,
            &foe_bytes(&FoeRepr::Ack { packet }),
        );
        if data.len() < full {
            assert!(
                client.recv_within(SILENCE).is_none(),
                "the last ACK is not answered"
            );
            return Some(content);
        }
        reply = client.recv();
    }
    None
}

#[test]
fn coe_through_ecatd_reaches_the_simulators_dictionaries() {
    let ecatd = Ecatd::start(&[]);
    let topology = Topology::default_segment();
    let mut client = GatewayClient::new(ecatd.gateway_addr());

    // Expedited upload on the drive: device type and vendor ID from the topology.
    let drive = &topology.slaves[0];
    assert_eq!(
        client.sdo_upload(DRIVE, 0x1000, 0),
        Ok(drive.device_type.to_le_bytes().to_vec())
    );
    assert_eq!(
        client.sdo_upload(DRIVE, 0x1018, 1),
        Ok(drive.vendor_id.to_le_bytes().to_vec())
    );
    // Normal (non-expedited) upload of the drive's name.
    assert_eq!(
        client.sdo_upload(DRIVE, 0x1008, 0),
        Ok(drive.name.as_bytes().to_vec())
    );

    // Expedited download on the drive, read back (in PREOP: in OP the cyclic outputs
    // overwrite the RxPDO-mapped 0x607A).
    let preop = call(
        &ecatd.grpc,
        &[],
        "ecat.v1.BusService/RequestState",
        r#"{"slave":"0","state":"AL_STATE_PREOP"}"#,
    )
    .unwrap();
    assert_eq!(preop["slave"]["state"], "AL_STATE_PREOP");
    assert_eq!(
        client.sdo_download(DRIVE, 0x607A, 0, &(-123_456i32).to_le_bytes(), MAILBOX),
        Ok(())
    );
    assert_eq!(
        client.sdo_upload(DRIVE, 0x607A, 0),
        Ok((-123_456i32).to_le_bytes().to_vec())
    );

    // Expedited download and upload on the CoE store's 0x2001.
    let store = &topology.slaves[3];
    let parameter = store.objects.iter().find(|o| o.index == 0x2001).unwrap();
    let initial = parameter
        .value
        .as_ref()
        .and_then(|v| v.as_integer())
        .unwrap() as u32;
    assert_eq!(
        client.sdo_upload(COE_STORE, 0x2001, 0),
        Ok(initial.to_le_bytes().to_vec())
    );
    assert_eq!(
        client.sdo_download(COE_STORE, 0x2001, 0, &0xCAFE_F00Du32.to_le_bytes(), MAILBOX),
        Ok(())
    );
    assert_eq!(
        client.sdo_upload(COE_STORE, 0x2001, 0),
        Ok(0xCAFE_F00Du32.to_le_bytes().to_vec())
    );

    // Segmented upload and download of the 4 KiB object 0x2000.
    let large = store.objects.iter().find(|o| o.index == 0x2000).unwrap();
    let size = large.size.unwrap();
    assert_eq!(size, 4096);
    assert_eq!(client.sdo_upload(COE_STORE, 0x2000, 0), Ok(pattern(size)));
    let written: Vec<u8> = pattern(size)
        .iter()
        .map(|b| b.wrapping_mul(7) ^ 0x5A)
        .collect();
    assert_eq!(
        client.sdo_download(COE_STORE, 0x2000, 0, &written, MAILBOX),
        Ok(())
    );
    assert_eq!(client.sdo_upload(COE_STORE, 0x2000, 0), Ok(written));

    // SDO Information: the store's object list holds its topology objects and equals what
    // the gRPC API reports.
    let (listed, _) = client.od_list(COE_STORE);
    for object in &store.objects {
        assert!(
            listed.contains(&object.index),
            "{:#x} missing",
            object.index
        );
    }
    assert!(listed.contains(&0x1018));
    let grpc = call(
        &ecatd.grpc,
        &[],
        "ecat.v1.CoeService/ObjectList",
        r#"{"slave":"3"}"#,
    )
    .unwrap();
    let grpc: Vec<u16> = grpc["indices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as u16)
        .collect();
    assert_eq!(listed, grpc);

    // 0x8000 + position reaches the slave at that position; the reply keeps the address.
    let reply = client.coe(0x8003, &upload_request(0x2001, 0));
    assert_eq!(reply.header.address, 0x8003);
    match reply.coe() {
        CoeRepr::SdoResponse(SdoResponse::InitiateUpload { index, payload, .. }) => {
            assert_eq!(index, 0x2001);
            assert_eq!(
                payload,
                master_core::wire::coe::SdoPayload::Expedited(&0xCAFE_F00Du32.to_le_bytes())
            );
        }
        other => panic!("{other:?}"),
    }

    // Broadcast: one reply per CoE slave, each with its station address and its value.
    let coe_slaves: Vec<(u16, u32)> = topology
        .slaves
        .iter()
        .enumerate()
        .filter(|(_, s)| s.protocols.contains(&Protocol::Coe))
        .map(|(position, s)| (1001 + position as u16, s.vendor_id))
        .collect();
    assert_eq!(coe_slaves.len(), 2, "drive and CoE store");
    client.send(
        BROADCAST_ADDRESS,
        MailboxType::Coe,
        &coe_bytes(&upload_request(0x1018, 1)),
    );
    let mut answered = Vec::new();
    for _ in &coe_slaves {
        let reply = client.recv();
        let CoeRepr::SdoResponse(SdoResponse::InitiateUpload { payload, .. }) = reply.coe() else {
            panic!("{reply:?}");
        };
        let master_core::wire::coe::SdoPayload::Expedited(value) = payload else {
            panic!("{payload:?}");
        };
        answered.push((
            reply.header.address,
            u32::from_le_bytes(value.try_into().unwrap()),
        ));
    }
    answered.sort();
    assert_eq!(answered, coe_slaves);
    assert!(
        client.recv_within(SILENCE).is_none(),
        "one reply per CoE slave, no more"
    );
}

#[test]
fn soe_foe_and_voe_through_ecatd() {
    let ecatd = Ecatd::start(&[]);
    let topology = Topology::default_segment();
    let drive = &topology.slaves[0];
    let mut client = GatewayClient::new(ecatd.gateway_addr());

    // SoE: P-0-0100's value, as the topology sets it.
    let idn = &drive.idns[0];
    let reply = client.exchange(DRIVE, MailboxType::Soe, &soe_read_request(idn.idn));
    let repr = soe_of(&reply);
    assert_eq!(repr.opcode, SoeOpcode::ReadResponse);
    assert_eq!(repr.error, None);
    assert_eq!(Some(repr.data.to_vec()), idn.value);

    // VoE: the simulator's echo inverts every byte.
    let vendor_id = drive.voe_vendor_id.unwrap();
    let sent: Vec<u8> = (0..40u8).collect();
    let mut request = vec![
        0u8;
        VoeRepr {
            vendor_id,
            vendor_type: 7,
            data: &sent,
        }
        .buffer_len()
    ];
    VoeRepr {
        vendor_id,
        vendor_type: 7,
        data: &sent,
    }
    .emit(&mut VoePacket::new_unchecked(&mut request[..]))
    .unwrap();
    let reply = client.exchange(DRIVE, MailboxType::Voe, &request);
    assert_eq!(reply.header.mailbox_type, MailboxType::Voe);
    let answer = VoeRepr::parse(&VoePacket::new_checked(&reply.data[..]).unwrap()).unwrap();
    assert_eq!((answer.vendor_id, answer.vendor_type), (vendor_id, 7));
    let inverted: Vec<u8> = sent.iter().map(|b| b ^ 0xFF).collect();
    assert_eq!(answer.data, &inverted[..]);

    // FoE: 1 MiB written packet by packet, read back with the same SHA-256 (the drive's
    // store holds 1 MiB: the file replaces firmware.bin).
    const MIB: usize = 1 << 20;
    let content: Vec<u8> = (0..MIB).map(|i| (i.wrapping_mul(31) >> 3) as u8).collect();
    foe_write(&mut client, DRIVE, "firmware.bin", &content);
    let back = foe_read(&mut client, DRIVE, "firmware.bin", MIB);
    assert_eq!(back.len(), MIB);
    assert_eq!(Sha256::digest(&back), Sha256::digest(&content));

    let stats = wait_for_gateway(&ecatd, |_| true)["stats"].clone();
    assert_eq!(stats["soe_count"], 1);
    assert_eq!(stats["voe_count"], 1);
    assert_eq!(stats["failed_requests"], 0, "{stats}");
}

#[test]
fn the_master_dictionary_at_address_0_describes_the_bus() {
    let ecatd = Ecatd::start(&[]);
    let mut client = GatewayClient::new(ecatd.gateway_addr());
    let identity = MasterIdentity::default();
    assert_eq!(
        client.sdo_upload(0, 0x1018, 3),
        Ok(identity.revision.to_le_bytes().to_vec())
    );
    assert_eq!(
        client.sdo_upload(0, 0x1008, 0),
        Ok(identity.device_name.as_bytes().to_vec())
    );

    // 0x8nnn:01 (station address) of every slave, 0xF020 (configured) and 0xF040
    // (detected) lists: the slave list the gRPC API reports.
    let list = call(&ecatd.grpc, &[], "ecat.v1.BusService/ListSlaves", "{}").unwrap();
    let stations: Vec<u16> = list["slaves"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["station"].as_u64().unwrap() as u16)
        .collect();
    let topology = Topology::default_segment();
    assert_eq!(stations.len(), topology.slaves.len());
    for (position, station) in stations.iter().enumerate() {
        assert_eq!(
            client.sdo_upload(0, 0x8000 + position as u16, 1),
            Ok(station.to_le_bytes().to_vec()),
            "0x{:04x}:01",
            0x8000 + position
        );
    }
    for list in [0xF020, 0xF040] {
        assert_eq!(
            client.sdo_upload(0, list, 0),
            Ok(vec![stations.len() as u8]),
            "{list:#x}:00"
        );
        for (i, station) in stations.iter().enumerate() {
            assert_eq!(
                client.sdo_upload(0, list, i as u8 + 1),
                Ok(station.to_le_bytes().to_vec()),
                "{list:#x}:{:02x}",
                i + 1
            );
        }
    }

    // Writing 0xA001:02 (AL control) moves slave 1 to PREOP, as both APIs then report.
    assert_eq!(
        client.sdo_download(0, 0xA001, 2, &2u16.to_le_bytes(), MAILBOX),
        Ok(())
    );
    let slave = call(
        &ecatd.grpc,
        &[],
        "ecat.v1.BusService/GetSlave",
        r#"{"slave":"1"}"#,
    )
    .unwrap();
    assert_eq!(slave["state"], "AL_STATE_PREOP");
    let (status, body) = curl(&["-s", &format!("{}/api/v1/slaves/1", ecatd.http)]);
    assert_eq!(status, 200);
    let rest: Value = serde_json::from_str(&body).unwrap();
    assert_eq!(rest["state"], "PREOP");
    assert_eq!(
        client.sdo_upload(0, 0xA001, 1),
        Ok(2u16.to_le_bytes().to_vec()),
        "AL status"
    );
}

/// Whether an entry's bit length is a capacity rather than its value's size.
fn is_variable(data_type: DataType) -> bool {
    matches!(
        data_type,
        DataType::VisibleString
            | DataType::OctetString
            | DataType::UnicodeString
            | DataType::Domain
    )
}

/// Whether complete access packs an entry at bit granularity (spec-notes §coe.ca: BOOL, BITn,
/// any length that is not whole bytes); the others start on a byte boundary.
fn bit_packed(entry: &EntrySummary) -> bool {
    entry.data_type == DataType::Boolean
        || (u16::from(DataType::Bit1)..=u16::from(DataType::Bit16))
            .contains(&u16::from(entry.data_type))
        || !entry.bit_length.is_multiple_of(8)
}

/// The complete-access image (spec-notes §coe.ca) of an ARRAY/RECORD built from single-entry
/// reads: SI0 (`count`) in 16 bits, then the entries 1..=count that exist (gaps left out) at
/// their described bit length: byte-sized ones byte-aligned (strings padded with zeros),
/// bit-sized ones packed LSB first.
fn image_from_entries(count: u8, entries: &[(EntrySummary, Vec<u8>)]) -> Vec<u8> {
    let mut image = vec![count, 0];
    let mut bit: usize = 16;
    for (entry, value) in entries.iter().filter(|(e, _)| e.subindex <= count) {
        if !bit_packed(entry) {
            bit = bit.div_ceil(8) * 8;
        }
        let len = usize::from(entry.bit_length);
        image.resize((bit + len).div_ceil(8), 0);
        for i in 0..len {
            if value
                .get(i / 8)
                .is_some_and(|byte| byte >> (i % 8) & 1 == 1)
            {
                image[(bit + i) / 8] |= 1 << ((bit + i) % 8);
            }
        }
        bit += len;
    }
    image
}

/// Reads SI0 and every described entry of `index` one by one.
fn read_entries(
    client: &mut GatewayClient,
    index: u16,
    described: &[EntrySummary],
) -> (u8, Vec<(EntrySummary, Vec<u8>)>) {
    let count = client.sdo_upload(0, index, 0).expect("SI0");
    assert_eq!(count.len(), 1, "{index:#06x}:00 is a u8");
    let entries = described
        .iter()
        .filter(|e| e.subindex > 0)
        .map(|e| {
            let value = client
                .sdo_upload(0, index, e.subindex)
                .unwrap_or_else(|code| panic!("{index:#06x}:{:02x}: {code:#010x}", e.subindex));
            (e.clone(), value)
        })
        .collect();
    (count[0], entries)
}

/// Complete access to `index` from subindex 0 and 1 equals the image of its single
/// entries. Live values (counters, frame rates) may move between reads, so one attempt
/// counts only when the single entries read before and after agree; bounded. Returns the
/// attempts it took.
fn complete_access_matches_entries(
    client: &mut GatewayClient,
    index: u16,
    described: &[EntrySummary],
) -> usize {
    const ATTEMPTS: usize = 20;
    let mut last = None;
    for attempt in 1..=ATTEMPTS {
        let (count, before) = read_entries(client, index, described);
        let whole = client.sdo_upload_with(0, index, 0, true);
        let from_one = client.sdo_upload_with(0, index, 1, true);
        let after = read_entries(client, index, described);
        let image = image_from_entries(count, &before);
        let from_one_expected = image.get(2..).map(<[u8]>::to_vec);
        if (count, &before) == (after.0, &after.1)
            && whole.as_ref() == Ok(&image)
            && from_one.as_ref().ok() == from_one_expected.as_ref()
        {
            return attempt;
        }
        last = Some((whole, from_one, image));
    }
    panic!("{index:#06x}: complete access never matched the entries: {last:?}");
}

#[test]
fn the_master_dictionary_is_listed_described_and_readable_through_ecatd() {
    let ecatd = Ecatd::start(&[]);
    let mut client = GatewayClient::new(ecatd.gateway_addr());
    let topology = Topology::default_segment();
    let slaves = u16::try_from(topology.slaves.len()).unwrap();

    // Get OD List (all objects): the master's identity, three objects per slave of the
    // topology (ETG.1510, spec-notes §master-od), the device-level objects (ibid.).
    let (list, list_fragments) = client.od_list(0);
    let mut expected = vec![0x1000, 0x1008, 0x1009, 0x100A, 0x1018];
    for base in [0x8000u16, 0x9000, 0xA000] {
        expected.extend((0..slaves).map(|n| base + n));
        let listed = list
            .iter()
            .filter(|&&i| (base..=base + 0xFFF).contains(&i))
            .count();
        assert_eq!(listed, topology.slaves.len(), "objects {base:#06x}+n");
    }
    expected.extend([0xF000, 0xF002, 0xF020, 0xF040, 0xF120, 0xF200]);
    assert_eq!(list, expected);

    // Every object described, every subindex up to its highest described and read.
    let mut values: BTreeMap<(u16, u8), Vec<u8>> = BTreeMap::new();
    let (mut entries, mut gaps, mut images, mut retries) = (0usize, 0usize, 0usize, 0usize);
    for &index in &list {
        let object = client
            .object_description(0, index)
            .unwrap_or_else(|code| panic!("{index:#06x}: {code:#010x}"));
        assert_eq!(object.index, index);
        assert!(!object.name.is_empty(), "{index:#06x} has a name");
        let composite = match object.object_code {
            ObjectCode::Var => {
                assert_eq!(object.max_subindex, 0, "{index:#06x} VAR");
                false
            }
            ObjectCode::Array | ObjectCode::Record => true,
            other => panic!("{index:#06x}: object code {other}"),
        };
        let mut described = Vec::new();
        for subindex in 0..=object.max_subindex {
            let at = format!("{index:#06x}:{subindex:02x}");
            match (
                client.entry_description(0, index, subindex),
                client.sdo_upload(0, index, subindex),
            ) {
                (Ok(entry), Ok(value)) => {
                    assert_eq!((entry.index, entry.subindex), (index, subindex), "{at}");
                    assert!(!entry.name.is_empty(), "{at} has a name");
                    assert!(entry.access.readable(), "{at} was read: {}", entry.access);
                    let bits = usize::from(entry.bit_length);
                    if is_variable(entry.data_type) {
                        assert!(value.len() * 8 <= bits, "{at} {entry:?}: {value:?}");
                    } else {
                        assert_eq!(value.len(), bits.div_ceil(8), "{at} {entry:?}");
                        // No bits beyond the described length.
                        let used = u32::try_from(bits % 8).unwrap();
                        if used != 0 {
                            assert_eq!(value.last().unwrap() >> used, 0, "{at} {value:?}");
                        }
                    }
                    if composite && subindex == 0 {
                        // SI0 is the highest subindex, as the description says.
                        assert_eq!(entry.data_type, DataType::Unsigned8, "{at}");
                        assert_eq!(value, [object.max_subindex], "{at}");
                    }
                    if object.object_code == ObjectCode::Array && subindex > 0 {
                        assert_eq!(entry.data_type, object.data_type, "{at} array type");
                    }
                    values.insert((index, subindex), value);
                    described.push(entry);
                    entries += 1;
                }
                // A gap in a record: neither described nor readable (spec-notes §master-od).
                (Err(a), Err(b)) if composite && subindex > 0 => {
                    let gap = u32::from(AbortCode::TransferFailed);
                    assert_eq!((a, b), (gap, gap), "{at}");
                    gaps += 1;
                }
                (d, r) => panic!("{at}: description {d:?}, upload {r:?}"),
            }
        }
        if composite {
            retries += complete_access_matches_entries(&mut client, index, &described) - 1;
            images += 1;
        }
    }
    println!(
        "{} objects ({list_fragments} OD list fragment(s)), {entries} entries described and \
         read, {gaps} gaps, {images} complete-access images ({retries} retries)",
        list.len()
    );
    assert!(entries > 100, "{entries}");

    // The values describe the bus as ecatd's APIs and the topology do.
    let u16_at = |index: u16, subindex: u8| -> u16 {
        u16::from_le_bytes(values[&(index, subindex)][..].try_into().unwrap())
    };
    let u32_at = |index: u16, subindex: u8| -> u32 {
        u32::from_le_bytes(values[&(index, subindex)][..].try_into().unwrap())
    };
    let grpc = call(&ecatd.grpc, &[], "ecat.v1.BusService/ListSlaves", "{}").unwrap();
    let grpc_stations: Vec<u16> = grpc["slaves"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| u16::try_from(s["station"].as_u64().unwrap()).unwrap())
        .collect();
    let (status, body) = curl(&["-s", &format!("{}/api/v1/slaves", ecatd.http)]);
    assert_eq!(status, 200, "{body}");
    let rest: Value = serde_json::from_str(&body).unwrap();
    let rest_stations: Vec<u16> = rest
        .as_array()
        .unwrap()
        .iter()
        .map(|s| u16::try_from(s["station"].as_u64().unwrap()).unwrap())
        .collect();
    assert_eq!(grpc_stations, rest_stations);
    assert_eq!(grpc_stations.len(), topology.slaves.len());
    assert_eq!(values[&(0xF020, 0)], [u8::try_from(slaves).unwrap()]);
    for (n, (spec, &station)) in topology.slaves.iter().zip(&grpc_stations).enumerate() {
        let n16 = u16::try_from(n).unwrap();
        let (config, info, diag) = (0x8000 + n16, 0x9000 + n16, 0xA000 + n16);
        assert_eq!(u16_at(config, 1), station, "{config:#06x}:01");
        assert_eq!(u16_at(info, 1), station, "{info:#06x}:01");
        assert_eq!(u16_at(0xF020, u8::try_from(n + 1).unwrap()), station);
        assert_eq!(
            values[&(config, 3)],
            spec.name.as_bytes(),
            "{config:#06x}:03"
        );
        for object in [config, info] {
            assert_eq!(u32_at(object, 5), spec.vendor_id, "{object:#06x}:05");
            assert_eq!(u32_at(object, 6), spec.product_code, "{object:#06x}:06");
            assert_eq!(u32_at(object, 7), spec.revision, "{object:#06x}:07");
            assert_eq!(u32_at(object, 8), spec.serial, "{object:#06x}:08");
        }
        // Every slave in OP, as the gRPC list says: AL status 0x0008.
        assert_eq!(grpc["slaves"][n]["state"], "AL_STATE_OP");
        assert_eq!(u16_at(diag, 1), 0x0008, "{diag:#06x}:01");
    }
    let identity = MasterIdentity::default();
    assert_eq!(values[&(0x1008, 0)], identity.device_name.as_bytes());
    assert_eq!(u32_at(0x1018, 1), identity.vendor_id);
    assert_eq!(u32_at(0x1018, 2), identity.product_code);
}

#[test]
fn errors_follow_the_table() {
    let ecatd = Ecatd::start(&[]);
    let mut client = GatewayClient::new(ecatd.gateway_addr());

    // Unknown station: CoE abort 0x06020000 naming the request's object.
    let reply = client.coe(0x0999, &upload_request(0x1018, 1));
    assert_eq!(reply.header.address, 0x0999);
    assert_eq!(abort_of(&reply), (0x1018, 1, object_missing()));
    // Protocols a slave does not serve: CoE abort 0x06010000 from the EoE port, SoE error
    // 0x1009 from the CoE store.
    let reply = client.coe(EOE_PORT, &upload_request(0x1018, 1));
    assert_eq!(
        abort_of(&reply),
        (0x1018, 1, u32::from(AbortCode::UnsupportedAccess))
    );
    let reply = client.exchange(COE_STORE, MailboxType::Soe, &soe_read_request(0x8064));
    assert_eq!(soe_of(&reply).error, Some(SoeError::from(0x1009)));
    // The master (address 0) speaks CoE only: VoE gets mailbox error 0x0002.
    let voe = {
        let repr = VoeRepr {
            vendor_id: 1,
            vendor_type: 1,
            data: &[1, 2],
        };
        repr.to_vec().unwrap()
    };
    let reply = client.exchange(0, MailboxType::Voe, &voe);
    assert_eq!(
        mailbox_error_of(&reply),
        MailboxErrorCode::UnsupportedProtocol
    );

    let failures = gateway_view(&ecatd)["stats"]["failures"].clone();
    assert_eq!(failures["unknown_address"], 1, "{failures}");
    assert_eq!(failures["unsupported_protocol"], 3, "{failures}");
}

#[test]
fn strict_mode_answers_no_errors_but_relays_the_slaves() {
    let ecatd = start_with_config("strict", "[gateway]\nstrict = true\n", &[]);
    assert_eq!(gateway_view(&ecatd)["strict"], true);
    let mut client = GatewayClient::new(ecatd.gateway_addr());
    client.send(
        0x0999,
        MailboxType::Coe,
        &coe_bytes(&upload_request(0x1018, 1)),
    );
    assert!(
        client.recv_within(SILENCE).is_none(),
        "no error reply in strict mode"
    );
    // The slave's own abort still comes back.
    let reply = client.coe(COE_STORE, &upload_request(0x5FFF, 0));
    assert_eq!(abort_of(&reply), (0x5FFF, 0, object_missing()));
    let view = wait_for_gateway(&ecatd, |v| v["stats"]["failures"]["unknown_address"] == 1);
    assert_eq!(view["stats"]["failures"]["unknown_address"], 1, "{view}");
    assert_eq!(view["stats"]["forwarded_requests"], 1);
}

#[test]
fn clients_outside_the_allowlist_get_nothing_and_are_counted() {
    // A network outside loopback with the write role needs --insecure (issue 15).
    let ecatd = start_with_config(
        "allow",
        "[gateway]\nallow = [\"10.0.0.0/8\"]\n",
        &["--insecure"],
    );
    assert_eq!(
        gateway_view(&ecatd)["allow"],
        serde_json::json!(["10.0.0.0/8 write"])
    );
    let mut client = GatewayClient::new(ecatd.gateway_addr());
    client.send(
        COE_STORE,
        MailboxType::Coe,
        &coe_bytes(&upload_request(0x1018, 1)),
    );
    assert!(
        client.recv_within(SILENCE).is_none(),
        "127.0.0.1 is not allowed"
    );
    let view = wait_for_gateway(&ecatd, |v| v["stats"]["failures"]["denied"] == 1);
    assert_eq!(view["stats"]["failures"]["denied"], 1, "{view}");
    assert_eq!(view["stats"]["total_requests"], 1);
    assert_eq!(view["stats"]["forwarded_requests"], 0);
    assert_eq!(
        metric(
            &ecatd,
            r#"ecat_mailbox_gateway_failures_total{reason="denied"}"#
        ),
        1.0
    );
}

#[test]
fn stop_and_restart_through_the_api() {
    let ecatd = Ecatd::start(&[]);
    let first = ecatd.gateway_addr();
    let mut client = GatewayClient::new(first);
    let vendor = Topology::default_segment().slaves[3].vendor_id;
    assert_eq!(
        client.sdo_upload(COE_STORE, 0x1018, 1),
        Ok(vendor.to_le_bytes().to_vec())
    );

    let stopped = call(&ecatd.grpc, &[], "ecat.v1.GatewayService/StopGateway", "{}").unwrap();
    assert!(stopped["running"].is_null(), "{stopped}");
    assert_eq!(metric(&ecatd, "ecat_mailbox_gateway_up"), 0.0);
    client.send(
        COE_STORE,
        MailboxType::Coe,
        &coe_bytes(&upload_request(0x1018, 1)),
    );
    assert!(
        client.recv_within(SILENCE).is_none(),
        "no reply while stopped"
    );

    let started = call(
        &ecatd.grpc,
        &[],
        "ecat.v1.GatewayService/StartGateway",
        "{}",
    )
    .unwrap();
    assert_eq!(started["running"], true);
    let port = started["port"].as_u64().unwrap() as u16;
    assert_eq!(started["boundAddress"], loopback(port).to_string());
    assert_eq!(metric(&ecatd, "ecat_mailbox_gateway_up"), 1.0);
    assert_eq!(
        metric(
            &ecatd,
            &format!(r#"ecat_mailbox_gateway_info{{port="{port}"}}"#)
        ),
        1.0
    );
    let mut client = GatewayClient::new(loopback(port));
    assert_eq!(
        client.sdo_upload(COE_STORE, 0x1018, 1),
        Ok(vendor.to_le_bytes().to_vec()),
        "served again after the restart"
    );
    let view = gateway_view(&ecatd);
    assert_eq!(view["stats"]["total_requests"], 1, "counters restarted");
}

#[test]
fn master_number_2_asks_for_34981_and_falls_back_when_it_is_taken() {
    let wanted = master_core::gateway::port_for_master(2);
    assert_eq!(wanted, 34981);
    // Hold the port so that the fallback is certain (if something else holds it, the
    // fallback is just as certain, and the free-port half below is skipped).
    let holder = UdpSocket::bind(loopback(wanted)).ok();
    let ecatd = Ecatd::start(&[
        "--gateway-listen",
        "127.0.0.1",
        "--gateway-master-number",
        "2",
    ]);
    let view = gateway_view(&ecatd);
    assert_eq!(view["master_number"], 2);
    assert_eq!(view["configured_address"], loopback(wanted).to_string());
    let port = view["port"].as_u64().unwrap() as u16;
    assert_ne!(port, wanted, "34981 is taken: a fallback port");
    assert_eq!(view["bound_address"], loopback(port).to_string());
    assert_eq!(ecatd.gateway_addr(), loopback(port), "the log line");
    assert_eq!(
        metric(
            &ecatd,
            &format!(r#"ecat_mailbox_gateway_info{{port="{port}"}}"#)
        ),
        1.0
    );
    assert!(
        ecatd
            .log()
            .lines()
            .any(|l| l.contains("mailbox gateway port taken") && l.contains(&wanted.to_string())),
        "no fallback warning:\n{}",
        ecatd.log()
    );
    let mut client = GatewayClient::new(loopback(port));
    let vendor = Topology::default_segment().slaves[0].vendor_id;
    assert_eq!(
        client.sdo_upload(DRIVE, 0x1018, 1),
        Ok(vendor.to_le_bytes().to_vec())
    );

    // With 34981 released, a restart binds it.
    let Some(holder) = holder else {
        return;
    };
    let (status, _) = curl(&[
        "-s",
        "-X",
        "POST",
        &format!("{}/api/v1/gateway/stop", ecatd.http),
    ]);
    assert_eq!(status, 200);
    drop(holder);
    let (status, body) = curl(&[
        "-s",
        "-X",
        "POST",
        &format!("{}/api/v1/gateway/start", ecatd.http),
    ]);
    assert_eq!(status, 200, "{body}");
    let started: Value = serde_json::from_str(&body).unwrap();
    assert_eq!(started["port"], wanted, "{started}");
    assert_eq!(started["bound_address"], loopback(wanted).to_string());
    let mut client = GatewayClient::new(loopback(wanted));
    assert_eq!(
        client.sdo_upload(DRIVE, 0x1018, 1),
        Ok(vendor.to_le_bytes().to_vec())
    );
}

/// The default segment and a second drive at its end ([`DRIVE_2`]), so that two slaves
/// serve FoE; written to a file for `--simulate`.
fn two_drives(name: &str) -> PathBuf {
    let mut topology = Topology::default_segment();
    let mut drive = topology.slaves[0].clone();
    drive.serial = 6;
    // One EoE endpoint per IP address.
    if let Some(eoe) = drive.eoe.as_mut() {
        eoe.ip = None;
    }
    topology.slaves.push(drive);
    let path = std::env::temp_dir().join(format!(
        "ecatd-gateway-{name}-{}-topology.toml",
        std::process::id()
    ));
    std::fs::write(&path, topology.to_toml().expect("the topology serialises")).unwrap();
    path
}

/// ecatd on [`two_drives`] with a `write` client at 127.0.0.1 and a `read` one at
/// 127.0.0.2 (the broadcasts come from the latter: its role is no protection for anyone).
fn start_for_broadcasts(name: &str) -> (Ecatd, GatewayClient, GatewayClient) {
    let topology = two_drives(name);
    let config =
        std::env::temp_dir().join(format!("ecatd-gateway-{name}-{}.toml", std::process::id()));
    // The application interface is not under test, and its default socket is one per host.
    std::fs::write(
        &config,
        "[gateway]\nallow = [\"127.0.0.1/32\", { net = \"127.0.0.2/32\", role = \"read\" }]\n\
         [app]\nenabled = false\n",
    )
    .unwrap();
    let ecatd = Ecatd::start_with(
        &["--simulate", topology.to_str().unwrap()],
        &["--config", config.to_str().unwrap()],
    );
    std::fs::remove_file(&topology).unwrap();
    std::fs::remove_file(&config).unwrap();
    let writer = GatewayClient::new(ecatd.gateway_addr());
    let reader = GatewayClient::from_host(Ipv4Addr::new(127, 0, 0, 2), ecatd.gateway_addr());
    (ecatd, writer, reader)
}

/// The replies to a broadcast, one per slave serving its protocol, by station address;
/// no more come.
fn broadcast_replies(client: &GatewayClient, slaves: usize) -> BTreeMap<u16, Reply> {
    let mut replies = BTreeMap::new();
    for _ in 0..slaves {
        let reply = client.recv();
        let station = reply.header.address;
        assert!(
            replies.insert(station, reply).is_none(),
            "one reply from {station}"
        );
    }
    assert!(
        client.recv_within(SILENCE).is_none(),
        "one reply per slave, no more"
    );
    replies
}

/// Issue 35 item 1: a broadcast no longer breaks another client's transfer. While a
/// `write` client is in a segmented SDO download to the CoE store, a `read` client's SDO
/// upload to 0xFFFF is answered by the other CoE slaves and, for the store, with mailbox
/// error 0x0009 (busy): the store never sees it, and the download goes on to the end
/// (before, the store answered the upload and the next segment got abort 0x05040001).
/// Segments are never broadcast: mailbox error 0x0004 at 0xFFFF, from whichever client.
#[test]
fn a_broadcast_skips_a_slave_in_another_clients_sdo_download() {
    let (ecatd, mut writer, mut reader) = start_for_broadcasts("sdo-broadcast");
    // The second drive is a copy of the first.
    let vendor = Topology::default_segment().slaves[0].vendor_id;
    // Not the store's initial value (the fill pattern), so the read-back proves the write.
    let content: Vec<u8> = (0..4096u32).map(|i| (i * 7 + 3) as u8).rev().collect();
    assert_ne!(content, pattern(content.len()));
    let first = max_initiate_data(MAILBOX);
    let reply = writer.coe(
        COE_STORE,
        &CoeRepr::SdoRequest(SdoRequest::InitiateDownload {
            index: 0x2000,
            subindex: 0,
            complete_access: false,
            payload: SdoPayload::Normal {
                complete_size: content.len() as u32,
                data: &content[..first],
            },
        }),
    );
    assert!(
        matches!(
            reply.coe(),
            CoeRepr::SdoResponse(SdoResponse::InitiateDownload { .. })
        ),
        "{reply:?}"
    );

    // The download is open: the broadcast skips the store, the drives answer.
    reader.send(
        BROADCAST_ADDRESS,
        MailboxType::Coe,
        &coe_bytes(&upload_request(0x1018, 1)),
    );
    let replies = broadcast_replies(&reader, 3);
    assert_eq!(
        replies.keys().copied().collect::<Vec<_>>(),
        [DRIVE, COE_STORE, DRIVE_2]
    );
    assert_eq!(
        mailbox_error_of(&replies[&COE_STORE]),
        MailboxErrorCode::ServiceInWork
    );
    for station in [DRIVE, DRIVE_2] {
        let CoeRepr::SdoResponse(SdoResponse::InitiateUpload {
            payload: SdoPayload::Expedited(value),
            ..
        }) = replies[&station].coe()
        else {
            panic!("{station}: {:?}", replies[&station]);
        };
        assert_eq!(value, vendor.to_le_bytes());
    }

    // A segment to 0xFFFF is refused before any slave sees it: the reader's upload segment,
    // and the writer's own download segment sent to the wrong address.
    let refused = [
        (
            &mut reader,
            coe_bytes(&CoeRepr::SdoRequest(SdoRequest::UploadSegment {
                toggle: false,
            })),
        ),
        (
            &mut writer,
            coe_bytes(&CoeRepr::SdoRequest(SdoRequest::DownloadSegment {
                toggle: false,
                last: false,
                data: &[0xEE; 7],
            })),
        ),
    ];
    for (client, segment) in refused {
        let reply = client.exchange(BROADCAST_ADDRESS, MailboxType::Coe, &segment);
        assert_eq!(reply.header.address, BROADCAST_ADDRESS);
        assert_eq!(
            mailbox_error_of(&reply),
            MailboxErrorCode::ServiceNotSupported
        );
    }

    // The download goes on where it was and ends.
    let mut toggle = false;
    let chunks: Vec<&[u8]> = content[first..].chunks(max_segment_data(MAILBOX)).collect();
    for (n, chunk) in chunks.iter().enumerate() {
        let reply = writer.coe(
            COE_STORE,
            &CoeRepr::SdoRequest(SdoRequest::DownloadSegment {
                toggle,
                last: n + 1 == chunks.len(),
                data: chunk,
            }),
        );
        assert_eq!(
            reply.coe(),
            CoeRepr::SdoResponse(SdoResponse::DownloadSegment { toggle }),
            "segment {n}"
        );
        toggle = !toggle;
    }
    assert_eq!(reader.sdo_upload(COE_STORE, 0x2000, 0), Ok(content));

    let stats = gateway_view(&ecatd)["stats"].clone();
    assert_eq!(stats["failures"]["other"], 2, "the two segments: {stats}");
    assert_eq!(
        stats["failures"]["busy"], 0,
        "the broadcast was answered: {stats}"
    );
}

/// The same for FoE: while the `write` client reads firmware.bin from the drive, the
/// `read` client's FoE read request to 0xFFFF is answered by the second drive and, for the
/// first, with mailbox error 0x0009; an ACK to 0xFFFF is refused (mailbox error 0x0004).
/// Both reads then end with the whole file: the broadcast's read of the second drive is
/// its client's, to go on with at that drive's address.
#[test]
fn a_broadcast_skips_a_slave_in_another_clients_foe_read() {
    let (_ecatd, mut writer, mut reader) = start_for_broadcasts("foe-broadcast");
    let file = pattern(1024);
    let request = foe_bytes(&FoeRepr::ReadRequest {
        password: 0,
        file_name: b"firmware.bin",
    });
    let first = writer.exchange(DRIVE, MailboxType::Foe, &request);
    assert!(
        matches!(foe_of(&first), FoeRepr::Data { packet: 1, .. }),
        "{first:?}"
    );

    reader.send(BROADCAST_ADDRESS, MailboxType::Foe, &request);
    let replies = broadcast_replies(&reader, 2);
    assert_eq!(
        mailbox_error_of(&replies[&DRIVE]),
        MailboxErrorCode::ServiceInWork
    );
    let second = replies[&DRIVE_2].clone();
    assert!(
        matches!(foe_of(&second), FoeRepr::Data { packet: 1, .. }),
        "{second:?}"
    );

    let ack = foe_bytes(&FoeRepr::Ack { packet: 1 });
    let reply = reader.exchange(BROADCAST_ADDRESS, MailboxType::Foe, &ack);
    assert_eq!(reply.header.address, BROADCAST_ADDRESS);
    assert_eq!(
        mailbox_error_of(&reply),
        MailboxErrorCode::ServiceNotSupported
    );

    assert_eq!(
        foe_read_on(&mut writer, DRIVE, &first, file.len()),
        Some(file.clone())
    );
    assert_eq!(
        foe_read_on(&mut reader, DRIVE_2, &second, file.len()),
        Some(file)
    );
}
