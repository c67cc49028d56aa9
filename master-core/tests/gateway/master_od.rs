//! The master's ETG.1510 dictionary at gateway address 0: every object listed, described
//! and readable (SDO Information consistent with the values), values matching the segment,
//! AL control writes that move a slave, segmented long strings, the scan command and the
//! diagnosis reset.

use crate::gateway_support;

use gateway_support::master_support::wait_until;
use gateway_support::{COE_STORE, Client, DRIVE, GwRig, station, test_config};
use master_core::gateway::GatewayConfig;
use master_core::master::SlaveAddress;
use master_core::master_od::MasterIdentity;
use master_core::wire::coe::info::od_list::OdListType;
use master_core::wire::coe::{AbortCode, DataType, ObjectCode, SdoInfoService};
use master_core::wire::register::AlState;
use sim::esc::ErrorCounter;

const MASTER: u16 = 0;

fn u16_of(bytes: Vec<u8>) -> u16 {
    u16::from_le_bytes(bytes.try_into().expect("2 bytes"))
}

fn u32_of(bytes: Vec<u8>) -> u32 {
    u32::from_le_bytes(bytes.try_into().expect("4 bytes"))
}

fn is_variable(data_type: DataType) -> bool {
    matches!(
        data_type,
        DataType::VisibleString
            | DataType::OctetString
            | DataType::UnicodeString
            | DataType::Domain
    )
}

#[test]
fn every_object_is_listed_described_and_readable() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let list = client.od_list(MASTER);
    let slaves = rig.topology.slaves.len() as u16;
    let mut expected = vec![0x1000, 0x1008, 0x1009, 0x100A, 0x1018];
    for base in [0x8000u16, 0x9000, 0xA000] {
        expected.extend((0..slaves).map(|n| base + n));
    }
    expected.extend([0xF000, 0xF002, 0xF020, 0xF040, 0xF120, 0xF200]);
    assert_eq!(list, expected);

    let mut entries_read = 0;
    for &index in &list {
        let object = client.object(MASTER, index).expect("object description");
        assert_eq!(object.index, index);
        let mut has_text = false;
        for subindex in 0..=object.max_subindex {
            let described = client.entry(MASTER, index, subindex);
            let read = client.upload(MASTER, index, subindex);
            match (described, read) {
                (Ok(entry), Ok(value)) => {
                    has_text |= is_variable(entry.data_type);
                    if is_variable(entry.data_type) {
                        assert!(value.len() * 8 <= usize::from(entry.bit_length));
                    } else {
                        assert_eq!(
                            value.len() * 8,
                            usize::from(entry.bit_length).div_ceil(8) * 8,
                            "{index:#06x}:{subindex:02x} {entry:?}"
                        );
                    }
                    entries_read += 1;
                }
                // A gap in a record: neither described nor readable.
                (Err(a), Err(b)) => {
                    assert_eq!(
                        (a, b),
                        (AbortCode::TransferFailed, AbortCode::TransferFailed)
                    );
                }
                (d, r) => panic!("{index:#06x}:{subindex:02x}: {d:?} vs {r:?}"),
            }
        }
        if object.object_code == ObjectCode::Record {
            // Records with strings too (0x8nnn, 0xF002): strings at their declared length.
            let whole = client.upload_with(MASTER, index, 0, true);
            assert!(
                whole.is_ok(),
                "complete access to {index:#06x} (text: {has_text}): {whole:?}"
            );
        }
    }
    assert!(entries_read > 100, "{entries_read}");
}

/// The complete-access image of `index` built from single-subindex reads: SI0 padded to
/// 16 bits, then every entry up to SI0 at its declared length (strings padded with zeros).
fn image_from_entries(client: &mut gateway_support::Client, index: u16) -> Vec<u8> {
    let count = client.upload(MASTER, index, 0).expect("SI0")[0];
    let mut image = vec![count, 0];
    for subindex in 1..=count {
        let Ok(entry) = client.entry(MASTER, index, subindex) else {
            continue; // a gap: not in the image
        };
        assert_eq!(
            entry.bit_length % 8,
            0,
            "{index:#06x}:{subindex:02x} byte-sized"
        );
        let mut value = client.upload(MASTER, index, subindex).expect("entry");
        let len = usize::from(entry.bit_length) / 8;
        assert!(value.len() <= len, "{index:#06x}:{subindex:02x}");
        value.resize(len, 0);
        image.extend_from_slice(&value);
    }
    image
}

#[test]
fn complete_access_reads_records_with_strings_field_by_field() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    for index in [0x8000u16, 0x8000 + COE_STORE as u16, 0xF002] {
        let whole = client
            .upload_with(MASTER, index, 0, true)
            .expect("complete access");
        assert_eq!(
            whole,
            image_from_entries(&mut client, index),
            "{index:#06x}"
        );
        // From subindex 1: the same without SI0.
        let from_one = client.upload_with(MASTER, index, 1, true).expect("from 1");
        assert_eq!(from_one, whole[2..], "{index:#06x} from 1");
    }
    // The name field of 0x8000 (:03, after :01 u16 and :02 type of 64 bytes) is the
    // topology's name, zero-padded to 64 bytes.
    let whole = client.upload_with(MASTER, 0x8000, 0, true).unwrap();
    let name = &rig.topology.slaves[DRIVE].name;
    let field = &whole[2 + 2 + 64..2 + 2 + 64 + 64];
    assert_eq!(&field[..name.len()], name.as_bytes());
    assert!(field[name.len()..].iter().all(|&b| b == 0));
}

#[test]
fn values_describe_the_master_and_the_segment() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let identity = MasterIdentity::default();
    assert_eq!(
        String::from_utf8(client.upload(MASTER, 0x1008, 0).unwrap()).unwrap(),
        identity.device_name
    );
    assert_eq!(
        String::from_utf8(client.upload(MASTER, 0x100A, 0).unwrap()).unwrap(),
        identity.software_version
    );
    assert_eq!(
        u32_of(client.upload(MASTER, 0x1018, 3).unwrap()),
        identity.revision
    );
    for (n, spec) in rig.topology.slaves.iter().enumerate() {
        let n16 = n as u16;
        let address = station(n);
        assert_eq!(
            u16_of(client.upload(MASTER, 0x8000 + n16, 1).unwrap()),
            address
        );
        assert_eq!(
            String::from_utf8(client.upload(MASTER, 0x8000 + n16, 3).unwrap()).unwrap(),
            spec.name
        );
        assert_eq!(
            u32_of(client.upload(MASTER, 0x8000 + n16, 5).unwrap()),
            spec.vendor_id
        );
        assert_eq!(
            u32_of(client.upload(MASTER, 0x8000 + n16, 6).unwrap()),
            spec.product_code
        );
        assert_eq!(
            u32_of(client.upload(MASTER, 0x9000 + n16, 8).unwrap()),
            spec.serial
        );
        let mailbox = spec.mailbox.as_ref().map_or(0, |m| m.rx_size);
        assert_eq!(
            u16_of(client.upload(MASTER, 0x8000 + n16, 0x21).unwrap()),
            mailbox
        );
        // Every slave was brought to OP: AL status 0x0008, AL control 0x0008.
        assert_eq!(
            u16_of(client.upload(MASTER, 0xA000 + n16, 1).unwrap()),
            0x0008
        );
        assert_eq!(
            u16_of(client.upload(MASTER, 0xA000 + n16, 2).unwrap()),
            0x0008
        );
        assert_eq!(
            u16_of(client.upload(MASTER, 0xF020, n as u8 + 1).unwrap()),
            address
        );
        assert_eq!(
            u16_of(client.upload(MASTER, 0xF040, n as u8 + 1).unwrap()),
            address
        );
    }
    assert_eq!(
        client.upload(MASTER, 0xF020, 0).unwrap(),
        [rig.topology.slaves.len() as u8]
    );
    // The drive's protocols as its SII announces them (CoE, FoE, SoE, VoE, EoE).
    let protocols = u16_of(client.upload(MASTER, 0x8000 + DRIVE as u16, 0x27).unwrap());
    assert_eq!(protocols, 0x02 | 0x04 | 0x08 | 0x10 | 0x20);
    // The whole segment is in OP.
    assert_eq!(u16_of(client.upload(MASTER, 0xF120, 0x10).unwrap()), 0x0008);
    // Unknown objects and subindices abort as spec-notes §coe.abort says.
    assert_eq!(
        client.upload(MASTER, 0x8000 + 99, 1),
        Err(AbortCode::ObjectDoesNotExist)
    );
    assert_eq!(
        client.upload(MASTER, 0x1018, 9),
        Err(AbortCode::SubindexDoesNotExist)
    );
    assert_eq!(
        client.download(MASTER, 0x1018, 1, &[1, 2, 3, 4]),
        Err(AbortCode::ReadOnly)
    );
}

#[test]
fn writing_al_control_moves_the_slave() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let object = 0xA000 + COE_STORE as u16;
    client
        .download(MASTER, object, 2, &0x0002u16.to_le_bytes())
        .expect("AL control accepted");
    let slave = rig
        .master()
        .slave(SlaveAddress::Position(COE_STORE as u16))
        .unwrap();
    assert_eq!(slave.al_state, AlState::PreOp);
    let status = gateway_support::block_on(rig.master().read_register(
        SlaveAddress::Position(COE_STORE as u16),
        0x0130,
        2,
    ))
    .unwrap();
    assert_eq!(status, [0x02, 0x00], "the slave itself is in PREOP");
    assert_eq!(u16_of(client.upload(MASTER, object, 1).unwrap()), 0x0002);
    assert_eq!(u16_of(client.upload(MASTER, object, 2).unwrap()), 0x0002);
    // Its mailbox still works in PREOP, and it goes back to OP the same way.
    assert!(client.upload(station(COE_STORE), 0x1018, 1).is_ok());
    client
        .download(MASTER, object, 2, &0x0008u16.to_le_bytes())
        .expect("back to OP");
    assert_eq!(u16_of(client.upload(MASTER, object, 1).unwrap()), 0x0008);
    // Not a state: refused, nothing changes.
    assert_eq!(
        client.download(MASTER, object, 2, &0x0007u16.to_le_bytes()),
        Err(AbortCode::ValueRange)
    );
    assert_eq!(
        rig.master()
            .slave(SlaveAddress::Position(COE_STORE as u16))
            .unwrap()
            .al_state,
        AlState::Op
    );
}

#[test]
fn strings_longer_than_the_mailbox_are_segmented_and_lists_fragmented() {
    let name = "an EtherCAT master with a rather long device name, 60 chars";
    let rig = GwRig::start(GatewayConfig {
        master_mailbox_size: 32,
        identity: MasterIdentity {
            device_name: name.to_owned(),
            ..MasterIdentity::default()
        },
        ..test_config()
    });
    let mut client = rig.client();
    client.mailbox_size = 32;
    assert_eq!(
        String::from_utf8(client.upload(MASTER, 0x1008, 0).unwrap()).unwrap(),
        name
    );
    let (_, datagrams) = client
        .info(
            MASTER,
            SdoInfoService::OdListRequest {
                list_type: OdListType::All,
            },
        )
        .unwrap();
    // 26 objects, 20 bytes of list a fragment.
    assert_eq!(datagrams, (2 + 2 * 26usize).div_ceil(20));
}

#[test]
fn error_counters_are_read_live_and_the_diagnosis_reset_clears_them() {
    let rig = GwRig::start(test_config());
    let mut client = Client::new(rig.addr());
    let object = 0xA000 + COE_STORE as u16;
    for _ in 0..3 {
        rig.segment()
            .esc_mut(COE_STORE)
            .unwrap()
            .count_error(ErrorCounter::InvalidFrame(0));
    }
    rig.segment()
        .esc_mut(COE_STORE)
        .unwrap()
        .count_error(ErrorCounter::RxError(1));
    assert_eq!(u32_of(client.upload(MASTER, object, 0x0A).unwrap()), 3);
    assert_eq!(u32_of(client.upload(MASTER, object, 0x0B).unwrap()), 1);
    client.download(MASTER, 0xF200, 0x10, &[1]).expect("reset");
    assert_eq!(u32_of(client.upload(MASTER, object, 0x0A).unwrap()), 0);
    assert_eq!(u32_of(client.upload(MASTER, object, 0x0B).unwrap()), 0);
}

#[test]
fn the_scan_command_rescans_and_reports() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    assert_eq!(client.upload(MASTER, 0xF002, 2).unwrap(), [0]);
    client
        .download(MASTER, 0xF002, 1, &[1, 0])
        .expect("scan started");
    assert!(wait_until(
        || client.upload(MASTER, 0xF002, 2).unwrap() == [1]
    ));
    let slaves = rig.topology.slaves.len() as u8;
    assert_eq!(
        client.upload(MASTER, 0xF002, 3).unwrap(),
        [slaves, 0, 0, 0, 0, 0]
    );
    assert_eq!(
        client.download(MASTER, 0xF002, 1, &[9, 0]),
        Err(AbortCode::ValueRange)
    );
}

#[test]
fn device_types_are_the_slaves_own_0x1000() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let mut nonzero = 0;
    for (n, handles) in rig.handles.iter().enumerate() {
        // The simulator's dictionary is the truth; slaves without CoE report 0.
        let expected = handles.dictionary.as_ref().map_or(0, |d| {
            d.lock()
                .unwrap()
                .get::<u32>(0x1000, 0)
                .expect("0x1000 in the simulated dictionary")
        });
        nonzero += usize::from(expected != 0);
        assert_eq!(
            u32_of(client.upload(MASTER, 0x8000 + n as u16, 4).unwrap()),
            expected,
            "slave {n}"
        );
    }
    assert!(
        nonzero > 0,
        "the default segment has a CoE slave with a device type"
    );
}

fn wkc_errors(client: &mut gateway_support::Client, slaves: usize) -> Vec<u32> {
    (0..slaves as u16)
        .map(|n| u32_of(client.upload(MASTER, 0xA000 + n, 0x0E).unwrap()))
        .collect()
}

#[test]
fn wkc_errors_count_for_the_slaves_that_miss() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let slaves = rig.topology.slaves.len();
    let master = rig.master();

    // Healthy cycles: nothing counted.
    let start = master.cycle_stats().completed;
    assert!(wait_until(|| master.cycle_stats().completed >= start + 20));
    assert_eq!(wkc_errors(&mut client, slaves), vec![0; slaves]);

    // The DI8 (position 2, inputs only) loses its configuration: only it is counted.
    const DI8: usize = 2;
    rig.segment().power_cycle(DI8);
    assert!(wait_until(|| wkc_errors(&mut client, slaves)[DI8] > 0));
    let after_power_cycle = wkc_errors(&mut client, slaves);
    for (n, count) in after_power_cycle.iter().enumerate() {
        if n != DI8 {
            assert_eq!(*count, 0, "slave {n} after the DI8's power cycle");
        }
    }

    // The line is cut in front of the CoE store: it and the EoE port behind it miss the
    // mailbox-status read; the drive and the DO8 in front are not counted.
    rig.segment().set_plugged(COE_STORE, false);
    assert!(wait_until(|| {
        let counts = wkc_errors(&mut client, slaves);
        counts[COE_STORE] > 0 && counts[COE_STORE + 1] > 0
    }));
    let counts = wkc_errors(&mut client, slaves);
    assert_eq!(counts[DRIVE], 0);
    assert_eq!(counts[1], 0);
    // The master's own API says the same.
    assert_eq!(master.wkc_errors()[DRIVE], 0);
    assert!(master.wkc_errors()[COE_STORE] > 0);
}
