//! Property tests: whatever bytes arrive, the CoE server does not panic, sends no more
//! replies than the request can call for, every reply fits SM1 and parses with the CoE
//! codec, and the dictionary's values keep their declared sizes.

use crate::od_support;

use master_core::od::{Outcome, SdoServer, ServerContext, StaticDictionary};
use master_core::wire::coe::info::SDO_INFO_HEADER_LEN;
use master_core::wire::coe::sdo_payload::SdoPayload;
use master_core::wire::coe::sdo_request::SdoRequest;
use master_core::wire::coe::sdo_response::SdoResponse;
use master_core::wire::coe::{AbortCode, CoeFrame, CoeRepr};
use master_core::wire::register::AlState;
use od_support::*;
use proptest::prelude::*;

/// Indices worth aiming at: every kind of object in the test dictionary and a missing one.
const INDICES: [u16; 16] = [
    0x1000, 0x1008, 0x1018, 0x1600, 0x1A00, 0x1C00, 0x1C12, 0x2001, 0x2004, 0x2005, OCTETS, BLOB,
    0x2031, 0x2040, 0x2050, 0x5555,
];

/// SDO command bytes of every specifier with interesting low bits.
const COMMANDS: [u8; 20] = [
    0x00, 0x01, 0x0B, 0x10, 0x11, 0x20, 0x21, 0x22, 0x23, 0x2B, 0x2F, 0x31, 0x40, 0x50, 0x60, 0x70,
    0x80, 0xA0, 0xC0, 0xE0,
];

fn request() -> impl Strategy<Value = Vec<u8>> {
    // Mostly what fits a data field, sometimes normal-transfer sized.
    let tail = || {
        prop_oneof![
            4 => proptest::collection::vec(any::<u8>(), 4..5),
            3 => proptest::collection::vec(any::<u8>(), 0..12),
            1 => proptest::collection::vec(any::<u8>(), 0..300),
        ]
    };
    prop_oneof![
        // Anything at all.
        proptest::collection::vec(any::<u8>(), 0..40),
        // A known CoE service with random contents.
        (
            proptest::sample::select(vec![0x10u8, 0x20, 0x30, 0x50, 0x80, 0xF0]),
            tail()
        )
            .prop_map(|(service, tail)| {
                let mut r = vec![0x00, service];
                r.extend(tail);
                r
            }),
        // A plausible SDO request at a real object.
        (
            proptest::sample::select(COMMANDS.to_vec()),
            proptest::sample::select(INDICES.to_vec()),
            0u8..8,
            tail()
        )
            .prop_map(|(command, index, subindex, tail)| {
                let mut r = vec![0x00, 0x20, command];
                r.extend(index.to_le_bytes());
                r.push(subindex);
                r.extend(tail);
                r
            }),
        // A plausible SDO Info request.
        (
            0u8..10,
            proptest::sample::select(INDICES.to_vec()),
            0u8..8,
            any::<u8>(),
            any::<bool>()
        )
            .prop_map(|(opcode, index, subindex, value_info, list)| {
                let mut r = vec![0x00, 0x80, opcode, 0x00, 0x00, 0x00];
                if list {
                    r.extend(u16::from(subindex).to_le_bytes());
                } else {
                    r.extend(index.to_le_bytes());
                    r.extend([subindex, value_info]);
                }
                r
            }),
    ]
}

/// Most replies a request can call for: several only for an OD list in fragments.
fn max_replies(dict: &StaticDictionary, request: &[u8], mailbox: usize) -> usize {
    let is_od_list = request.len() >= 3 && request[1] >> 4 == 8 && request[2] & 0x7F == 1;
    if !is_od_list {
        return 1;
    }
    let piece = (mailbox - 6 - SDO_INFO_HEADER_LEN) & !1;
    let words = 1 + dict.objects().count();
    (2 * words).div_ceil(piece)
}

/// One step of a transfer-heavy session, built with the codec.
fn step() -> impl Strategy<Value = Vec<u8>> {
    let index = proptest::sample::select(vec![BLOB, OCTETS, 0x1018, 0x1C12, 0x1600, 0x2050]);
    prop_oneof![
        (index.clone(), 0u8..2, any::<bool>()).prop_map(|(index, subindex, ca)| {
            sdo_bytes(&SdoRequest::InitiateUpload {
                index,
                subindex,
                complete_access: ca,
            })
        }),
        any::<bool>().prop_map(|toggle| sdo_bytes(&SdoRequest::UploadSegment { toggle })),
        (
            index,
            0u8..2,
            any::<bool>(),
            0u32..5000,
            proptest::collection::vec(any::<u8>(), 0..40)
        )
            .prop_map(|(index, subindex, ca, extra, data)| {
                sdo_bytes(&SdoRequest::InitiateDownload {
                    index,
                    subindex,
                    complete_access: ca,
                    payload: SdoPayload::Normal {
                        complete_size: data.len() as u32 + extra % 200,
                        data: &data,
                    },
                })
            }),
        (
            any::<bool>(),
            any::<bool>(),
            proptest::collection::vec(any::<u8>(), 0..40)
        )
            .prop_map(|(toggle, last, data)| {
                sdo_bytes(&SdoRequest::DownloadSegment {
                    toggle,
                    last,
                    data: &data,
                })
            }),
        Just(sdo_bytes(&SdoRequest::Abort {
            index: BLOB,
            subindex: 0,
            code: AbortCode::Timeout
        })),
    ]
}

fn state() -> impl Strategy<Value = AlState> {
    proptest::sample::select(vec![
        AlState::Init,
        AlState::PreOp,
        AlState::SafeOp,
        AlState::Op,
        AlState::Unknown(0x0F),
    ])
}

/// Under `od` so that `cargo test -p master-core od` selects these tests.
mod od {
    use super::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

        #[test]
        fn arbitrary_requests_are_answered_safely(
            mailbox in 10usize..300,
            state in state(),
            requests in proptest::collection::vec(request(), 1..16),
        ) {
            let mut dict = test_dictionary();
            let mut server = SdoServer::new();
            let ctx = ServerContext::new(mailbox, state);
            for request in &requests {
                let mut replies: Vec<Vec<u8>> = Vec::new();
                let outcome = server.handle(&mut dict, request, ctx, &mut |r: &[u8]| {
                    replies.push(r.to_vec())
                });
                prop_assert!(replies.len() <= max_replies(&dict, request, mailbox.max(16)));
                match outcome {
                    Outcome::Replied(n) => prop_assert_eq!(n, replies.len()),
                    _ => prop_assert!(replies.is_empty()),
                }
                if mailbox < 16 {
                    prop_assert_eq!(outcome, Outcome::MailboxTooSmall);
                }
                for reply in &replies {
                    prop_assert!(reply.len() + 6 <= mailbox, "reply exceeds SM1");
                    let frame = CoeFrame::new_checked(&reply[..]);
                    prop_assert!(frame.is_ok());
                    let parsed = CoeRepr::parse(&frame.unwrap());
                    prop_assert!(parsed.is_ok(), "reply {:02x?} does not parse: {:?}", reply, parsed);
                }
            }
            // Whatever was written, every value still has its declared size.
            for object in dict.objects() {
                for entry in &object.entries {
                    if entry.is_variable_length() {
                        prop_assert!(entry.value.len() <= entry.max_len);
                    } else {
                        prop_assert_eq!(entry.value.len(), entry.max_len);
                    }
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

        /// Sessions of initiates and segments in any order: every reply is one of the forms
        /// the request allows, and a toggle mismatch always ends the transfer.
        #[test]
        fn transfer_sessions_stay_consistent(
            mailbox in 16usize..140,
            steps in proptest::collection::vec(step(), 1..40),
        ) {
            let mut dict = test_dictionary();
            let mut server = SdoServer::new();
            // Requests here are built for the transfer, not for SM0: no SM0 limit.
            let ctx = ServerContext {
                rx_mailbox_size: 0,
                ..ServerContext::new(mailbox, AlState::PreOp)
            };
            for request in &steps {
                let mut replies: Vec<Vec<u8>> = Vec::new();
                server.handle(&mut dict, request, ctx, &mut |r: &[u8]| replies.push(r.to_vec()));
                let is_abort = request[2] == 0x80;
                prop_assert_eq!(replies.len(), usize::from(!is_abort));
                for reply in &replies {
                    prop_assert!(reply.len() + 6 <= mailbox);
                    let response = SdoResponse::parse(
                        &master_core::wire::coe::sdo::SdoFrame::new_checked(&reply[..]).unwrap(),
                    );
                    prop_assert!(response.is_ok());
                    if let Ok(SdoResponse::Abort { code: AbortCode::ToggleBit, .. }) = response {
                        prop_assert!(!server.in_transfer());
                    }
                }
            }
        }
    }
}
