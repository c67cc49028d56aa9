//! The SyncManager and FMMU writes of the reference capture (spec-notes §capture), a
//! published bring-up by another master: SM0 mailbox out at 0x1000, SM1 mailbox in at 0x1400, SM2
//! outputs at 0x1800, SM3 inputs at 0x1C00; FMMUs mapping 0x1800 to logical 0x12000, 0x1C00
//! to 0x11000, and bit 3 of SM1's status byte (0x080D) to logical 0x40000.
//!
//! The walk-through shows screenshots, not bytes, for lengths; the lengths below (128-byte
//! mailboxes, 2 bytes of outputs and inputs) are ours. Expected bytes are written out by hand
//! from the register layouts (ETG.1000.4, spec-notes §esc.fmmu, §esc.sm).

use master_core::wire::command::{Command, DatagramAddress};
use master_core::wire::datagram::{DatagramRepr, FrameBuilder};
use master_core::wire::frame::EthercatFrame;
use master_core::wire::register::address;
use master_core::wire::register::fmmu::{Fmmu, FmmuRepr};
use master_core::wire::register::sync_manager::{SyncManager, SyncManagerRepr};

const STATION: u16 = 0x03e9;

fn sm_bytes(repr: &SyncManagerRepr) -> [u8; 8] {
    let mut out = [0xa5u8; 8];
    repr.emit(&mut SyncManager::new_unchecked(&mut out[..]))
        .expect("emit SM");
    out
}

fn fmmu_bytes(repr: &FmmuRepr) -> [u8; 16] {
    let mut out = [0xa5u8; 16];
    repr.emit(&mut Fmmu::new_unchecked(&mut out[..]))
        .expect("emit FMMU");
    out
}

#[test]
fn sync_manager_writes() {
    let cases: [(SyncManagerRepr, [u8; 8]); 4] = [
        // start 0x1000, len 128, control 0x26 (mailbox, write, PDI irq), activate 1
        (
            SyncManagerRepr::mailbox_out(0x1000, 128),
            [0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00],
        ),
        // start 0x1400, len 128, control 0x22 (mailbox, read, PDI irq)
        (
            SyncManagerRepr::mailbox_in(0x1400, 128),
            [0x00, 0x14, 0x80, 0x00, 0x22, 0x00, 0x01, 0x00],
        ),
        // start 0x1800, len 2, control 0x64 (buffered, write, PDI irq, watchdog)
        (
            SyncManagerRepr::outputs(0x1800, 2),
            [0x00, 0x18, 0x02, 0x00, 0x64, 0x00, 0x01, 0x00],
        ),
        // start 0x1C00, len 2, control 0x20 (buffered, read, PDI irq)
        (
            SyncManagerRepr::inputs(0x1c00, 2),
            [0x00, 0x1c, 0x02, 0x00, 0x20, 0x00, 0x01, 0x00],
        ),
    ];
    for (repr, bytes) in &cases {
        assert_eq!(&sm_bytes(repr), bytes);
        let parsed =
            SyncManagerRepr::parse(&SyncManager::new_checked(&bytes[..]).unwrap()).unwrap();
        assert_eq!(&parsed, repr);
    }
}

#[test]
fn fmmu_writes() {
    let status_bit = FmmuRepr {
        logical_start: 0x40000,
        length: 1,
        logical_start_bit: 3,
        logical_stop_bit: 3,
        physical_start: address::sync_manager_status(1).expect("SM1"),
        physical_start_bit: 3,
        read: true,
        write: false,
        enable: true,
    };
    let cases: [(FmmuRepr, [u8; 16]); 3] = [
        (
            FmmuRepr::outputs(0x12000, 2, 0x1800),
            [
                0x00, 0x20, 0x01, 0x00, 0x02, 0x00, 0x00, 0x07, 0x00, 0x18, 0x00, 0x02, 0x01, 0, 0,
                0,
            ],
        ),
        (
            FmmuRepr::inputs(0x11000, 2, 0x1c00),
            [
                0x00, 0x10, 0x01, 0x00, 0x02, 0x00, 0x00, 0x07, 0x00, 0x1c, 0x00, 0x01, 0x01, 0, 0,
                0,
            ],
        ),
        (
            status_bit,
            [
                0x00, 0x00, 0x04, 0x00, 0x01, 0x00, 0x03, 0x03, 0x0d, 0x08, 0x03, 0x01, 0x01, 0, 0,
                0,
            ],
        ),
    ];
    for (repr, bytes) in &cases {
        assert_eq!(&fmmu_bytes(repr), bytes);
        let parsed = FmmuRepr::parse(&Fmmu::new_checked(&bytes[..]).unwrap()).unwrap();
        assert_eq!(&parsed, repr);
    }
    assert_eq!(status_bit.bit_count(), 1);
}

/// All of the above as the master sends them: one frame, FPWRs to the SM and FMMU registers.
#[test]
fn configuration_frame_round_trips() {
    let sms = [
        sm_bytes(&SyncManagerRepr::mailbox_out(0x1000, 128)),
        sm_bytes(&SyncManagerRepr::mailbox_in(0x1400, 128)),
        sm_bytes(&SyncManagerRepr::outputs(0x1800, 2)),
        sm_bytes(&SyncManagerRepr::inputs(0x1c00, 2)),
    ];
    let sm_block: Vec<u8> = sms.concat();
    let fmmus = [
        fmmu_bytes(&FmmuRepr::outputs(0x12000, 2, 0x1800)),
        fmmu_bytes(&FmmuRepr::inputs(0x11000, 2, 0x1c00)),
    ];
    let fmmu_block: Vec<u8> = fmmus.concat();
    let mut buf = [0u8; 256];
    let mut builder = FrameBuilder::new(&mut buf).unwrap();
    let sm_at = address::sync_manager(0).unwrap();
    let fmmu_at = address::fmmu(0).unwrap();
    builder
        .push(&DatagramRepr::request(
            Command::Fpwr,
            1,
            DatagramAddress::Node {
                station: STATION,
                ado: sm_at,
            },
            &sm_block,
        ))
        .unwrap();
    builder
        .push(&DatagramRepr::request(
            Command::Fpwr,
            2,
            DatagramAddress::Node {
                station: STATION,
                ado: fmmu_at,
            },
            &fmmu_block,
        ))
        .unwrap();
    let len = builder.finish([2, 0, 0, 0, 0, 1]).unwrap();
    let frame = EthercatFrame::parse(&buf[..len]).unwrap();
    let datagrams: Vec<_> = frame
        .datagrams()
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    assert_eq!(datagrams.len(), 2);
    assert_eq!(
        (datagrams[0].address, datagrams[0].data),
        (u32::from(sm_at) << 16 | u32::from(STATION), &sm_block[..])
    );
    assert_eq!(
        (datagrams[1].address, datagrams[1].data),
        (
            u32::from(fmmu_at) << 16 | u32::from(STATION),
            &fmmu_block[..]
        )
    );
    assert!(datagrams[0].more && !datagrams[1].more);
    // EtherCAT length: two datagrams of 12 bytes overhead + 32 + 32 data bytes.
    assert_eq!(frame.header.length, 12 + 32 + 12 + 32);
}
