//! SDO Information against the CoE server: OD lists (fragmented through a small mailbox),
//! object and entry descriptions equal to what was declared, and SDO Info errors.

use crate::od_support;

use master_core::od::{Dictionary, StaticDictionary};
use master_core::wire::coe::info::{
    EntryDescription, ObjectDescription, OdList, OdListType, SdoInfoService, ValueInfo,
};
use master_core::wire::coe::{AbortCode, DataType, ObjectAccess, ObjectCode};
use od_support::*;

/// The test dictionary with 60 more objects, so OD lists need many fragments.
fn big_dictionary() -> StaticDictionary {
    let mut dict = test_dictionary();
    let mut extra = StaticDictionary::builder();
    for i in 0..60u16 {
        extra = extra.var(
            0x3000 + i,
            "Filler",
            DataType::Unsigned8,
            ObjectAccess::RW,
            0u8,
        );
    }
    for object in extra.build().unwrap().objects() {
        dict.insert(object.clone());
    }
    dict
}

/// Collects the service data of a fragmented answer, checking the fragment headers.
fn reassemble(replies: &[Vec<u8>], opcode: u8) -> Vec<u8> {
    let mut data = Vec::new();
    let n = replies.len();
    for (k, reply) in replies.iter().enumerate() {
        let repr = info_reply(reply);
        assert_eq!(u8::from(repr.service.opcode()), opcode);
        assert_eq!(repr.fragments_left as usize, n - 1 - k, "fragments left");
        assert_eq!(repr.incomplete, k + 1 < n, "incomplete flag");
        // The raw service data (whatever the opcode) follows the 6 header bytes.
        data.extend_from_slice(&reply[6..]);
    }
    data
}

fn words(bytes: &[u8]) -> Vec<u16> {
    OdList(bytes).words().collect()
}

/// Under `od` so that `cargo test -p master-core od` selects these tests.
mod od {
    use super::*;

    #[test]
    fn od_list_across_fragments_matches_the_dictionary() {
        let mut c = Client::with(big_dictionary(), 32);
        let replies = c.info(SdoInfoService::OdListRequest {
            list_type: OdListType::All,
        });
        let expected = c.dict.indices(OdListType::All);
        // 32-byte SM1: 26 bytes of mailbox data, 20 of them service data (10 words) per
        // fragment. The list has 1 + N words.
        assert_eq!(replies.len(), (1 + expected.len()).div_ceil(10));
        assert!(replies.len() > 5);
        // The list type heads the first fragment only.
        let SdoInfoService::OdListResponse(first) = info_reply(&replies[0]).service else {
            panic!("not an OD list");
        };
        assert_eq!(first.first_fragment().unwrap().0, OdListType::All);
        let SdoInfoService::OdListResponse(second) = info_reply(&replies[1]).service else {
            panic!("not an OD list");
        };
        assert_eq!(words(second.raw())[0], expected[9]);
        let all = words(&reassemble(&replies, 2));
        assert_eq!(all[0], 1);
        assert_eq!(all[1..], expected);
        assert!(all.contains(&0x1018) && all.contains(&0x303B));
    }

    #[test]
    fn od_list_fits_one_message_in_a_large_mailbox() {
        let mut c = Client::new(1024);
        let replies = c.info(SdoInfoService::OdListRequest {
            list_type: OdListType::All,
        });
        assert_eq!(replies.len(), 1);
        let repr = info_reply(&replies[0]);
        assert!(!repr.incomplete);
        assert_eq!(repr.fragments_left, 0);
        let SdoInfoService::OdListResponse(list) = repr.service else {
            panic!("not an OD list");
        };
        let (ty, rest) = list.first_fragment().unwrap();
        assert_eq!(ty, OdListType::All);
        assert_eq!(
            rest.words().collect::<Vec<_>>(),
            c.dict.indices(OdListType::All)
        );
    }

    #[test]
    fn od_list_types() {
        let mut c = Client::new(128);
        let list = |c: &mut Client, list_type| {
            let replies = c.info(SdoInfoService::OdListRequest { list_type });
            words(&reassemble(&replies, 2))
        };
        // Type 0: five counts.
        let all = c.dict.indices(OdListType::All).len() as u16;
        assert_eq!(list(&mut c, OdListType::Lengths), [0, all, 1, 1, 0, 0]);
        // RxPDO-mappable: 0x7000; TxPDO-mappable: 0x6000.
        assert_eq!(list(&mut c, OdListType::RxPdoMappable), [2, 0x7000]);
        assert_eq!(list(&mut c, OdListType::TxPdoMappable), [3, 0x6000]);
        assert_eq!(list(&mut c, OdListType::Backup), [4]);
        // An unknown list type is an SDO Info error.
        let replies = c.info(SdoInfoService::OdListRequest {
            list_type: OdListType::Unknown(9),
        });
        assert_eq!(
            info_reply(&replies[0]).service,
            SdoInfoService::Error {
                code: AbortCode::UnsupportedAccess
            }
        );
    }

    #[test]
    fn object_descriptions_equal_the_declarations() {
        let mut c = Client::new(128);
        let describe = |c: &mut Client, index| {
            let replies = c.info(SdoInfoService::ObjectDescriptionRequest { index });
            assert_eq!(replies.len(), 1);
            replies.into_iter().next().unwrap()
        };
        let reply = describe(&mut c, 0x1018);
        assert_eq!(
            info_reply(&reply).service,
            SdoInfoService::ObjectDescriptionResponse(ObjectDescription {
                index: 0x1018,
                data_type: DataType::Identity,
                max_subindex: 4,
                object_code: ObjectCode::Record,
                name: b"Identity",
            })
        );
        // An assignment reports its capacity, not the current SI0.
        let reply = describe(&mut c, 0x1C12);
        assert_eq!(
            info_reply(&reply).service,
            SdoInfoService::ObjectDescriptionResponse(ObjectDescription {
                index: 0x1C12,
                data_type: DataType::Unsigned16,
                max_subindex: 4,
                object_code: ObjectCode::Array,
                name: b"RxPDO assign",
            })
        );
        let reply = describe(&mut c, 0x1008);
        assert_eq!(
            info_reply(&reply).service,
            SdoInfoService::ObjectDescriptionResponse(ObjectDescription {
                index: 0x1008,
                data_type: DataType::VisibleString,
                max_subindex: 0,
                object_code: ObjectCode::Var,
                name: b"Manufacturer device name",
            })
        );
        // Every object of the dictionary describes itself as declared.
        for index in c.dict.indices(OdListType::All) {
            let reply = describe(&mut c, index);
            let SdoInfoService::ObjectDescriptionResponse(d) = info_reply(&reply).service else {
                panic!("no description of 0x{index:04X}");
            };
            let object = c.dict.get_object(index).unwrap();
            assert_eq!(d.name, object.name.as_bytes());
            assert_eq!(d.max_subindex, object.max_subindex());
            assert_eq!(d.object_code, object.object_code);
        }
    }

    #[test]
    fn entry_descriptions_equal_the_declarations() {
        let mut c = Client::new(128);
        let all = ValueInfo(
            ValueInfo::UNIT_TYPE | ValueInfo::DEFAULT | ValueInfo::MINIMUM | ValueInfo::MAXIMUM,
        );
        let replies = c.info(SdoInfoService::EntryDescriptionRequest {
            index: 0x2005,
            subindex: 0,
            value_info: all,
        });
        assert_eq!(
            info_reply(&replies[0]).service,
            SdoInfoService::EntryDescriptionResponse(EntryDescription {
                index: 0x2005,
                subindex: 0,
                value_info: all,
                data_type: DataType::Integer16,
                bit_length: 16,
                access: ObjectAccess::RW,
                unit_type: Some(0x0001_0000),
                default: Some(&5i16.to_le_bytes()),
                minimum: Some(&(-100i16).to_le_bytes()),
                maximum: Some(&100i16.to_le_bytes()),
                description: b"Limited",
            })
        );
        // An entry without those values answers with the bits cleared.
        let replies = c.info(SdoInfoService::EntryDescriptionRequest {
            index: 0x1018,
            subindex: 1,
            value_info: all,
        });
        assert_eq!(
            info_reply(&replies[0]).service,
            SdoInfoService::EntryDescriptionResponse(EntryDescription {
                index: 0x1018,
                subindex: 1,
                value_info: ValueInfo(0),
                data_type: DataType::Unsigned32,
                bit_length: 32,
                access: ObjectAccess::RO,
                unit_type: None,
                default: None,
                minimum: None,
                maximum: None,
                description: b"Vendor ID",
            })
        );
        // SI0 of an assignment: writable in PREOP, maximum = capacity.
        let replies = c.info(SdoInfoService::EntryDescriptionRequest {
            index: 0x1C12,
            subindex: 0,
            value_info: ValueInfo(ValueInfo::MAXIMUM),
        });
        let SdoInfoService::EntryDescriptionResponse(d) = info_reply(&replies[0]).service else {
            panic!("no entry description");
        };
        assert_eq!(d.access, ObjectAccess(0x000F));
        assert_eq!(d.maximum, Some(&[4u8][..]));
        // Strings report their maximum length in bits.
        let replies = c.info(SdoInfoService::EntryDescriptionRequest {
            index: 0x2060,
            subindex: 2,
            value_info: ValueInfo(0),
        });
        let SdoInfoService::EntryDescriptionResponse(d) = info_reply(&replies[0]).service else {
            panic!("no entry description");
        };
        assert_eq!((d.data_type, d.bit_length), (DataType::VisibleString, 128));
    }

    #[test]
    fn long_descriptions_are_cut_to_one_message() {
        // Descriptions are answered in one message (single-message readers such as SOEM's):
        // names are cut, optional values dropped when they do not fit.
        let name = "A rather long object name that does not fit a tiny mailbox at all";
        let dict = StaticDictionary::builder()
            .var(0x2000, name, DataType::Unsigned32, ObjectAccess::RW, 1u32)
            .range(0u32, 10u32)
            .build()
            .unwrap();
        let mut c = Client::with(dict, 32);
        let replies = c.info(SdoInfoService::ObjectDescriptionRequest { index: 0x2000 });
        assert_eq!(replies.len(), 1);
        assert_eq!(replies[0].len(), 26);
        let SdoInfoService::ObjectDescriptionResponse(d) = info_reply(&replies[0]).service else {
            panic!("no object description");
        };
        assert_eq!(d.name, &name.as_bytes()[..14]);
        let range = ValueInfo(ValueInfo::MINIMUM | ValueInfo::MAXIMUM);
        let request = SdoInfoService::EntryDescriptionRequest {
            index: 0x2000,
            subindex: 0,
            value_info: range,
        };
        let replies = c.info(request);
        let SdoInfoService::EntryDescriptionResponse(e) = info_reply(&replies[0]).service else {
            panic!("no entry description");
        };
        // 26 − 6 − 10 = 10 bytes: minimum and maximum (8) and 2 bytes of name.
        assert_eq!(e.value_info, range);
        assert_eq!(
            (e.minimum, e.maximum),
            (Some(&[0u8; 4][..]), Some(&[10, 0, 0, 0][..]))
        );
        assert_eq!(e.description, b"A ");
        // At 24 bytes the values no longer fit: left out, the name takes the room.
        c.ctx.mailbox_size = 24;
        let replies = c.info(request);
        let SdoInfoService::EntryDescriptionResponse(e) = info_reply(&replies[0]).service else {
            panic!("no entry description");
        };
        assert_eq!(e.value_info, ValueInfo(0));
        assert_eq!(e.description, &name.as_bytes()[..2]);
        // Below the fixed part nothing fits: an SDO Info error says so.
        c.ctx.mailbox_size = 21;
        let replies = c.info(request);
        assert_eq!(
            info_reply(&replies[0]).service,
            SdoInfoService::Error {
                code: AbortCode::ObjectTooLong
            }
        );
    }

    #[test]
    fn info_errors() {
        let mut c = Client::new(128);
        let error_of = |c: &mut Client, service| {
            let replies = c.info(service);
            assert_eq!(replies.len(), 1);
            let repr = info_reply(&replies[0]);
            assert!(!repr.incomplete && repr.fragments_left == 0);
            match repr.service {
                SdoInfoService::Error { code } => code,
                other => panic!("expected an SDO Info error, got {other:?}"),
            }
        };
        assert_eq!(
            error_of(
                &mut c,
                SdoInfoService::ObjectDescriptionRequest { index: 0x5555 }
            ),
            AbortCode::ObjectDoesNotExist
        );
        let entry = |index, subindex| SdoInfoService::EntryDescriptionRequest {
            index,
            subindex,
            value_info: ValueInfo(0),
        };
        assert_eq!(
            error_of(&mut c, entry(0x5555, 0)),
            AbortCode::ObjectDoesNotExist
        );
        assert_eq!(
            error_of(&mut c, entry(0x1018, 9)),
            AbortCode::SubindexDoesNotExist
        );
        assert_eq!(
            error_of(&mut c, entry(0x2040, 3)),
            AbortCode::TransferFailed
        );
        // A response opcode sent to the server, and an unknown opcode.
        assert_eq!(
            error_of(
                &mut c,
                SdoInfoService::Error {
                    code: AbortCode::GeneralError
                }
            ),
            AbortCode::UnknownCommand
        );
        let replies = c.raw(&[0x00, 0x80, 0x09, 0x00, 0x00, 0x00]);
        assert!(matches!(
            info_reply(&replies[0]).service,
            SdoInfoService::Error {
                code: AbortCode::UnknownCommand
            }
        ));
        // A request whose data are cut short.
        let replies = c.raw(&[0x00, 0x80, 0x03, 0x00, 0x00, 0x00, 0x18]);
        assert!(matches!(
            info_reply(&replies[0]).service,
            SdoInfoService::Error {
                code: AbortCode::LengthTooLow
            }
        ));
    }
}
