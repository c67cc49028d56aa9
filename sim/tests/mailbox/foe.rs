//! The simulated FoE server: multi-packet reads and writes, BUSY phases, every error code
//! with its text, packet-number checks.

use crate::mailbox_support;

use ecat_wire::Emit;
use ecat_wire::foe::{FoeError, FoePacket, FoeRepr};
use ecat_wire::mailbox::MailboxType;
use sim::device::MailboxStack;
use sim::device::foe::{BusyPhase, FileStore, FoeFile, FoeService};

use mailbox_support::{Bench, Reply};

fn foe(repr: FoeRepr<'_>) -> Vec<u8> {
    repr.to_vec().unwrap()
}

fn parse(reply: &Reply) -> FoeRepr<'_> {
    assert_eq!(reply.header.mailbox_type, MailboxType::Foe, "{reply:?}");
    FoeRepr::parse(&FoePacket::new_checked(&reply.data[..]).unwrap()).unwrap()
}

/// An FoE error seen by the master: code and text.
type Failure = (FoeError, String);

fn failure(repr: FoeRepr<'_>) -> Failure {
    match repr {
        FoeRepr::Error { code, text } => (code, String::from_utf8(text.to_vec()).unwrap()),
        other => panic!("expected an FoE ERROR, got {other}"),
    }
}

fn bench_with(service: FoeService, sm: u16) -> Bench {
    Bench::new(MailboxStack::new().with(service), sm, sm)
}

/// What a master does to upload `name` (SOEM `ecx_FOEread`).
fn read_file(bench: &mut Bench, name: &str, password: u32) -> Result<Vec<u8>, Failure> {
    let max_data = usize::from(bench.ctx.tx_mailbox_size) - 12;
    let rrq = foe(FoeRepr::ReadRequest {
        password,
        file_name: name.as_bytes(),
    });
    let mut reply = bench.one(MailboxType::Foe, &rrq);
    let mut file = Vec::new();
    let mut expected = 1;
    loop {
        let (packet, data) = match parse(&reply) {
            FoeRepr::Data { packet, data } => (packet, data.to_vec()),
            other => return Err(failure(other)),
        };
        assert_eq!(packet, expected, "packets numbered from 1");
        assert!(data.len() <= max_data);
        file.extend_from_slice(&data);
        let ack = foe(FoeRepr::Ack { packet });
        if data.len() < max_data {
            assert!(
                bench.request(MailboxType::Foe, &ack).is_empty(),
                "nothing after the last ACK"
            );
            return Ok(file);
        }
        reply = bench.one(MailboxType::Foe, &ack);
        expected += 1;
    }
}

/// Progress reports of the BUSY answers seen during a write.
type BusyLog = Vec<(u16, u16, String)>;

/// What a master does to download `data` as `name`, re-sending after BUSY (spec-notes §foe).
fn write_file(
    bench: &mut Bench,
    name: &str,
    password: u32,
    data: &[u8],
) -> Result<BusyLog, Failure> {
    let max_data = usize::from(bench.ctx.rx_mailbox_size) - 12;
    let mut busy = Vec::new();
    let mut exchange = |bench: &mut Bench, message: &[u8], expected_ack: u32| loop {
        let reply = bench.one(MailboxType::Foe, message);
        match parse(&reply) {
            FoeRepr::Ack { packet } => {
                assert_eq!(packet, expected_ack);
                return Ok(());
            }
            FoeRepr::Busy { done, entire, text } => {
                busy.push((done, entire, String::from_utf8(text.to_vec()).unwrap()));
            }
            other => return Err(failure(other)),
        }
    };
    let wrq = foe(FoeRepr::WriteRequest {
        password,
        file_name: name.as_bytes(),
    });
    exchange(bench, &wrq, 0)?;
    let mut packet = 1;
    let mut offset = 0;
    loop {
        let len = (data.len() - offset).min(max_data);
        let message = foe(FoeRepr::Data {
            packet,
            data: &data[offset..offset + len],
        });
        exchange(bench, &message, packet)?;
        offset += len;
        if len < max_data {
            return Ok(busy);
        }
        packet += 1;
    }
}

fn pattern(len: usize) -> Vec<u8> {
    (0..len).map(|i| (i * 31 + i / 256) as u8).collect()
}

#[test]
fn ten_kib_round_trip_with_sm_128() {
    let store = FileStore::default();
    let mut bench = bench_with(FoeService::new(store.clone()), 128);
    let file = pattern(10 * 1024);
    let busy = write_file(&mut bench, "log.dat", 0, &file).unwrap();
    assert!(busy.is_empty());
    assert_eq!(store.data("log.dat").unwrap(), file, "stored byte for byte");
    assert_eq!(read_file(&mut bench, "log.dat", 0).unwrap(), file);
    let service = bench.stack.service::<FoeService>().unwrap();
    assert_eq!(
        (service.writes_completed(), service.reads_completed()),
        (1, 1)
    );
    assert!(service.is_idle());
}

#[test]
fn size_a_multiple_of_the_packet_ends_with_an_empty_packet() {
    let store = FileStore::default();
    let mut bench = bench_with(FoeService::new(store.clone()), 128);
    let file = pattern(3 * 116);
    write_file(&mut bench, "exact", 0, &file).unwrap();
    assert_eq!(store.data("exact").unwrap(), file);
    // Read: packets 1..3 full, packet 4 empty.
    let rrq = foe(FoeRepr::ReadRequest {
        password: 0,
        file_name: b"exact",
    });
    let mut reply = bench.one(MailboxType::Foe, &rrq);
    for n in 1..=4u32 {
        let FoeRepr::Data { packet, data } = parse(&reply) else {
            panic!("data expected")
        };
        assert_eq!(packet, n);
        assert_eq!(data.len(), if n < 4 { 116 } else { 0 });
        let ack = foe(FoeRepr::Ack { packet: n });
        let mut replies = bench.request(MailboxType::Foe, &ack);
        if n == 4 {
            assert!(replies.is_empty());
        } else {
            reply = replies.remove(0);
        }
    }
}

#[test]
fn busy_phases_then_ack_for_bin_files() {
    let store = FileStore::default();
    let service = FoeService::new(store.clone()).with_busy(BusyPhase {
        after_write_request: 2,
        after_last_packet: 3,
        ..BusyPhase::default()
    });
    let mut bench = bench_with(service, 64);
    let firmware = pattern(200);
    let busy = write_file(&mut bench, "fw.bin", 0, &firmware).unwrap();
    let expected: BusyLog = [(0, 2), (1, 2), (0, 3), (1, 3), (2, 3)]
        .into_iter()
        .map(|(done, entire)| (done, entire, "flashing".to_owned()))
        .collect();
    assert_eq!(busy, expected);
    assert_eq!(store.data("fw.bin").unwrap(), firmware);
    // Other names: no BUSY at all.
    let busy = write_file(&mut bench, "notes.txt", 0, b"hello").unwrap();
    assert!(busy.is_empty());
    assert_eq!(bench.stack.service::<FoeService>().unwrap().busy_sent(), 5);
}

#[test]
fn busy_after_wrq_also_accepts_the_first_data_packet_as_the_retry() {
    // IgH answers BUSY by sending the data packet it was about to send.
    let store = FileStore::default();
    let service = FoeService::new(store.clone()).with_busy(BusyPhase {
        after_write_request: 1,
        file_suffix: None,
        ..BusyPhase::default()
    });
    let mut bench = bench_with(service, 64);
    let wrq = foe(FoeRepr::WriteRequest {
        password: 0,
        file_name: b"a",
    });
    assert!(matches!(
        parse(&bench.one(MailboxType::Foe, &wrq)),
        FoeRepr::Busy {
            done: 0,
            entire: 1,
            ..
        }
    ));
    let data1 = foe(FoeRepr::Data {
        packet: 1,
        data: b"xyz",
    });
    assert_eq!(
        parse(&bench.one(MailboxType::Foe, &data1)),
        FoeRepr::Ack { packet: 1 }
    );
    assert_eq!(store.data("a").unwrap(), b"xyz");
}

#[test]
fn error_codes_carry_their_texts() {
    let store = FileStore::new(1000);
    store.insert("ro.txt", FoeFile::new(b"keep".to_vec()).read_only());
    store.insert(
        "secret",
        FoeFile::new(b"s3cr3t".to_vec()).with_password(0x1234),
    );
    store.insert("slot.bin", FoeFile::new(vec![0; 10]).write_only());
    let mut bench = bench_with(FoeService::new(store.clone()), 128);
    let cases: Vec<(Failure, FoeError, &str)> = vec![
        (
            read_file(&mut bench, "missing", 0).unwrap_err(),
            FoeError::NotFound,
            "Not found",
        ),
        (
            write_file(&mut bench, "ro.txt", 0, b"x").unwrap_err(),
            FoeError::AccessDenied,
            "Access denied",
        ),
        (
            read_file(&mut bench, "slot.bin", 0).unwrap_err(),
            FoeError::AccessDenied,
            "Access denied",
        ),
        (
            read_file(&mut bench, "secret", 0x9999).unwrap_err(),
            FoeError::NoRights,
            "No rights",
        ),
        (
            write_file(&mut bench, "big", 0, &pattern(2000)).unwrap_err(),
            FoeError::DiskFull,
            "Disk full",
        ),
    ];
    for (got, code, text) in cases {
        assert_eq!(got, (code, text.to_owned()));
    }
    assert_eq!(read_file(&mut bench, "secret", 0x1234).unwrap(), b"s3cr3t");
    assert_eq!(store.data("ro.txt").unwrap(), b"keep");
    assert!(store.get("big").is_none(), "a failed write stores nothing");
    // A store that does not create files.
    store.set_create_on_write(false);
    assert_eq!(
        write_file(&mut bench, "new", 0, b"x").unwrap_err().0,
        FoeError::NotFound
    );
}

#[test]
fn unexpected_opcodes_are_illegal() {
    let mut bench = bench_with(FoeService::default(), 128);
    let illegal = |reply: &Reply| failure(parse(reply));
    let ack = foe(FoeRepr::Ack { packet: 1 });
    assert_eq!(
        illegal(&bench.one(MailboxType::Foe, &ack)).0,
        FoeError::Illegal
    );
    let data = foe(FoeRepr::Data {
        packet: 1,
        data: b"x",
    });
    assert_eq!(
        illegal(&bench.one(MailboxType::Foe, &data)).0,
        FoeError::Illegal
    );
    let busy = foe(FoeRepr::Busy {
        done: 0,
        entire: 1,
        text: b"",
    });
    assert_eq!(
        illegal(&bench.one(MailboxType::Foe, &busy)),
        (FoeError::Illegal, "Illegal".into())
    );
    // Opcode 9 is none of the six.
    let reply = bench.one(MailboxType::Foe, &[9, 0, 0, 0, 0, 0]);
    assert_eq!(illegal(&reply).0, FoeError::Illegal);
    // An ERROR from the master is never answered.
    let error = foe(FoeRepr::Error {
        code: FoeError::NotDefined,
        text: b"abort",
    });
    assert!(bench.request(MailboxType::Foe, &error).is_empty());
}

#[test]
fn wrong_packet_numbers() {
    let store = FileStore::default();
    store.insert("f", FoeFile::new(pattern(500)));
    let mut bench = bench_with(FoeService::new(store), 128);
    // Write: DATA 2 where 1 is expected.
    let wrq = foe(FoeRepr::WriteRequest {
        password: 0,
        file_name: b"g",
    });
    assert_eq!(
        parse(&bench.one(MailboxType::Foe, &wrq)),
        FoeRepr::Ack { packet: 0 }
    );
    let data2 = foe(FoeRepr::Data {
        packet: 2,
        data: b"x",
    });
    let reply = bench.one(MailboxType::Foe, &data2);
    assert_eq!(
        failure(parse(&reply)),
        (FoeError::PacketNumberWrong, "Packet number wrong".into())
    );
    // Read: ACK 5 after DATA 1.
    let rrq = foe(FoeRepr::ReadRequest {
        password: 0,
        file_name: b"f",
    });
    assert!(matches!(
        parse(&bench.one(MailboxType::Foe, &rrq)),
        FoeRepr::Data { packet: 1, .. }
    ));
    let ack5 = foe(FoeRepr::Ack { packet: 5 });
    let reply = bench.one(MailboxType::Foe, &ack5);
    assert_eq!(failure(parse(&reply)).0, FoeError::PacketNumberWrong);
    assert!(bench.stack.service::<FoeService>().unwrap().is_idle());
}

#[test]
fn master_error_aborts_a_read() {
    let store = FileStore::default();
    store.insert("f", FoeFile::new(pattern(500)));
    let mut bench = bench_with(FoeService::new(store), 128);
    let rrq = foe(FoeRepr::ReadRequest {
        password: 0,
        file_name: b"f",
    });
    bench.one(MailboxType::Foe, &rrq);
    let abort = foe(FoeRepr::Error {
        code: FoeError::NotDefined,
        text: b"buffer too small",
    });
    assert!(bench.request(MailboxType::Foe, &abort).is_empty());
    assert!(bench.stack.service::<FoeService>().unwrap().is_idle());
}
