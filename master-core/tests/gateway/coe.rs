//! CoE through the ETG.8200 gateway against the simulated segment: expedited and
//! segmented transfers (the 4 KiB object both ways), the sample clients' short requests, SDO
//! Information with its fragments, addressing by position, and the rewritten counter.

use crate::gateway_support;

use gateway_support::{COE_STORE, DRIVE, GwRig, datagram, sdo, station, test_config};
use master_core::gateway::POSITION_BASE;
use master_core::od::Dictionary;
use master_core::wire::coe::info::od_list::OdListType;
use master_core::wire::coe::{DataType, ObjectCode, SdoPayload, SdoRequest, SdoResponse};
use master_core::wire::mailbox::MailboxType;
use sim::topology::{MailboxSpec, Topology};

fn store_value(rig: &GwRig, index: u16) -> Vec<u8> {
    let dict = rig.handles[COE_STORE]
        .dictionary
        .as_ref()
        .expect("CoE dictionary");
    dict.lock().unwrap().get_bytes(index, 0).unwrap().to_vec()
}

#[test]
fn expedited_upload_and_download_reach_the_slave() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let address = station(COE_STORE);
    let vendor = client.upload(address, 0x1018, 1).expect("0x1018:01");
    assert_eq!(
        vendor,
        rig.topology.slaves[COE_STORE].vendor_id.to_le_bytes()
    );

    client
        .download(address, 0x2001, 0, &0xCAFE_BABEu32.to_le_bytes())
        .expect("download");
    assert_eq!(store_value(&rig, 0x2001), 0xCAFE_BABEu32.to_le_bytes());
    assert_eq!(
        client.upload(address, 0x2001, 0).unwrap(),
        0xCAFE_BABEu32.to_le_bytes()
    );

    let stats = rig.gateway().stats();
    assert_eq!(stats.total_requests, 3);
    assert_eq!(stats.forwarded_requests, 3);
    assert_eq!(stats.coe_count, 3);
    assert_eq!(stats.failed_requests, 0);
    assert_eq!(stats.latency.count(), 3);
    assert!(stats.started_at_ms > 0);
}

#[test]
fn the_4_kib_object_is_transferred_segmented_both_ways() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let address = station(COE_STORE);
    let original = store_value(&rig, 0x2000);
    assert_eq!(original.len(), 4096);
    assert_eq!(client.upload(address, 0x2000, 0).unwrap(), original);

    let new: Vec<u8> = (0..4096u32).map(|i| (i * 7 + 3) as u8).collect();
    client
        .download(address, 0x2000, 0, &new)
        .expect("segmented download");
    assert_eq!(store_value(&rig, 0x2000), new, "the slave stored it");
    assert_eq!(client.upload(address, 0x2000, 0).unwrap(), new);
    // 4096 bytes in 119-byte segments: one initiate plus 35 segments each way, plus the
    // first upload.
    let stats = rig.gateway().stats();
    assert_eq!(stats.failed_requests, 0);
    assert_eq!(stats.forwarded_requests, stats.total_requests);
}

#[test]
fn the_seeds_short_sample_requests_are_served() {
    let rig = GwRig::start(test_config());
    let client = rig.client();
    let address = station(COE_STORE);
    // The short upload of spec-notes §coe.sdo-short: 8 bytes of CoE data (the reserved bytes cut to 2).
    let mut upload = vec![0u8; 8];
    upload[1] = 0x20;
    upload[2] = 0x40;
    upload[3..5].copy_from_slice(&0x1018u16.to_le_bytes());
    upload[5] = 0x02;
    client.send_raw(&datagram(address, MailboxType::Coe, 0, &upload));
    let reply = client.recv();
    assert_eq!(
        reply.sdo(),
        SdoResponse::InitiateUpload {
            index: 0x1018,
            subindex: 2,
            complete_access: false,
            payload: SdoPayload::Expedited(
                &rig.topology.slaves[COE_STORE].product_code.to_le_bytes()
            ),
        }
    );
    // Its download: command 0x20 and the value right after the subindex.
    let mut download = vec![0u8; 6];
    download[1] = 0x20;
    download[2] = 0x20;
    download[3..5].copy_from_slice(&0x2001u16.to_le_bytes());
    download.extend_from_slice(&0x0BAD_F00Du32.to_le_bytes());
    client.send_raw(&datagram(address, MailboxType::Coe, 0, &download));
    let reply = client.recv();
    assert!(
        matches!(
            reply.sdo(),
            SdoResponse::InitiateDownload {
                index: 0x2001,
                subindex: 0,
                ..
            }
        ),
        "{:?}",
        reply.sdo()
    );
    assert_eq!(store_value(&rig, 0x2001), 0x0BAD_F00Du32.to_le_bytes());
}

#[test]
fn sdo_information_comes_back_fragment_by_fragment() {
    // The drive with 32-byte mailboxes, so that its OD list needs several fragments.
    let mut topology = Topology::default_segment();
    topology.slaves[DRIVE].mailbox = Some(MailboxSpec {
        rx_size: 32,
        tx_size: 32,
        start: None,
    });
    let rig = GwRig::with_topology(topology, test_config());
    let mut client = rig.client();
    let dict = rig.handles[DRIVE]
        .dictionary
        .as_ref()
        .expect("drive dictionary");
    let expected = dict.lock().unwrap().indices(OdListType::All);
    let address = station(DRIVE);
    let (data, datagrams) = client
        .info(
            address,
            master_core::wire::coe::SdoInfoService::OdListRequest {
                list_type: OdListType::All,
            },
        )
        .expect("OD list");
    let (_, list) = master_core::wire::coe::info::od_list::OdList(&data)
        .first_fragment()
        .unwrap();
    assert_eq!(list.words().collect::<Vec<_>>(), expected);
    // 32-byte mailbox: 6 mailbox header + 6 SDO Info header leave 20 bytes a fragment.
    let expected_datagrams = (2 + 2 * expected.len()).div_ceil(20);
    assert!(
        expected_datagrams > 1,
        "the drive's list of {} needs fragments",
        expected.len()
    );
    assert_eq!(datagrams, expected_datagrams);

    let object = client.object(station(COE_STORE), 0x2000).unwrap();
    assert_eq!(object.name, "Large object");
    assert_eq!(object.object_code, ObjectCode::Var);
    let entry = client.entry(station(COE_STORE), 0x2001, 0).unwrap();
    assert_eq!(
        (entry.data_type, entry.bit_length),
        (DataType::Unsigned32, 32)
    );
    // Each fragment counts once: the request was one.
    assert_eq!(rig.gateway().stats().forwarded_requests, 3);
}

#[test]
fn position_addresses_reach_the_slave_and_the_reply_carries_the_address_asked() {
    let rig = GwRig::start(test_config());
    let mut client = rig.client();
    let address = POSITION_BASE + COE_STORE as u16;
    let reply = client.request(
        address,
        MailboxType::Coe,
        &sdo(SdoRequest::InitiateUpload {
            index: 0x1018,
            subindex: 4,
            complete_access: false,
        }),
    );
    assert_eq!(reply.header.address, address);
    assert_eq!(reply.from, rig.addr(), "answered from the bound socket");
    assert_eq!(
        reply.sdo(),
        SdoResponse::InitiateUpload {
            index: 0x1018,
            subindex: 4,
            complete_access: false,
            payload: SdoPayload::Expedited(&rig.topology.slaves[COE_STORE].serial.to_le_bytes()),
        }
    );
}

#[test]
fn a_repeated_client_counter_is_never_dropped() {
    let rig = GwRig::start(test_config());
    let client = rig.client();
    let request = sdo(SdoRequest::InitiateUpload {
        index: 0x1018,
        subindex: 1,
        complete_access: false,
    });
    // The same counter five times: a slave would drop every repeat if it were forwarded.
    for _ in 0..5 {
        client.send_raw(&datagram(station(COE_STORE), MailboxType::Coe, 3, &request));
        let reply = client.recv();
        assert!(matches!(reply.sdo(), SdoResponse::InitiateUpload { .. }));
    }
}
