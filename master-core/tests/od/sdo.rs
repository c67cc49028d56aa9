//! SDO transfers against the CoE server: expedited, normal, segmented and complete access,
//! the sample-client forms, and write hooks (one per download).

use crate::od_support;

use std::sync::{Arc, Mutex};

use master_core::od::{PdoEntry, WriteEvent};
use master_core::wire::coe::sdo_payload::SdoPayload;
use master_core::wire::coe::sdo_request::SdoRequest;
use master_core::wire::coe::sdo_response::SdoResponse;
use master_core::wire::coe::{AbortCode, max_initiate_data, max_segment_data};
use master_core::wire::mailbox::Mailbox;
use od_support::*;

/// Deterministic, non-repeating test bytes.
fn pattern(len: usize) -> Vec<u8> {
    (0..len).map(|i| (i * 7 + i / 251) as u8).collect()
}

/// Under `od` so that `cargo test -p master-core od` selects these tests.
mod od {
    use super::*;

    #[test]
    fn expedited_round_trips_of_1_2_4_bytes() {
        let mut c = Client::new(128);
        for (index, value) in [
            (0x2001u16, vec![0x5A]),
            (0x2002, vec![0x34, 0x12]),
            (0x2004, vec![0x78, 0x56, 0x34, 0x12]),
        ] {
            // The download is one expedited frame answered by 0x60 with index and subindex.
            let reply = c.one(&SdoRequest::InitiateDownload {
                index,
                subindex: 0,
                complete_access: false,
                payload: SdoPayload::Expedited(&value),
            });
            assert_eq!(
                sdo_reply(&reply),
                SdoResponse::InitiateDownload {
                    index,
                    subindex: 0,
                    complete_access: false
                }
            );
            assert_eq!(reply.len(), 10);
            assert_eq!(c.dict.get_bytes(index, 0).unwrap(), value.as_slice());
            // The upload is expedited with exactly that many bytes.
            let reply = c.one(&SdoRequest::InitiateUpload {
                index,
                subindex: 0,
                complete_access: false,
            });
            assert_eq!(
                sdo_reply(&reply),
                SdoResponse::InitiateUpload {
                    index,
                    subindex: 0,
                    complete_access: false,
                    payload: SdoPayload::Expedited(&value)
                }
            );
        }
        // ETG.1000.6, spec-notes §coe.sdo: upload of 0x1018:01 gives `43 18 10 01 | vendor`.
        let reply = c.one(&SdoRequest::InitiateUpload {
            index: 0x1018,
            subindex: 1,
            complete_access: false,
        });
        assert_eq!(
            reply,
            [0x00, 0x30, 0x43, 0x18, 0x10, 0x01, 0x02, 0x00, 0x00, 0x00]
        );
    }

    #[test]
    fn normal_transfer_of_100_bytes_in_one_frame() {
        let mut c = Client::new(128);
        let data = pattern(100);
        // 100 ≤ 128 − 16: one initiate frame carries everything, no segments.
        let reply = c.one(&SdoRequest::InitiateDownload {
            index: OCTETS,
            subindex: 0,
            complete_access: false,
            payload: SdoPayload::Normal {
                complete_size: 100,
                data: &data,
            },
        });
        assert!(matches!(
            sdo_reply(&reply),
            SdoResponse::InitiateDownload { index: OCTETS, .. }
        ));
        assert!(!c.server.in_transfer());
        assert_eq!(c.dict.get_bytes(OCTETS, 0).unwrap(), data.as_slice());
        let reply = c.one(&SdoRequest::InitiateUpload {
            index: OCTETS,
            subindex: 0,
            complete_access: false,
        });
        assert_eq!(
            sdo_reply(&reply),
            SdoResponse::InitiateUpload {
                index: OCTETS,
                subindex: 0,
                complete_access: false,
                payload: SdoPayload::Normal {
                    complete_size: 100,
                    data: &data
                }
            }
        );
        assert!(!c.server.in_transfer());
    }

    #[test]
    fn four_kib_segmented_both_ways() {
        for mailbox in [128usize, 1024] {
            let mut c = Client::new(mailbox);
            let data = pattern(4096);
            c.download(BLOB, 0, false, &data).unwrap();
            assert_eq!(c.dict.get_bytes(BLOB, 0).unwrap(), data.as_slice());
            assert_eq!(c.dict.write_count(BLOB), 1);
            assert_eq!(c.upload(BLOB, 0, false).unwrap(), data, "mailbox {mailbox}");
            assert!(!c.server.in_transfer());
        }
    }

    #[test]
    fn segmented_upload_frames_follow_the_mailbox_rules() {
        // 4096 bytes with M = 128: 112 in the initiate, then 119 per segment; the last one
        // (4096 − 112 = 3984 = 33 × 119 + 57) carries 57 bytes with the last bit.
        let mut c = Client::new(128);
        let reply = c.one(&SdoRequest::InitiateUpload {
            index: BLOB,
            subindex: 0,
            complete_access: false,
        });
        assert_eq!(reply.len(), 10 + max_initiate_data(128));
        let mut toggle = false;
        let mut segments = 0;
        loop {
            let reply = c.one(&SdoRequest::UploadSegment { toggle });
            let SdoResponse::UploadSegment { last, data, .. } = sdo_reply(&reply) else {
                panic!("not a segment");
            };
            segments += 1;
            if last {
                assert_eq!(data.len(), 57);
                break;
            }
            assert_eq!(data.len(), max_segment_data(128));
            toggle = !toggle;
        }
        assert_eq!(segments, 34);
    }

    #[test]
    fn short_last_segment_is_padded_to_seven_bytes() {
        // 100 bytes, M = 24: 8 in the initiate, 15 per segment; 92 = 6 × 15 + 2, the last
        // segment has 2 bytes in a 10-byte frame with 5 unused (spec-notes §coe.sdo rule).
        let mut c = Client::new(24);
        let data = pattern(100);
        c.download(OCTETS, 0, false, &data).unwrap();
        c.one(&SdoRequest::InitiateUpload {
            index: OCTETS,
            subindex: 0,
            complete_access: false,
        });
        let mut toggle = false;
        let mut got = data[..8].to_vec();
        loop {
            let reply = c.one(&SdoRequest::UploadSegment { toggle });
            let SdoResponse::UploadSegment {
                last, data: seg, ..
            } = sdo_reply(&reply)
            else {
                panic!("not a segment");
            };
            got.extend_from_slice(seg);
            if last {
                assert_eq!(reply.len(), 10);
                assert_eq!(reply[2], 0x01 | (5 << 1) | if toggle { 0x10 } else { 0 });
                break;
            }
            toggle = !toggle;
        }
        assert_eq!(got, data);
    }

    #[test]
    fn wrong_toggle_aborts_both_ways() {
        let mut c = Client::new(128);
        c.one(&SdoRequest::InitiateUpload {
            index: BLOB,
            subindex: 0,
            complete_access: false,
        });
        // The first segment request must have toggle 0.
        let reply = c.one(&SdoRequest::UploadSegment { toggle: true });
        assert_eq!(
            sdo_reply(&reply),
            SdoResponse::Abort {
                index: BLOB,
                subindex: 0,
                code: AbortCode::ToggleBit
            }
        );
        assert!(!c.server.in_transfer());

        let data = pattern(300);
        let reply = c.one(&SdoRequest::InitiateDownload {
            index: BLOB,
            subindex: 0,
            complete_access: false,
            payload: SdoPayload::Normal {
                complete_size: 300,
                data: &data[..100],
            },
        });
        assert!(matches!(
            sdo_reply(&reply),
            SdoResponse::InitiateDownload { .. }
        ));
        let seg = |toggle, data| SdoRequest::DownloadSegment {
            toggle,
            last: false,
            data,
        };
        assert!(matches!(
            sdo_reply(&c.one(&seg(false, &data[100..200]))),
            SdoResponse::DownloadSegment { toggle: false }
        ));
        // Toggle 0 again instead of 1.
        assert_eq!(
            c.abort_of(&seg(false, &data[200..300])),
            AbortCode::ToggleBit
        );
        assert!(!c.server.in_transfer());
        // Nothing was stored.
        assert_eq!(c.dict.get_bytes(BLOB, 0).unwrap()[0], 0xEE);
        assert_eq!(c.dict.write_count(BLOB), 0);
    }

    #[test]
    fn complete_access_upload_of_identity_and_assignment() {
        let mut c = Client::new(128);
        let mut expected = vec![4, 0];
        for v in [VENDOR, PRODUCT, REVISION, SERIAL] {
            expected.extend_from_slice(&v.to_le_bytes());
        }
        assert_eq!(c.upload(0x1018, 0, true).unwrap(), expected);
        // From subindex 1: no SI0.
        assert_eq!(c.upload(0x1018, 1, true).unwrap(), expected[2..]);
        // 0x1C12 = {SI0 = 1 padded to 16 bits, 0x1600}: 4 bytes, expedited with the CA bit.
        let reply = c.one(&SdoRequest::InitiateUpload {
            index: 0x1C12,
            subindex: 0,
            complete_access: true,
        });
        assert_eq!(
            reply,
            [0x00, 0x30, 0x53, 0x12, 0x1c, 0x00, 0x01, 0x00, 0x00, 0x16]
        );
        // Entries beyond SI0 are not part of the image.
        c.dict.set(0x1C12, 2, &0x1601u16).unwrap();
        assert_eq!(c.upload(0x1C12, 0, true).unwrap(), [1, 0, 0x00, 0x16]);
        // A gap is skipped: 0x2040 = SI0 4, :01 u16, :02 u32, (:03 missing), :04 u8.
        assert_eq!(
            c.upload(0x2040, 0, true).unwrap(),
            [4, 0, 0x01, 0x01, 0x02, 0x02, 0x02, 0x02, 4]
        );
        // A VAR through complete access is its value.
        assert_eq!(
            c.upload(0x2004, 0, true).unwrap(),
            0x4444_4444u32.to_le_bytes()
        );
    }

    #[test]
    fn complete_access_packs_bits() {
        let mut c = Client::new(128);
        // SI0 (16 bits), A = 1, B = 0, two bits = 2 → 0b1001 in one byte, then byte 0xAB,
        // then C = 1.
        let image = c.upload(0x2050, 0, true).unwrap();
        assert_eq!(image, [5, 0, 0b1001, 0xAB, 0x01]);
        // Write A = 0, B = 1, bits = 3, byte 0x12; C is read-only and skipped.
        c.download(0x2050, 0, true, &[5, 0, 0b1110, 0x12, 0x00])
            .unwrap();
        assert!(!c.dict.get::<bool>(0x2050, 1).unwrap());
        assert!(c.dict.get::<bool>(0x2050, 2).unwrap());
        assert_eq!(c.dict.get::<u8>(0x2050, 3).unwrap(), 3);
        assert_eq!(c.dict.get::<u8>(0x2050, 4).unwrap(), 0x12);
        assert!(c.dict.get::<bool>(0x2050, 5).unwrap());
        assert_eq!(c.dict.entry_write_count(0x2050, 5), 0);
    }

    #[test]
    fn complete_access_download_of_a_pdo_mapping() {
        let mut c = Client::new(128);
        let entries = [PdoEntry::new(0x7000, 0, 16), PdoEntry::new(0x0000, 0, 8)];
        let mut image = vec![2, 0];
        for e in entries {
            image.extend_from_slice(&e.to_u32().to_le_bytes());
        }
        c.download(0x1600, 0, true, &image).unwrap();
        assert_eq!(c.dict.mapped_entries(0x1600), entries);
        assert_eq!(c.dict.process_data_bits(0x1C12), 24);
        assert_eq!(c.dict.write_count(0x1600), 1);
        assert_eq!(c.upload(0x1600, 0, true).unwrap(), image);
        // The whole assignment too, segmented through a small mailbox (M = 20: 4 bytes in
        // the initiate frame, the rest in a segment).
        let mut small = Client::new(20);
        small
            .download(0x1C12, 0, true, &[2, 0, 0x00, 0x16, 0x01, 0x16])
            .unwrap();
        assert_eq!(small.dict.assigned_pdos(0x1C12), [0x1600, 0x1601]);
        assert_eq!(small.dict.write_count(0x1C12), 1);
    }

    #[test]
    fn tolerated_sample_client_requests_are_served() {
        let mut c = Client::new(128);
        // spec-notes §coe.sdo-short: an upload request of 8 bytes (reserved bytes cut to 2)...
        let upload = [
            0x08, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0x00, 0x00,
        ];
        let mbx = Mailbox::new_checked(&upload[..]).unwrap();
        let replies = c.raw(mbx.data());
        assert_eq!(replies.len(), 1);
        assert_eq!(
            sdo_reply(&replies[0]),
            SdoResponse::InitiateUpload {
                index: 0x1018,
                subindex: 1,
                complete_access: false,
                payload: SdoPayload::Expedited(&VENDOR.to_le_bytes())
            }
        );
        // ... and a download with command 0x20 and a 2-byte value.
        let download = [
            0x08, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x20, 0x20, 0x02, 0x20, 0x00, 0x34, 0x12,
        ];
        let mbx = Mailbox::new_checked(&download[..]).unwrap();
        let replies = c.raw(mbx.data());
        assert_eq!(replies.len(), 1);
        assert!(matches!(
            sdo_reply(&replies[0]),
            SdoResponse::InitiateDownload {
                index: 0x2002,
                subindex: 0,
                ..
            }
        ));
        assert_eq!(c.dict.get::<u16>(0x2002, 0).unwrap(), 0x1234);
        // Expedited without size indication (0x22): the object's size decides.
        let replies = c.raw(&[0x00, 0x20, 0x22, 0x02, 0x20, 0x00, 0x78, 0x56, 0xAA, 0xBB]);
        assert!(matches!(
            sdo_reply(&replies[0]),
            SdoResponse::InitiateDownload { .. }
        ));
        assert_eq!(c.dict.get::<u16>(0x2002, 0).unwrap(), 0x5678);
    }

    #[test]
    fn write_hook_sees_one_write_per_download() {
        let mut c = Client::new(64);
        // (index, subindices, complete access) of every download the hook saw.
        type Seen = Vec<(u16, Vec<u8>, bool)>;
        let seen: Arc<Mutex<Seen>> = Arc::default();
        let log = seen.clone();
        c.dict.on_write(.., move |e: &WriteEvent<'_>, _| {
            log.lock()
                .unwrap()
                .push((e.index, e.subindices.to_vec(), e.complete_access));
            Ok(())
        });
        c.download(0x2002, 0, false, &[1, 2]).unwrap(); // expedited
        c.download(OCTETS, 0, false, &pattern(40)).unwrap(); // normal, one frame
        c.download(BLOB, 0, false, &pattern(1000)).unwrap(); // segmented
        c.download(0x1018, 0, true, &[0; 18]).unwrap_err(); // read-only: no write
        c.download(0x2040, 0, true, &[4, 0, 1, 2, 3, 4, 5, 6, 7])
            .unwrap(); // complete access
        assert_eq!(
            *seen.lock().unwrap(),
            [
                (0x2002, vec![0], false),
                (OCTETS, vec![0], false),
                (BLOB, vec![0], false),
                // SI0 of 0x2040 is read-only: skipped, the gap :03 too.
                (0x2040, vec![1, 2, 4], true),
            ]
        );
        for index in [0x2002, OCTETS, BLOB, 0x2040] {
            assert_eq!(c.dict.write_count(index), 1, "0x{index:04X}");
        }
        assert_eq!(c.dict.write_count(0x1018), 0);
        assert_eq!(c.dict.entry_write_count(0x2040, 4), 1);
        // Uploads write nothing.
        c.upload(BLOB, 0, false).unwrap();
        assert_eq!(seen.lock().unwrap().len(), 4);
    }

    #[test]
    fn write_hook_can_refuse_and_the_value_is_restored() {
        let mut c = Client::new(128);
        // The simulator's kind of check: an assignment may only name existing PDOs.
        c.dict.on_write(0x1C12..=0x1C13, |e, dict| {
            let assigned = dict.assigned_pdos(e.index);
            if assigned.iter().all(|&pdo| dict.get_object(pdo).is_some()) {
                Ok(())
            } else {
                Err(AbortCode::ParameterIncompatible)
            }
        });
        let image = [1, 0, 0x05, 0x16]; // {0x1605}, which does not exist
        assert_eq!(
            c.download(0x1C12, 0, true, &image),
            Err(AbortCode::ParameterIncompatible)
        );
        assert_eq!(c.dict.assigned_pdos(0x1C12), [0x1600]);
        assert_eq!(c.dict.write_count(0x1C12), 0);
        c.download(0x1C12, 0, true, &[1, 0, 0x00, 0x16]).unwrap();
        assert_eq!(c.dict.write_count(0x1C12), 1);
    }

    #[test]
    fn pdo_procedure_of_digest_6_11() {
        // Expedited downloads in the order of ETG.1000.6, spec-notes §coe.pdo succeed in PREOP.
        let mut c = Client::new(128);
        c.download(0x1C12, 0, false, &[0]).unwrap();
        c.download(0x1600, 0, false, &[0]).unwrap();
        c.download(
            0x1600,
            1,
            false,
            &PdoEntry::new(0x7000, 0, 16).to_u32().to_le_bytes(),
        )
        .unwrap();
        c.download(
            0x1600,
            2,
            false,
            &PdoEntry::new(0, 0, 16).to_u32().to_le_bytes(),
        )
        .unwrap();
        c.download(0x1600, 0, false, &[2]).unwrap();
        c.download(0x1C12, 1, false, &0x1600u16.to_le_bytes())
            .unwrap();
        c.download(0x1C12, 0, false, &[1]).unwrap();
        assert_eq!(c.dict.process_data_bits(0x1C12), 32);
        assert_eq!(c.dict.write_count(0x1C12), 3);
    }
}
