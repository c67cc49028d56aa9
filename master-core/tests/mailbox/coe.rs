//! CoE through the mailbox engine against the simulator in-process: SDO transfers of every
//! form, complete access, aborts, SDO Information, emergencies, raw transactions. Expected
//! values come from the simulated slaves' dictionaries.

use crate::mailbox_support;

use std::time::Duration;

use mailbox_support::{COE_STORE, DRIVE, Rig, station};
use master_core::mailbox::MailboxError;
use master_core::od::Dictionary;
use master_core::wire::coe::info::OdListType;
use master_core::wire::coe::sdo::SdoFrame;
use master_core::wire::coe::{AbortCode, SdoPayload, SdoRequest, SdoResponse};
use master_core::wire::mailbox::{HEADER_LEN, Mailbox, MailboxHeader, MailboxType};
use sim::device::coe::{SharedDictionary, lock_dictionary};
use sim::topology::{SIM_VENDOR_ID, Topology};

fn dictionary(rig: &Rig, position: usize) -> SharedDictionary {
    rig.handles[position]
        .dictionary
        .clone()
        .expect("a CoE slave")
}

fn bytes(dict: &SharedDictionary, index: u16, subindex: u8) -> Vec<u8> {
    lock_dictionary(dict)
        .get_bytes(index, subindex)
        .unwrap()
        .to_vec()
}

fn pattern(len: usize, seed: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u8).wrapping_mul(31).wrapping_add(seed))
        .collect()
}

#[tokio::test]
async fn sdo_download_and_upload_of_1_2_4_100_and_4096_bytes() {
    let rig = Rig::default_segment();
    let store = rig.slave(COE_STORE);
    let dict = dictionary(&rig, COE_STORE);
    for (n, len) in [1usize, 2, 4, 100, 4096].into_iter().enumerate() {
        let value = pattern(len, n as u8);
        let before = lock_dictionary(&dict).write_count(0x2000);
        store.sdo_download(0x2000, 0, &value).await.unwrap();
        assert_eq!(bytes(&dict, 0x2000, 0), value, "{len} bytes stored");
        assert_eq!(
            lock_dictionary(&dict).write_count(0x2000),
            before + 1,
            "one write for {len} bytes"
        );
        // Change it behind the master's back, so the upload must really read it.
        let changed = pattern(len, 0x80 | n as u8);
        lock_dictionary(&dict).set(0x2000, 0, &changed[..]).unwrap();
        assert_eq!(
            store.sdo_upload(0x2000, 0).await.unwrap(),
            changed,
            "{len} bytes read"
        );
    }
    // Typed objects of the drive.
    let drive = rig.slave(DRIVE);
    assert_eq!(
        drive.sdo_upload(0x1018, 1).await.unwrap(),
        SIM_VENDOR_ID.to_le_bytes()
    );
    drive
        .sdo_download(0x607A, 0, &(-12345i32).to_le_bytes())
        .await
        .unwrap();
    assert_eq!(
        lock_dictionary(&dictionary(&rig, DRIVE))
            .get::<i32>(0x607A, 0)
            .unwrap(),
        -12345
    );
    let stats = store.stats();
    assert_eq!(
        (stats.failed, stats.unexpected, stats.duplicates),
        (0, 0, 0)
    );
}

#[tokio::test]
async fn complete_access_reads_and_writes_whole_objects() {
    let rig = Rig::default_segment();
    let drive = rig.slave(DRIVE);
    let dict = dictionary(&rig, DRIVE);
    // 0x1018 from subindex 0: SI0 padded to 16 bits, then the four u32 entries.
    let mut expected = vec![bytes(&dict, 0x1018, 0)[0], 0];
    for sub in 1..=4 {
        expected.extend(bytes(&dict, 0x1018, sub));
    }
    assert_eq!(
        drive.sdo_upload_complete(0x1018, 0).await.unwrap(),
        expected
    );
    assert_eq!(
        drive.sdo_upload_complete(0x1018, 1).await.unwrap(),
        expected[2..],
        "from subindex 1"
    );
    // The RxPDO assignment in one transfer: one PDO, 0x1600.
    let before = lock_dictionary(&dict).write_count(0x1C12);
    drive
        .sdo_download_complete(0x1C12, 0, &[1, 0, 0x00, 0x16])
        .await
        .unwrap();
    assert_eq!(lock_dictionary(&dict).write_count(0x1C12), before + 1);
    assert_eq!(
        lock_dictionary(&dict).get::<u16>(0x1C12, 1).unwrap(),
        0x1600
    );
}

#[tokio::test]
async fn every_abort_reaches_the_caller_with_its_code() {
    let rig = Rig::default_segment();
    let drive = rig.slave(DRIVE);
    let cases: [(u16, u8, Option<Vec<u8>>, AbortCode); 5] = [
        (0x5555, 0, None, AbortCode::ObjectDoesNotExist),
        (0x1018, 9, None, AbortCode::SubindexDoesNotExist),
        (0x1018, 1, Some(vec![1, 2, 3, 4]), AbortCode::ReadOnly),
        (0x6040, 0, Some(vec![1, 2, 3, 4]), AbortCode::LengthTooHigh),
        (0x5555, 0, Some(vec![0; 300]), AbortCode::ObjectDoesNotExist),
    ];
    for (index, subindex, write, code) in cases {
        let result = match &write {
            None => drive.sdo_upload(index, subindex).await.map(drop),
            Some(data) => drive.sdo_download(index, subindex, data).await,
        };
        let err = result.unwrap_err();
        assert_eq!(
            err,
            MailboxError::SdoAbort {
                index,
                subindex,
                code
            },
            "{index:#06x}:{subindex} write={}",
            write.is_some()
        );
        assert!(err.to_string().contains(code.description()), "{err}");
    }
    // The slave's SDO server is idle again: a normal request works.
    assert_eq!(drive.sdo_upload(0x6040, 0).await.unwrap().len(), 2);
}

#[tokio::test]
async fn sdo_information_matches_the_dictionary() {
    // A small send mailbox, so that lists and descriptions come in fragments.
    let mut topology = Topology::default_segment();
    let small = 24;
    topology.slaves[DRIVE].mailbox.as_mut().unwrap().tx_size = small;
    let rig = Rig::start(
        &topology,
        Default::default(),
        1,
        mailbox_support::bus_config(),
    );
    let drive = rig.slave(DRIVE);
    let dict = dictionary(&rig, DRIVE);
    let lists = [
        OdListType::All,
        OdListType::RxPdoMappable,
        OdListType::TxPdoMappable,
        OdListType::Backup,
        OdListType::Settings,
    ];
    let mut lengths = Vec::new();
    for list in lists {
        let expected = Dictionary::indices(&*lock_dictionary(&dict), list);
        assert_eq!(
            drive.sdo_info_od_list(list).await.unwrap(),
            expected,
            "{list}"
        );
        lengths.push(expected.len() as u16);
    }
    // 6 mailbox + 2 CoE + 4 SDO Info header bytes per fragment.
    let words_per_fragment = (usize::from(small) - 12) / 2;
    assert!(
        usize::from(lengths[0]) > 2 * words_per_fragment,
        "the full list needs several fragments"
    );
    assert_eq!(
        drive.sdo_info_od_list(OdListType::Lengths).await.unwrap(),
        lengths
    );
    // Descriptions come in one message each (the simulator cuts long names to fit SM1),
    // so they are compared on a slave with the default 128-byte mailbox.
    let rig = Rig::default_segment();
    let drive = rig.slave(DRIVE);
    let dict = dictionary(&rig, DRIVE);
    let objects: Vec<_> = lock_dictionary(&dict).objects().cloned().collect();
    for object in &objects {
        let info = drive.sdo_info_object(object.index).await.unwrap();
        assert_eq!(info.index, object.index);
        assert_eq!(info.name, object.name);
        assert_eq!(info.object_code, object.object_code);
        assert_eq!(info.data_type, object.data_type);
        assert_eq!(info.max_subindex, object.max_subindex());
    }
    let identity = objects.iter().find(|o| o.index == 0x1018).unwrap();
    for entry in &identity.entries {
        let info = drive
            .sdo_info_entry(0x1018, entry.subindex, 0x70)
            .await
            .unwrap();
        assert_eq!(info.description, entry.name);
        assert_eq!(info.data_type, entry.data_type);
        assert_eq!(info.bit_length, entry.bit_length);
        assert_eq!(info.access, entry.access);
        assert_eq!(info.default, entry.default);
    }
    let err = drive.sdo_info_object(0x5555).await.unwrap_err();
    assert_eq!(err, MailboxError::SdoInfo(AbortCode::ObjectDoesNotExist));
}

#[tokio::test]
async fn a_raw_transaction_returns_the_slaves_answer() {
    let rig = Rig::default_segment();
    let drive = rig.slave(DRIVE);
    let request = SdoRequest::InitiateUpload {
        index: 0x1018,
        subindex: 2,
        complete_access: false,
    };
    let mut message = vec![0u8; HEADER_LEN + request.buffer_len()];
    MailboxHeader {
        length: request.buffer_len() as u16,
        address: 0,
        channel: 0,
        priority: 0,
        mailbox_type: MailboxType::Coe,
        counter: 0,
    }
    .emit(&mut Mailbox::new_unchecked(&mut message[..]))
    .unwrap();
    request
        .emit(&mut SdoFrame::new_unchecked(&mut message[HEADER_LEN..]))
        .unwrap();
    let answer = drive
        .raw(MailboxType::Coe, &message[HEADER_LEN..])
        .await
        .unwrap();
    let answer = answer.message();
    let header = MailboxHeader::parse(&Mailbox::new_checked(answer).unwrap()).unwrap();
    assert_eq!(header.mailbox_type, MailboxType::Coe);
    let response = SdoResponse::parse(&SdoFrame::new_checked(&answer[HEADER_LEN..]).unwrap());
    let expected = bytes(&dictionary(&rig, DRIVE), 0x1018, 2);
    match response.unwrap() {
        SdoResponse::InitiateUpload {
            index: 0x1018,
            subindex: 2,
            payload: SdoPayload::Expedited(value),
            ..
        } => assert_eq!(value, expected),
        other => panic!("unexpected answer {other}"),
    }
    // A protocol the slave does not have: the mailbox error reply comes back as it is.
    let eoe_port = rig.slave(mailbox_support::EOE_PORT);
    let answer = eoe_port
        .raw(MailboxType::Coe, &message[HEADER_LEN..])
        .await
        .unwrap();
    let answer = answer.message();
    assert_eq!(answer[5] & 0x0F, 0, "a mailbox error reply (type 0)");
    assert_eq!(
        &answer[6..10],
        &[0x01, 0x00, 0x02, 0x00],
        "0x0002 unsupported"
    );
}

#[tokio::test]
async fn a_protocol_the_slave_does_not_announce_is_refused_by_the_master() {
    let rig = Rig::default_segment();
    let eoe_port = rig.slave(mailbox_support::EOE_PORT);
    assert!(!eoe_port.config().protocols.supports(MailboxType::Coe));
    assert_eq!(
        eoe_port.sdo_upload(0x1000, 0).await.unwrap_err(),
        MailboxError::Unsupported {
            station: station(mailbox_support::EOE_PORT),
            protocol: MailboxType::Coe
        }
    );
    assert_eq!(
        rig.engine().slave(0x0999).unwrap_err(),
        MailboxError::UnknownSlave(0x0999)
    );
}

/// An emergency to raise: error code, error register, manufacturer data.
type Raise = (u16, u8, [u8; 5]);

#[tokio::test]
async fn emergencies_go_to_history_and_subscribers_never_to_a_transfer() {
    let rig = Rig::default_segment();
    let trigger = rig.handles[COE_STORE].emergencies.clone().unwrap();
    let store = rig.slave(COE_STORE);
    let mut events = store.subscribe_emergencies();
    let raised: Vec<Raise> = (0..40u16)
        .map(|i| (0x8100 + i, i as u8, [i as u8, 1, 2, 3, 4]))
        .collect();
    let value = pattern(4096, 9);
    for chunk in raised.chunks(4) {
        for &(code, register, data) in chunk {
            assert!(trigger.raise(code, register, data));
        }
        // A segmented transfer while emergencies come in between its answers.
        store.sdo_download(0x2000, 0, &value).await.unwrap();
        assert_eq!(store.sdo_upload(0x2000, 0).await.unwrap(), value);
    }
    let mut seen = Vec::new();
    while seen.len() < raised.len() {
        let event = tokio::time::timeout(Duration::from_secs(5), events.recv())
            .await
            .expect("every emergency is published")
            .unwrap();
        assert_eq!(event.station, station(COE_STORE));
        seen.push((event.error_code, event.error_register, event.data));
    }
    assert_eq!(seen, raised);
    let history = store.emergencies();
    assert_eq!(history.len(), 32, "the default history keeps the last 32");
    assert_eq!(history.last().unwrap().error_code, 0x8100 + 39);
    assert_eq!(history.first().unwrap().error_code, 0x8100 + 8);
    let stats = store.stats();
    assert_eq!(stats.emergencies, 40);
    assert_eq!((stats.unexpected, stats.failed), (0, 0));
}

#[tokio::test]
async fn a_transfer_cancelled_at_any_point_leaves_the_mailbox_clean() {
    let rig = Rig::default_segment();
    let store = rig.slave(COE_STORE);
    let dict = dictionary(&rig, COE_STORE);
    let big = pattern(4096, 77);
    lock_dictionary(&dict).set(0x2000, 0, &big[..]).unwrap();
    // Drop segmented uploads after ever longer times: before they start, after a few
    // segments, after they finished. Whatever point the cancellation hits, the next
    // request gets its own answer, never a leftover of the cancelled one.
    for step in 0..40u64 {
        let cancelled = tokio::time::timeout(
            Duration::from_micros(step * 50),
            store.sdo_upload(0x2000, 0),
        )
        .await;
        if let Ok(done) = cancelled {
            assert_eq!(done.unwrap(), big);
        }
        assert_eq!(
            store.sdo_upload(0x2001, 0).await.unwrap(),
            bytes(&dict, 0x2001, 0),
            "after cancelling at {} µs",
            step * 50
        );
        assert_eq!(store.sdo_upload(0x2000, 0).await.unwrap(), big);
    }
    let stats = store.stats();
    assert!(stats.cancelled > 0, "{stats:?}");
    assert_eq!((stats.unexpected, stats.failed), (0, 0), "{stats:?}");
}
