//! SoE through the mailbox engine against the simulated drive: values read and written in
//! several fragments, element selection, drive numbers, the drive's error codes.

use crate::mailbox_support;

use mailbox_support::{DRIVE, Rig, station};
use master_core::mailbox::MailboxError;
use master_core::wire::soe::{ElementFlags, Idn, SoeError};
use sim::device::soe::defaults::{MANUFACTURER_VERSION, MANUFACTURER_VERSION_TEXT};
use sim::topology::Topology;

/// A list element as it travels: current length, maximum length, contents.
fn list(contents: &[u8], max: u16) -> Vec<u8> {
    let mut out = (contents.len() as u16).to_le_bytes().to_vec();
    out.extend_from_slice(&max.to_le_bytes());
    out.extend_from_slice(contents);
    out
}

/// The drive with 32-byte mailboxes: 22 bytes of element data per fragment.
fn small_mailbox_rig() -> Rig {
    let mut topology = Topology::default_segment();
    let mailbox = topology.slaves[DRIVE].mailbox.as_mut().unwrap();
    mailbox.rx_size = 32;
    mailbox.tx_size = 32;
    Rig::start(
        &topology,
        Default::default(),
        3,
        mailbox_support::bus_config(),
    )
}

#[tokio::test]
async fn values_longer_than_a_mailbox_are_read_and_written_in_fragments() {
    let rig = small_mailbox_rig();
    let drive = rig.slave(DRIVE);
    // S-0-0030, a 58-character text: 62 bytes in three read fragments.
    let text = MANUFACTURER_VERSION_TEXT.as_bytes();
    assert!(text.len() + 4 > 2 * 22);
    let value = drive
        .soe_read(0, Idn::from_raw(MANUFACTURER_VERSION), ElementFlags::VALUE)
        .await
        .unwrap();
    assert_eq!(value, list(text, 64));
    // S-0-0024, the MDT configuration list: 16 IDNs (36 bytes) in two write fragments.
    let idns: Vec<u8> = (1..=16u16)
        .flat_map(|i| (0x0100 + i).to_le_bytes())
        .collect();
    let written = list(&idns, 32);
    assert!(written.len() > 22);
    let mdt = Idn::from_raw(24);
    drive
        .soe_write(0, mdt, ElementFlags::VALUE, &written)
        .await
        .unwrap();
    assert_eq!(
        drive.soe_read(0, mdt, ElementFlags::VALUE).await.unwrap(),
        written
    );
    let stats = drive.stats();
    assert_eq!((stats.failed, stats.unexpected), (0, 0));
}

#[tokio::test]
async fn elements_other_than_the_value_and_fixed_size_idns() {
    let rig = Rig::default_segment();
    let drive = rig.slave(DRIVE);
    let name = drive
        .soe_read(0, Idn::from_raw(MANUFACTURER_VERSION), ElementFlags::NAME)
        .await
        .unwrap();
    assert_eq!(name[4..], *b"Manufacturer version");
    // S-0-0036 velocity command value: a signed 32-bit value with limits ±1 000 000.
    let velocity = Idn::from_raw(36);
    drive
        .soe_write(0, velocity, ElementFlags::VALUE, &(-4321i32).to_le_bytes())
        .await
        .unwrap();
    assert_eq!(
        drive
            .soe_read(0, velocity, ElementFlags::VALUE)
            .await
            .unwrap(),
        (-4321i32).to_le_bytes()
    );
    assert_eq!(
        drive
            .soe_read(0, velocity, ElementFlags::MAXIMUM)
            .await
            .unwrap(),
        1_000_000i32.to_le_bytes()
    );
}

#[tokio::test]
async fn the_drives_error_codes_reach_the_caller() {
    let rig = Rig::default_segment();
    let drive = rig.slave(DRIVE);
    let cases = [
        (0u8, 999u16, None, SoeError::NoIdn),
        (
            0,
            MANUFACTURER_VERSION,
            Some(vec![0; 8]),
            SoeError::DataReadOnly,
        ),
        (3, 1, None, SoeError::InvalidDriveNumber),
        (0, 36, Some(vec![0xFF; 4 + 1]), SoeError::DataTooLong),
    ];
    for (drive_number, number, write, code) in cases {
        let idn = Idn::from_raw(number);
        let result = match &write {
            None => drive
                .soe_read(drive_number, idn, ElementFlags::VALUE)
                .await
                .map(drop),
            Some(data) => {
                drive
                    .soe_write(drive_number, idn, ElementFlags::VALUE, data)
                    .await
            }
        };
        let err = result.unwrap_err();
        assert_eq!(
            err,
            MailboxError::Soe {
                drive: drive_number,
                idn,
                code
            }
        );
        assert!(err.to_string().contains(code.description()), "{err}");
    }
    assert!(matches!(
        drive
            .soe_read(8, Idn::from_raw(1), ElementFlags::VALUE)
            .await,
        Err(MailboxError::Invalid(_))
    ));
    assert_eq!(drive.station(), station(DRIVE));
}

#[tokio::test]
async fn each_drive_of_a_multi_axis_slave_has_its_own_idns() {
    let mut topology = Topology::default_segment();
    topology.slaves[DRIVE].soe_drives = 2;
    let rig = Rig::start(
        &topology,
        Default::default(),
        4,
        mailbox_support::bus_config(),
    );
    let drive = rig.slave(DRIVE);
    let mode = Idn::from_raw(32);
    let before = drive.soe_read(0, mode, ElementFlags::VALUE).await.unwrap();
    drive
        .soe_write(1, mode, ElementFlags::VALUE, &0x0007u32.to_le_bytes())
        .await
        .unwrap();
    // The default drive's S-0-0032 holds 4 bytes (sim/src/topology/default.rs).
    assert_eq!(
        drive.soe_read(1, mode, ElementFlags::VALUE).await.unwrap(),
        0x0007u32.to_le_bytes()
    );
    assert_eq!(
        drive.soe_read(0, mode, ElementFlags::VALUE).await.unwrap(),
        before,
        "drive 0 untouched"
    );
}
