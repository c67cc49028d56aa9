//! FoE through the mailbox engine against the simulator in-process: a 1 MiB file written
//! and read back through BUSY phases, the slave's errors with code and text, cancellation.

use crate::mailbox_support;

use std::sync::{Arc, Mutex};
use std::time::Duration;

use mailbox_support::{DRIVE, Rig};
use master_core::mailbox::{FoeOptions, FoeProgress, MailboxConfig, MailboxError, SlaveMailbox};
use master_core::wire::foe::FoeError;
use sha2::{Digest, Sha256};
use sim::device::foe::{BusyPhase, FileStore, FoeFile, FoeService};
use sim::device::{MailboxStack, SlaveDevice};
use sim::topology::Topology;

const MIB: usize = 1 << 20;

/// The default segment with the drive's FoE server answering BUSY around writes of
/// `*.bin` files: 3 times after the WRQ, 5 times after the last packet.
fn rig_with_busy() -> (Rig, FileStore) {
    let files = Arc::new(Mutex::new(None));
    let keep = Arc::clone(&files);
    let rig = Rig::start_with(
        &Topology::default_segment(),
        Default::default(),
        7,
        mailbox_support::bus_config(),
        MailboxConfig::default(),
        move |segment, handles| {
            let store = handles[DRIVE].files.clone().unwrap();
            let busy = BusyPhase {
                after_write_request: 3,
                after_last_packet: 5,
                ..BusyPhase::default()
            };
            let stack = MailboxStack::new().with(FoeService::new(store.clone()).with_busy(busy));
            *keep.lock().unwrap() = Some(store);
            segment
                .slave_mut(DRIVE)
                .unwrap()
                .replace_device(Box::new(SlaveDevice::new().with_mailbox(stack)));
        },
    );
    let store = files.lock().unwrap().take().unwrap();
    (rig, store)
}

fn file(len: usize) -> Vec<u8> {
    let mut state = 0x1234_5678u32;
    (0..len)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as u8
        })
        .collect()
}

#[tokio::test]
async fn a_1_mib_file_written_and_read_back_has_the_same_sha256() {
    let (rig, store) = rig_with_busy();
    let drive = rig.slave(DRIVE).with_timeout(Duration::from_secs(120));
    // What the scan did (its CoE read of 0x1000 is refused by this FoE-only device) is
    // not this transfer's.
    let before = drive.stats();
    let content = file(MIB);
    let reports = Arc::new(Mutex::new(Vec::new()));
    let log = Arc::clone(&reports);
    let options = FoeOptions {
        password: 0,
        progress: Some(Arc::new(move |p: FoeProgress| log.lock().unwrap().push(p))),
    };
    // firmware.bin exists (1 KiB); the store holds 1 MiB, so it is replaced in place.
    drive
        .foe_write("firmware.bin", &content, options.clone())
        .await
        .unwrap();
    assert_eq!(
        Sha256::digest(store.data("firmware.bin").unwrap()),
        Sha256::digest(&content),
        "the slave stored the file"
    );
    let busy: Vec<_> = reports
        .lock()
        .unwrap()
        .iter()
        .filter_map(|p| match p {
            FoeProgress::Busy { done, entire, text } => Some((*done, *entire, text.clone())),
            FoeProgress::Transferred { .. } => None,
        })
        .collect();
    let mut expected: Vec<_> = (0..3).map(|i| (i, 3, "flashing".to_string())).collect();
    expected.extend((0..5).map(|i| (i, 5, "flashing".to_string())));
    assert_eq!(busy, expected, "every BUSY phase reported");
    assert!(matches!(
        reports.lock().unwrap().last(),
        Some(FoeProgress::Transferred {
            bytes: MIB,
            total: Some(MIB)
        })
    ));
    reports.lock().unwrap().clear();
    let read = drive.foe_read("firmware.bin", options).await.unwrap();
    assert_eq!(Sha256::digest(&read), Sha256::digest(&content));
    assert!(matches!(
        reports.lock().unwrap().last(),
        Some(FoeProgress::Transferred {
            bytes: MIB,
            total: None
        })
    ));
    let stats = drive.stats();
    assert_eq!(
        (
            stats.failed - before.failed,
            stats.unexpected - before.unexpected,
            stats.duplicates - before.duplicates
        ),
        (0, 0, 0)
    );
}

#[tokio::test]
async fn files_whose_size_is_a_multiple_of_the_packet_size_end_with_an_empty_packet() {
    let rig = Rig::default_segment();
    let drive = rig.slave(DRIVE);
    let store = rig.handles[DRIVE].files.clone().unwrap();
    // 128-byte mailboxes: 116 data bytes per packet.
    for len in [0, 116, 232, 117] {
        let content = file(len);
        drive
            .foe_write("plain.txt", &content, FoeOptions::default())
            .await
            .unwrap();
        assert_eq!(store.data("plain.txt").unwrap(), content, "{len} bytes");
        let read = drive
            .foe_read("plain.txt", FoeOptions::default())
            .await
            .unwrap();
        assert_eq!(read, content, "{len} bytes back");
    }
}

#[tokio::test]
async fn the_slaves_foe_errors_come_with_code_and_text() {
    let rig = Rig::default_segment();
    let drive = rig.slave(DRIVE);
    let store = rig.handles[DRIVE].files.clone().unwrap();
    store.insert(
        "secret.bin",
        FoeFile::new(b"classified".to_vec()).with_password(0xC0DE),
    );
    store.insert("rom.txt", FoeFile::new(b"fixed".to_vec()).read_only());
    let err = drive
        .foe_read("missing.txt", FoeOptions::default())
        .await
        .unwrap_err();
    assert_eq!(
        err,
        MailboxError::Foe {
            code: FoeError::NotFound,
            text: FoeError::NotFound.description().to_string()
        }
    );
    assert!(err.to_string().contains("0x8001"), "{err}");
    let err = drive
        .foe_read("secret.bin", FoeOptions::default())
        .await
        .unwrap_err();
    assert!(
        matches!(
            err,
            MailboxError::Foe {
                code: FoeError::NoRights,
                ..
            }
        ),
        "{err}"
    );
    let with_password = FoeOptions {
        password: 0xC0DE,
        ..FoeOptions::default()
    };
    assert_eq!(
        drive.foe_read("secret.bin", with_password).await.unwrap(),
        b"classified"
    );
    let err = drive
        .foe_write("rom.txt", b"new", FoeOptions::default())
        .await
        .unwrap_err();
    assert!(
        matches!(
            err,
            MailboxError::Foe {
                code: FoeError::AccessDenied,
                ..
            }
        ),
        "{err}"
    );
    assert_eq!(store.data("rom.txt").unwrap(), b"fixed");
}

/// Options whose progress callback says once 64 KiB of a write are through.
fn signal_halfway() -> (FoeOptions, tokio::sync::mpsc::UnboundedReceiver<()>) {
    let (halfway, reached) = tokio::sync::mpsc::unbounded_channel();
    let options = FoeOptions {
        password: 0,
        progress: Some(Arc::new(move |p: FoeProgress| {
            if let FoeProgress::Transferred { bytes, .. } = p
                && bytes >= 64 * 1024
            {
                let _ = halfway.send(());
            }
        })),
    };
    (options, reached)
}

/// The dropped write was counted as cancelled and stored nothing.
fn assert_cancelled_without_a_trace(drive: &SlaveMailbox, store: &FileStore, before: &[u8]) {
    mailbox_support::wait_until("the cancellation", Duration::from_secs(10), || {
        drive.stats().cancelled == 1
    });
    assert_eq!(
        store.data("firmware.bin").unwrap(),
        before,
        "nothing stored"
    );
}

#[tokio::test]
async fn a_cancelled_write_is_ended_towards_the_slave() {
    let rig = Rig::default_segment();
    let drive = rig.slave(DRIVE).with_timeout(Duration::from_secs(60));
    let store = rig.handles[DRIVE].files.clone().unwrap();
    let before = store.data("firmware.bin").unwrap();
    let (options, mut reached) = signal_halfway();
    let content = file(256 * 1024);
    tokio::select! {
        result = drive.foe_write("firmware.bin", &content, options) => {
            panic!("the write finished before it was cancelled: {result:?}")
        }
        _ = reached.recv() => {}
    }
    // The write's future is dropped: the engine ends the transfer with an FoE ERROR.
    assert_cancelled_without_a_trace(&drive, &store, &before);
    // The slave's FoE server is idle: the next transfer works from the start.
    let read = drive
        .foe_read("firmware.bin", FoeOptions::default())
        .await
        .unwrap();
    assert_eq!(read, before);
}

/// A request runs in its caller's future; when the caller's whole runtime goes away in the
/// middle of a transfer, the rest of the work moves to the engine's thread, which ends the
/// transfer towards the slave the protocol's way, so the next caller finds the mailbox clean.
#[test]
fn a_write_whose_runtime_shuts_down_is_ended_and_the_next_request_works() {
    let rig = Rig::default_segment();
    let drive = rig.slave(DRIVE).with_timeout(Duration::from_secs(60));
    let store = rig.handles[DRIVE].files.clone().unwrap();
    let before = store.data("firmware.bin").unwrap();
    let caller = tokio::runtime::Builder::new_current_thread()
        .build()
        .unwrap();
    let (options, mut reached) = signal_halfway();
    let content = file(256 * 1024);
    let writer = drive.clone();
    let write =
        caller.spawn(async move { writer.foe_write("firmware.bin", &content, options).await });
    // The caller's runtime runs the transfer on this thread until half of it is through.
    caller.block_on(async {
        while reached.try_recv().is_err() {
            assert!(
                !write.is_finished(),
                "the write ended before half of it was through"
            );
            tokio::task::yield_now().await;
        }
    });
    drop(caller);
    assert_cancelled_without_a_trace(&drive, &store, &before);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .build()
        .unwrap();
    let read = runtime
        .block_on(drive.foe_read("firmware.bin", FoeOptions::default()))
        .unwrap();
    assert_eq!(read, before);
    assert_eq!(drive.stats().failed, 0, "{:?}", drive.stats());
}

#[tokio::test]
async fn files_survive_ten_percent_frame_loss() {
    // Thousands of exchanges with lost reads (recovered by the repeat procedure, twice in
    // a row at times) and lost writes (resent by the bus, discarded by the slave's counter).
    for seed in [1u64, 2, 3] {
        let faults = master_core::link::FaultConfig {
            drop_tx: 0.05,
            drop_rx: 0.05,
            ..Default::default()
        };
        let config = MailboxConfig {
            timeout: Duration::from_secs(60),
            idle_poll: None,
            ..MailboxConfig::default()
        };
        let rig = Rig::start_with(
            &Topology::default_segment(),
            faults,
            seed,
            mailbox_support::bus_config(),
            config,
            |_, _| {},
        );
        let drive = rig.slave(DRIVE);
        let content = file(64 * 1024);
        drive
            .foe_write("lossy.txt", &content, FoeOptions::default())
            .await
            .unwrap();
        let read = drive
            .foe_read("lossy.txt", FoeOptions::default())
            .await
            .unwrap();
        assert_eq!(
            Sha256::digest(&read),
            Sha256::digest(&content),
            "seed {seed}"
        );
        // The owner may still be recovering a read it sent ahead of the transfer's end when
        // the result came back: every lost read gets its repeat request, at its own pace.
        mailbox_support::wait_until("every lost read repeated", Duration::from_secs(10), || {
            let stats = drive.stats();
            stats.repeats == stats.lost_reads
        });
        let stats = drive.stats();
        assert!(stats.lost_reads > 0, "seed {seed}: {stats:?}");
        assert_eq!(
            (stats.failed, stats.unexpected),
            (0, 0),
            "seed {seed}: {stats:?}"
        );
    }
}
