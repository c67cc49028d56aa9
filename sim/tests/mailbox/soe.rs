//! The simulated SoE drive: element reads, value writes with their error codes, and
//! fragmented reads and writes.

use crate::mailbox_support;

use ecat_wire::Emit;
use ecat_wire::mailbox::{MailboxErrorCode, MailboxType};
use ecat_wire::register::al::AlState;
use ecat_wire::soe::{
    ElementFlags, Idn, IdnOrFragments, SoeAttribute, SoeDataType, SoeError, SoeOpcode, SoePacket,
    SoeRepr,
};
use sim::device::MailboxStack;
use sim::device::soe::SoeService;
use sim::device::soe::defaults::MANUFACTURER_VERSION_TEXT;

use mailbox_support::{Bench, Reply};

fn bench(sm0: u16, sm1: u16) -> Bench {
    Bench::new(MailboxStack::new().with(SoeService::new(1)), sm0, sm1)
}

fn request(
    opcode: SoeOpcode,
    drive: u8,
    elements: ElementFlags,
    idn_or_fragments: IdnOrFragments,
    data: &[u8],
) -> Vec<u8> {
    let repr = SoeRepr {
        opcode,
        drive,
        elements,
        idn_or_fragments,
        error: None,
        data,
    };
    repr.to_vec().unwrap()
}

fn idn(number: u16) -> IdnOrFragments {
    IdnOrFragments::Idn(Idn::from_raw(number))
}

fn read_req(number: u16, elements: ElementFlags) -> Vec<u8> {
    request(SoeOpcode::ReadRequest, 0, elements, idn(number), &[])
}

fn write_req(number: u16, elements: ElementFlags, data: &[u8]) -> Vec<u8> {
    request(SoeOpcode::WriteRequest, 0, elements, idn(number), data)
}

fn soe(reply: &Reply) -> SoeRepr<'_> {
    assert_eq!(reply.header.mailbox_type, MailboxType::Soe, "{reply:?}");
    SoeRepr::parse(&SoePacket::new_checked(&reply.data[..]).unwrap()).unwrap()
}

/// Reads `elements` of IDN `number`: Ok(data) or Err(SoE error code).
fn read(bench: &mut Bench, number: u16, elements: ElementFlags) -> Result<Vec<u8>, SoeError> {
    let reply = bench.one(MailboxType::Soe, &read_req(number, elements));
    let repr = soe(&reply);
    assert_eq!(repr.opcode, SoeOpcode::ReadResponse);
    assert_eq!(repr.elements, elements, "elements echoed");
    assert_eq!(repr.idn_or_fragments, idn(number));
    match repr.error {
        Some(code) => Err(code),
        None => Ok(repr.data.to_vec()),
    }
}

fn write(
    bench: &mut Bench,
    number: u16,
    elements: ElementFlags,
    data: &[u8],
) -> Result<(), SoeError> {
    let reply = bench.one(MailboxType::Soe, &write_req(number, elements, data));
    let repr = soe(&reply);
    assert_eq!(repr.opcode, SoeOpcode::WriteResponse);
    assert_eq!(repr.idn_or_fragments, idn(number));
    repr.error.map_or(Ok(()), Err)
}

fn list(text: &[u8]) -> Vec<u8> {
    let n = text.len() as u16;
    let mut out = n.to_le_bytes().to_vec();
    out.extend_from_slice(&n.to_le_bytes());
    out.extend_from_slice(text);
    out
}

#[test]
fn read_value_name_and_attribute_of_s_0_0032() {
    let mut bench = bench(128, 128);
    assert_eq!(
        read(&mut bench, 32, ElementFlags::VALUE),
        Ok(vec![0x02, 0x00])
    );
    assert_eq!(
        read(&mut bench, 32, ElementFlags::NAME),
        Ok(list(b"Primary operation mode"))
    );
    let attribute = read(&mut bench, 32, ElementFlags::ATTRIBUTE).unwrap();
    let attribute = SoeAttribute::from_u32(u32::from_le_bytes(attribute.try_into().unwrap()));
    assert_eq!(attribute.element_size, 2);
    assert!(!attribute.list);
    assert_eq!(attribute.data_type, SoeDataType::Hex);
    assert_eq!(
        read(&mut bench, 32, ElementFlags::DEFAULT),
        Ok(vec![0x02, 0x00])
    );
}

#[test]
fn several_elements_come_in_bit_order() {
    let mut bench = bench(128, 128);
    let data = read(
        &mut bench,
        1,
        ElementFlags::VALUE | ElementFlags::NAME | ElementFlags::MINIMUM | ElementFlags::UNIT,
    )
    .unwrap();
    let mut expected = list(b"NC cycle time (TNcyc)");
    expected.extend(list(b"us"));
    expected.extend(125u16.to_le_bytes());
    expected.extend(1000u16.to_le_bytes());
    assert_eq!(data, expected);
}

#[test]
fn read_errors() {
    let mut bench = bench(128, 128);
    assert_eq!(
        read(&mut bench, 999, ElementFlags::VALUE),
        Err(SoeError::NoIdn)
    );
    assert_eq!(
        read(&mut bench, 32, ElementFlags::UNIT),
        Err(SoeError::NoUnit)
    );
    assert_eq!(
        read(&mut bench, 40, ElementFlags::MINIMUM),
        Err(SoeError::NoMinimum)
    );
    assert_eq!(
        read(&mut bench, 40, ElementFlags::MAXIMUM),
        Err(SoeError::NoMaximum)
    );
    assert_eq!(
        read(&mut bench, 40, ElementFlags::DEFAULT),
        Err(SoeError::NoDefault)
    );
    assert_eq!(
        read(&mut bench, 32, ElementFlags::empty()),
        Err(SoeError::NoElementAddressed)
    );
    // Drive 3 does not exist on a one-drive slave.
    let reply = bench.one(
        MailboxType::Soe,
        &request(SoeOpcode::ReadRequest, 3, ElementFlags::VALUE, idn(32), &[]),
    );
    let repr = soe(&reply);
    assert_eq!(
        (repr.drive, repr.error),
        (3, Some(SoeError::InvalidDriveNumber))
    );
    // A master never sends a notification.
    let reply = bench.one(
        MailboxType::Soe,
        &request(
            SoeOpcode::Notification,
            0,
            ElementFlags::VALUE,
            idn(32),
            &[],
        ),
    );
    assert_eq!(
        reply.error_code(),
        Some(MailboxErrorCode::ServiceNotSupported)
    );
    let reply = bench.one(MailboxType::Soe, &[0x01, 0x40]);
    assert_eq!(reply.error_code(), Some(MailboxErrorCode::SizeTooShort));
}

#[test]
fn idn_lists() {
    let mut bench = bench(128, 128);
    let data = read(&mut bench, 17, ElementFlags::VALUE).unwrap();
    let (cur, max) = (
        u16::from_le_bytes([data[0], data[1]]),
        u16::from_le_bytes([data[2], data[3]]),
    );
    assert_eq!(usize::from(cur), data.len() - 4);
    assert!(max >= cur);
    let idns: Vec<u16> = data[4..]
        .chunks(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect();
    for expected in [1, 16, 17, 24, 30, 32, 36, 40, 51] {
        assert!(
            idns.contains(&expected),
            "S-0-0017 lists {expected}: {idns:?}"
        );
    }
    let at = read(&mut bench, 16, ElementFlags::VALUE).unwrap();
    assert_eq!(&at[4..], &[51, 0, 40, 0]);
}

#[test]
fn write_value_with_range_and_access_errors() {
    let mut bench = bench(128, 128);
    let v = ElementFlags::VALUE;
    assert_eq!(
        write(&mut bench, 1, v, &100u16.to_le_bytes()),
        Err(SoeError::DataBelowMinimum)
    );
    assert_eq!(
        write(&mut bench, 1, v, &65001u16.to_le_bytes()),
        Err(SoeError::DataAboveMaximum)
    );
    assert_eq!(
        write(&mut bench, 1, v, &[0x10]),
        Err(SoeError::DataTooShort)
    );
    assert_eq!(
        write(&mut bench, 1, v, &[1, 2, 3]),
        Err(SoeError::DataTooLong)
    );
    assert_eq!(write(&mut bench, 1, v, &2000u16.to_le_bytes()), Ok(()));
    assert_eq!(read(&mut bench, 1, v), Ok(2000u16.to_le_bytes().to_vec()));
    // Signed limits on S-0-0036.
    assert_eq!(
        write(&mut bench, 36, v, &(-1_000_001i32).to_le_bytes()),
        Err(SoeError::DataBelowMinimum)
    );
    assert_eq!(write(&mut bench, 36, v, &(-5i32).to_le_bytes()), Ok(()));
    assert_eq!(read(&mut bench, 36, v), Ok((-5i32).to_le_bytes().to_vec()));
    // Read-only value, other elements, unknown IDN.
    assert_eq!(
        write(&mut bench, 40, v, &[0; 4]),
        Err(SoeError::DataReadOnly)
    );
    assert_eq!(
        write(&mut bench, 32, ElementFlags::NAME, &list(b"x")),
        Err(SoeError::NameReadOnly)
    );
    assert_eq!(
        write(&mut bench, 32, ElementFlags::DEFAULT, &[0, 0]),
        Err(SoeError::DefaultReadOnly)
    );
    assert_eq!(write(&mut bench, 999, v, &[0, 0]), Err(SoeError::NoIdn));
    // S-0-0001 may only change in PREOP.
    bench.ctx.al_state = AlState::SafeOp;
    assert_eq!(
        write(&mut bench, 1, v, &1000u16.to_le_bytes()),
        Err(SoeError::DataWriteProtected)
    );
    assert_eq!(
        write(&mut bench, 32, v, &[0x0B, 0x00]),
        Ok(()),
        "S-0-0032 is writable in SAFEOP"
    );
}

#[test]
fn read_in_three_fragments() {
    // SM1 = 32: 32 − 6 − 4 = 22 data bytes per response; S-0-0030's value is 4 + 58 bytes.
    let mut bench = bench(128, 32);
    let replies = bench.request(MailboxType::Soe, &read_req(30, ElementFlags::VALUE));
    assert_eq!(replies.len(), 3, "{replies:?}");
    let mut value = Vec::new();
    let mut headers = Vec::new();
    for reply in &replies {
        let repr = soe(reply);
        assert_eq!(repr.opcode, SoeOpcode::ReadResponse);
        assert_eq!(repr.error, None);
        headers.push(repr.idn_or_fragments);
        value.extend_from_slice(repr.data);
    }
    assert_eq!(
        headers,
        [
            IdnOrFragments::FragmentsLeft(2),
            IdnOrFragments::FragmentsLeft(1),
            idn(30)
        ]
    );
    // List header: 58 bytes now, room for 64.
    assert_eq!(value[..4], [58, 0, 64, 0]);
    let text = std::str::from_utf8(&value[4..]).unwrap();
    assert_eq!(text, MANUFACTURER_VERSION_TEXT);
    let counters: Vec<u8> = replies.iter().map(|r| r.header.counter).collect();
    assert_eq!(counters, [1, 2, 3], "one slave counter per posted fragment");
}

#[test]
fn write_in_three_fragments() {
    // SM0 = 24: 24 − 6 − 4 = 14 data bytes per request; 16 IDNs = 4 + 32 bytes.
    let mut bench = bench(24, 128);
    let idns: Vec<u16> = (100..116).collect();
    let mut value = 32u16.to_le_bytes().to_vec();
    value.extend(32u16.to_le_bytes());
    value.extend(idns.iter().flat_map(|i| i.to_le_bytes()));
    let pieces: Vec<&[u8]> = value.chunks(14).collect();
    assert_eq!(pieces.len(), 3);
    let v = ElementFlags::VALUE;
    let first = request(
        SoeOpcode::WriteRequest,
        0,
        v,
        IdnOrFragments::FragmentsLeft(2),
        pieces[0],
    );
    assert!(
        bench.request(MailboxType::Soe, &first).is_empty(),
        "no answer before the last"
    );
    let second = request(
        SoeOpcode::WriteRequest,
        0,
        v,
        IdnOrFragments::FragmentsLeft(1),
        pieces[1],
    );
    assert!(bench.request(MailboxType::Soe, &second).is_empty());
    let last = request(SoeOpcode::WriteRequest, 0, v, idn(16), pieces[2]);
    let reply = bench.one(MailboxType::Soe, &last);
    let repr = soe(&reply);
    assert_eq!((repr.opcode, repr.error), (SoeOpcode::WriteResponse, None));
    assert_eq!(repr.idn_or_fragments, idn(16));
    let stack = &bench.stack;
    let entry = stack.service::<SoeService>().unwrap().entry(0, 16).unwrap();
    assert_eq!(entry.value, value[4..]);
    assert_eq!(stack.service::<SoeService>().unwrap().abandoned_writes(), 0);
}

#[test]
fn second_drive_has_its_own_table() {
    let mut bench = Bench::new(MailboxStack::new().with(SoeService::new(2)), 128, 128);
    let set = request(
        SoeOpcode::WriteRequest,
        1,
        ElementFlags::VALUE,
        idn(32),
        &[0x05, 0x00],
    );
    assert_eq!(soe(&bench.one(MailboxType::Soe, &set)).error, None);
    let get = |drive| {
        request(
            SoeOpcode::ReadRequest,
            drive,
            ElementFlags::VALUE,
            idn(32),
            &[],
        )
    };
    let reply = bench.one(MailboxType::Soe, &get(1));
    assert_eq!(
        (soe(&reply).drive, soe(&reply).data),
        (1, &[0x05, 0x00][..])
    );
    let reply = bench.one(MailboxType::Soe, &get(0));
    assert_eq!(soe(&reply).data, &[0x02, 0x00]);
}
