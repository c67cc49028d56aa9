//! The slave's mailbox layer: header checks and their error codes, the counter rule, the
//! address echo, the slave's own counter, dispatch, and the VoE echo service behind it.

use crate::mailbox_support;

use std::any::Any;

use ecat_wire::Emit;
use ecat_wire::mailbox::{MailboxErrorCode, MailboxHeader, MailboxType};
use ecat_wire::register::al::AlState;
use ecat_wire::voe::{VoePacket, VoeRepr};
use proptest::prelude::*;
use sim::device::eoe::EoeService;
use sim::device::foe::FoeService;
use sim::device::soe::SoeService;
use sim::device::voe::VoeEcho;
use sim::device::{Device, DeviceContext, MailboxService, MailboxStack, Outbox, ReplySink};

use mailbox_support::{Bench, build_message, parse_reply};

fn voe_request(vendor_id: u32, vendor_type: u16, data: &[u8]) -> Vec<u8> {
    let repr = VoeRepr {
        vendor_id,
        vendor_type,
        data,
    };
    repr.to_vec().unwrap()
}

fn voe_bench() -> Bench {
    Bench::new(MailboxStack::new().with(VoeEcho::default()), 128, 128)
}

fn only_error(replies: Vec<mailbox_support::Reply>) -> MailboxErrorCode {
    assert_eq!(replies.len(), 1, "{replies:?}");
    replies[0].error_code().expect("a mailbox error reply")
}

#[test]
fn length_zero_is_an_invalid_header() {
    let mut bench = voe_bench();
    let message = build_message(MailboxType::Voe, 0, 0, 1, &[]);
    assert_eq!(
        only_error(bench.send_padded(&message)),
        MailboxErrorCode::InvalidHeader
    );
}

#[test]
fn length_beyond_sm0_is_an_invalid_header() {
    let mut bench = voe_bench();
    // SM0 = 128 → at most 122 data bytes.
    let mut message = build_message(MailboxType::Voe, 0, 0, 1, &[0u8; 122]);
    assert_eq!(bench.send_padded(&message).len(), 1, "122 bytes are fine");
    message[0] = 123;
    message.push(0);
    assert_eq!(
        only_error(bench.send_raw(&message)),
        MailboxErrorCode::InvalidHeader
    );
}

#[test]
fn length_beyond_the_delivered_bytes_is_an_invalid_size() {
    let mut bench = voe_bench();
    let mut message = build_message(MailboxType::Voe, 0, 0, 1, &voe_request(0x1164, 1, &[1]));
    message.truncate(message.len() - 1);
    assert_eq!(
        only_error(bench.send_raw(&message)),
        MailboxErrorCode::InvalidSize
    );
}

#[test]
fn fewer_bytes_than_a_header_is_too_short() {
    let mut bench = voe_bench();
    let replies = bench.send_raw(&[0x04, 0x00, 0x00]);
    assert_eq!(only_error(replies), MailboxErrorCode::SizeTooShort);
}

#[test]
fn wrong_channel_and_types() {
    let mut bench = voe_bench();
    let data = voe_request(0x1164, 1, &[1]);
    let message = build_message(MailboxType::Voe, 0, 5, 0, &data);
    assert_eq!(
        only_error(bench.send_padded(&message)),
        MailboxErrorCode::InvalidChannel
    );
    // AoE and CoE are not registered in this slave.
    assert_eq!(
        only_error(bench.request(MailboxType::Aoe, &[1, 2, 3, 4])),
        MailboxErrorCode::UnsupportedProtocol
    );
    assert_eq!(
        only_error(bench.request(MailboxType::Coe, &[0, 0x20, 0x40, 0, 0x10, 0])),
        MailboxErrorCode::UnsupportedProtocol
    );
    assert_eq!(
        only_error(bench.request(MailboxType::Unknown(9), &[1])),
        MailboxErrorCode::UnsupportedProtocol
    );
    // A master never sends type 0; SOES calls that an invalid header.
    assert_eq!(
        only_error(bench.request(MailboxType::Error, &[1, 0, 2, 0])),
        MailboxErrorCode::InvalidHeader
    );
    let counters = bench.stack.counters();
    assert_eq!(counters.received, 5);
    assert_eq!(counters.errors, 5);
}

#[test]
fn repeated_counter_is_discarded_and_zero_is_always_accepted() {
    let mut bench = voe_bench();
    let data = voe_request(0x1164, 1, &[1, 2]);
    let first = build_message(MailboxType::Voe, 0, 0, 3, &data);
    assert_eq!(bench.send_padded(&first).len(), 1);
    assert!(bench.send_padded(&first).is_empty(), "repetition discarded");
    let next = build_message(MailboxType::Voe, 0, 0, 4, &data);
    assert_eq!(bench.send_padded(&next).len(), 1);
    let zero = build_message(MailboxType::Voe, 0, 0, 0, &data);
    assert_eq!(bench.send_padded(&zero).len(), 1);
    assert_eq!(
        bench.send_padded(&zero).len(),
        1,
        "counter 0 is never a repetition"
    );
    // After a 0, the earlier 4 is no longer "the last accepted".
    assert_eq!(bench.send_padded(&next).len(), 1);
    let counters = bench.stack.counters();
    assert_eq!(counters.duplicates_discarded, 1);
    assert_eq!(counters.received, 6);
    assert_eq!(counters.replies_posted, 5);
}

#[test]
fn fall_back_to_init_forgets_the_last_counter() {
    let mut bench = voe_bench();
    let data = voe_request(0x1164, 1, &[1]);
    let message = build_message(MailboxType::Voe, 0, 0, 2, &data);
    assert_eq!(bench.send_padded(&message).len(), 1);
    let ctx = bench.ctx;
    bench
        .stack
        .state_change(AlState::PreOp, AlState::Init, &ctx)
        .unwrap();
    let replies = bench.send_padded(&message);
    assert_eq!(replies.len(), 1, "accepted after the reset");
    assert_eq!(replies[0].header.counter, 1, "slave counter restarts too");
}

#[test]
fn address_is_echoed_and_slave_counter_wraps() {
    let mut bench = voe_bench();
    bench.address = 0x1234;
    let data = voe_request(0x1164, 1, &[1]);
    let mut counters = Vec::new();
    for _ in 0..9 {
        let reply = bench.one(MailboxType::Voe, &data);
        assert_eq!(reply.header.address, 0x1234);
        assert_eq!(reply.header.mailbox_type, MailboxType::Voe);
        assert_eq!((reply.header.channel, reply.header.priority), (0, 0));
        counters.push(reply.header.counter);
    }
    assert_eq!(counters, [1, 2, 3, 4, 5, 6, 7, 1, 2]);
    // Error replies echo the address as well.
    let reply = bench.one(MailboxType::Aoe, &[1]);
    assert_eq!(reply.header.address, 0x1234);
    assert_eq!(reply.header.counter, 3);
}

#[test]
fn supported_protocols_follow_the_services() {
    let stack = MailboxStack::new()
        .with(VoeEcho::default())
        .with(SoeService::default())
        .with(FoeService::default())
        .with(EoeService::default());
    assert_eq!(stack.supported_protocols(), 0x02 | 0x08 | 0x10 | 0x20);
    assert_eq!(MailboxStack::new().supported_protocols(), 0);
    assert!(stack.service::<VoeEcho>().is_some());
    assert!(stack.service::<MailboxStack>().is_none());
}

#[test]
fn voe_echo_inverts_the_data() {
    let mut bench = voe_bench();
    let reply = bench.one(
        MailboxType::Voe,
        &voe_request(0x1164, 0x0042, &[0x00, 0x0F, 0xA5]),
    );
    let packet = VoePacket::new_checked(&reply.data[..]).unwrap();
    let repr = VoeRepr::parse(&packet).unwrap();
    assert_eq!(repr.vendor_id, 0x1164);
    assert_eq!(repr.vendor_type, 0x0042);
    assert_eq!(repr.data, &[0xFF, 0xF0, 0x5A]);
    assert_eq!(bench.stack.service::<VoeEcho>().unwrap().handled(), 1);
}

#[test]
fn voe_other_vendor_and_short_header() {
    let mut bench = voe_bench();
    assert_eq!(
        only_error(bench.request(MailboxType::Voe, &voe_request(0x0002, 1, &[1]))),
        MailboxErrorCode::ServiceNotSupported
    );
    assert_eq!(
        only_error(bench.request(MailboxType::Voe, &[0x64, 0x11, 0])),
        MailboxErrorCode::SizeTooShort
    );
    let mut other = Bench::new(MailboxStack::new().with(VoeEcho::new(0x0000_0002)), 64, 64);
    let reply = other.one(MailboxType::Voe, &voe_request(0x0002, 1, &[1]));
    assert_eq!(reply.header.mailbox_type, MailboxType::Voe);
}

/// A deliberately faulty service: answers with `len` bytes and posts `count` messages.
struct Chatty {
    len: usize,
    count: usize,
}

impl MailboxService for Chatty {
    fn mailbox_type(&self) -> MailboxType {
        MailboxType::Aoe
    }

    fn handle(&mut self, _: &MailboxHeader, _: &[u8], _: &DeviceContext, replies: &mut ReplySink) {
        for i in 0..self.count {
            let _ = replies.send(vec![i as u8; self.len]);
        }
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

#[test]
fn a_reply_too_large_for_sm1_becomes_no_more_memory() {
    let stack = MailboxStack::new().with(Chatty { len: 59, count: 1 });
    let mut bench = Bench::new(stack, 128, 64);
    assert_eq!(
        only_error(bench.request(MailboxType::Aoe, &[1])),
        MailboxErrorCode::NoMoreMemory
    );
    assert_eq!(bench.stack.counters().service_faults, 1);
    bench.stack.service_mut::<Chatty>().unwrap().len = 58;
    let reply = bench.one(MailboxType::Aoe, &[1]);
    assert_eq!(reply.data.len(), 58, "exactly SM1 − 6 fits");
}

#[test]
fn many_replies_wait_for_the_master_in_order() {
    let stack = MailboxStack::new().with(Chatty { len: 4, count: 20 });
    let mut bench = Bench::new(stack, 128, 128);
    let message = bench.build(MailboxType::Aoe, &[1]);
    bench
        .stack
        .mailbox_received(&message, &bench.ctx.clone(), &mut bench.outbox);
    assert_eq!(bench.outbox.len(), 1, "the outbox holds one");
    assert_eq!(bench.stack.backlog_len(), 19, "the rest waits in the layer");
    let replies = bench.drain();
    let firsts: Vec<u8> = replies.iter().map(|r| r.data[0]).collect();
    assert_eq!(firsts, (0..20).collect::<Vec<u8>>());
}

#[test]
fn backlog_overflow_is_counted_not_fatal() {
    let stack = MailboxStack::with_backlog(4).with(Chatty { len: 4, count: 10 });
    let mut bench = Bench::new(stack, 128, 128);
    let replies = bench.request(MailboxType::Aoe, &[1]);
    assert_eq!(replies.len(), 4);
    assert_eq!(bench.stack.counters().replies_posted, 4);
}

fn full_stack() -> MailboxStack {
    MailboxStack::new()
        .with(VoeEcho::default())
        .with(SoeService::new(2))
        .with(FoeService::default())
        .with(EoeService::default())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Whatever a master writes, the slave does not panic, and every message it posts parses
    /// with the mailbox codec and fits SM1.
    #[test]
    fn arbitrary_bytes_never_panic(
        messages in proptest::collection::vec(
            (proptest::collection::vec(any::<u8>(), 0..160), any::<bool>()), 1..6),
        sm0 in 0u16..200,
        sm1 in 0u16..200,
    ) {
        let mut stack = full_stack();
        let ctx = DeviceContext {
            station_address: 1,
            al_state: AlState::PreOp,
            rx_mailbox_size: sm0,
            tx_mailbox_size: sm1,
        };
        let mut outbox = Outbox::new(8);
        for (mut bytes, typed) in messages {
            if typed && bytes.len() >= 6 {
                // Steer half the cases into a real protocol with a consistent length.
                let len = (bytes.len() - 6) as u16;
                bytes[0..2].copy_from_slice(&len.to_le_bytes());
                bytes[4] = 0;
                bytes[5] = (bytes[5] & 0x70) | [2u8, 4, 5, 15][usize::from(bytes[5] & 3)];
            }
            stack.mailbox_received(&bytes, &ctx, &mut outbox);
            stack.poll(&ctx, &mut outbox);
            while let Some(message) = outbox.pop() {
                prop_assert!(message.len() <= usize::from(sm1));
                let reply = parse_reply(&message);
                prop_assert!((1..=7).contains(&reply.header.counter));
                if reply.header.mailbox_type == MailboxType::Error {
                    prop_assert!(mailbox_support::Reply::error_code(&reply).is_some());
                }
            }
        }
    }
}

/// A request shaped like one of the protocols: a plausible first header byte (opcode or frame
/// type), a small IDN / packet number, then random bytes — to reach the services' state
/// machines rather than only their parsers.
fn shaped_request() -> impl Strategy<Value = (MailboxType, Vec<u8>)> {
    let tail = proptest::collection::vec(any::<u8>(), 0..120);
    prop_oneof![
        // FoE: opcodes 0..=7, packet numbers 0..4, file names "a"/"fw.bin" or data.
        (0u8..8, 0u32..4, any::<bool>(), tail.clone()).prop_map(|(op, n, named, tail)| {
            let mut data = vec![op, 0];
            data.extend_from_slice(&n.to_le_bytes());
            if named {
                data.extend_from_slice(if n % 2 == 0 { b"a" } else { b"fw.bin" });
            } else {
                data.extend_from_slice(&tail);
            }
            (MailboxType::Foe, data)
        }),
        // SoE: any flags byte, any elements, an IDN of the default set or a fragment count.
        (
            any::<u8>(),
            any::<u8>(),
            prop::sample::select(vec![1u16, 2, 16, 17, 30, 32, 36, 999]),
            tail.clone()
        )
            .prop_map(|(flags, elements, idn, tail)| {
                let mut data = vec![flags, elements];
                data.extend_from_slice(&idn.to_le_bytes());
                data.extend_from_slice(&tail);
                (MailboxType::Soe, data)
            }),
        // EoE: frame types 0..=10, any flags, any fragment info.
        (0u8..11, any::<u8>(), any::<u16>(), tail.clone()).prop_map(|(ty, flags, info, tail)| {
            let mut data = vec![ty, flags];
            data.extend_from_slice(&info.to_le_bytes());
            data.extend_from_slice(&tail);
            (MailboxType::Eoe, data)
        }),
        // VoE for the served vendor or another one.
        (any::<bool>(), tail).prop_map(|(ours, tail)| {
            let vendor: u32 = if ours { 0x1164 } else { 2 };
            let mut data = vendor.to_le_bytes().to_vec();
            data.extend_from_slice(&[1, 0]);
            data.extend_from_slice(&tail);
            (MailboxType::Voe, data)
        }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Sequences of protocol-shaped requests never panic and every reply parses and fits SM1.
    #[test]
    fn protocol_shaped_sequences_never_panic(
        requests in proptest::collection::vec(shaped_request(), 1..24),
        sm in prop::sample::select(vec![16u16, 32, 64, 128, 256]),
    ) {
        let mut bench = Bench::new(full_stack(), sm, sm);
        for (mailbox_type, data) in requests {
            if data.len() + 6 > usize::from(sm) {
                continue;
            }
            for reply in bench.request(mailbox_type, &data) {
                prop_assert!(reply.data.len() + 6 <= usize::from(sm));
                if reply.header.mailbox_type == MailboxType::Error {
                    prop_assert!(reply.error_code().is_some());
                }
            }
        }
    }
}
