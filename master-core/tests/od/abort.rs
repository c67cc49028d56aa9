//! Every refusal of the CoE server reaches the client as an SDO abort with its code
//! (spec-notes §coe.abort, §master-od), and requests that are not SDO at all get an `Outcome` instead.

use crate::od_support;

use master_core::od::{Outcome, PdoEntry, ServerContext};
use master_core::wire::coe::sdo_payload::SdoPayload;
use master_core::wire::coe::sdo_request::SdoRequest;
use master_core::wire::coe::sdo_response::SdoResponse;
use master_core::wire::coe::{AbortCode, CoeService};
use master_core::wire::register::AlState;
use od_support::*;

fn up(index: u16, subindex: u8) -> SdoRequest<'static> {
    SdoRequest::InitiateUpload {
        index,
        subindex,
        complete_access: false,
    }
}

fn ca_up(index: u16, subindex: u8) -> SdoRequest<'static> {
    SdoRequest::InitiateUpload {
        index,
        subindex,
        complete_access: true,
    }
}

fn down(index: u16, subindex: u8, value: &[u8]) -> SdoRequest<'_> {
    SdoRequest::InitiateDownload {
        index,
        subindex,
        complete_access: false,
        payload: SdoPayload::Expedited(value),
    }
}

fn normal(index: u16, subindex: u8, ca: bool, size: u32, data: &[u8]) -> SdoRequest<'_> {
    SdoRequest::InitiateDownload {
        index,
        subindex,
        complete_access: ca,
        payload: SdoPayload::Normal {
            complete_size: size,
            data,
        },
    }
}

/// Under `od` so that `cargo test -p master-core od` selects these tests.
mod od {
    use super::*;

    #[test]
    fn addressing_aborts() {
        let mut c = Client::new(128);
        assert_eq!(c.abort_of(&up(0x5555, 0)), AbortCode::ObjectDoesNotExist);
        assert_eq!(
            c.abort_of(&down(0x5555, 0, &[1])),
            AbortCode::ObjectDoesNotExist
        );
        // Above the highest subindex: 0x06090011; a gap below it: 0x08000020 (spec-notes §master-od).
        assert_eq!(c.abort_of(&up(0x1018, 5)), AbortCode::SubindexDoesNotExist);
        assert_eq!(c.abort_of(&up(0x2004, 1)), AbortCode::SubindexDoesNotExist);
        assert_eq!(c.abort_of(&up(0x2040, 3)), AbortCode::TransferFailed);
        assert_eq!(
            c.abort_of(&down(0x2040, 3, &[1])),
            AbortCode::TransferFailed
        );
        assert_eq!(
            c.abort_of(&down(0x2040, 5, &[1])),
            AbortCode::SubindexDoesNotExist
        );
        // The abort names the object asked for.
        let reply = c.one(&up(0x5555, 7));
        assert_eq!(
            sdo_reply(&reply),
            SdoResponse::Abort {
                index: 0x5555,
                subindex: 7,
                code: AbortCode::ObjectDoesNotExist
            }
        );
    }

    #[test]
    fn access_aborts() {
        let mut c = Client::new(128);
        assert_eq!(
            c.abort_of(&down(0x2030, 0, &[1, 0, 0, 0])),
            AbortCode::ReadOnly
        );
        assert_eq!(
            c.abort_of(&down(0x1018, 1, &[1, 0, 0, 0])),
            AbortCode::ReadOnly
        );
        assert_eq!(c.abort_of(&up(0x2031, 0)), AbortCode::WriteOnly);
        // Write-only is still writable.
        c.download(0x2031, 0, false, &[9, 0, 0, 0]).unwrap();
        // PREOP-only entries in SAFEOP / OP.
        let mut c = Client::new(128).state(AlState::SafeOp);
        assert_eq!(
            c.abort_of(&down(0x2032, 0, &[1, 0])),
            AbortCode::DeviceState
        );
        c.ctx.state = AlState::Op;
        assert_eq!(c.abort_of(&down(0x1C12, 0, &[0])), AbortCode::DeviceState);
        assert_eq!(c.abort_of(&down(0x1600, 0, &[0])), AbortCode::DeviceState);
        // Read is fine in every state.
        assert_eq!(c.upload(0x1C12, 0, false).unwrap(), [1]);
        // Segmented downloads are refused at the initiate, before any segment.
        assert_eq!(
            c.abort_of(&normal(0x2030, 0, false, 4, &[1, 2])),
            AbortCode::ReadOnly
        );
        assert!(!c.server.in_transfer());
    }

    #[test]
    fn length_aborts() {
        let mut c = Client::new(128);
        assert_eq!(
            c.abort_of(&down(0x2002, 0, &[1, 2, 3, 4])),
            AbortCode::LengthTooHigh
        );
        assert_eq!(
            c.abort_of(&down(0x2004, 0, &[1, 2])),
            AbortCode::LengthTooLow
        );
        assert_eq!(
            c.abort_of(&down(0x2003, 0, &[1, 2, 3, 4])),
            AbortCode::LengthTooHigh
        );
        assert_eq!(
            c.abort_of(&normal(0x2033, 0, false, 9, &[0; 9])),
            AbortCode::LengthTooHigh
        );
        assert_eq!(
            c.abort_of(&normal(OCTETS, 0, false, 101, &[0; 101])),
            AbortCode::LengthTooHigh
        );
        // Too long for the entry already at the initiate of a segmented download.
        assert_eq!(
            c.abort_of(&normal(BLOB, 0, false, 5000, &[0; 100])),
            AbortCode::LengthTooHigh
        );
        assert_eq!(
            c.abort_of(&normal(0x2033, 0, false, 6, &[0; 3])),
            AbortCode::LengthTooLow
        );
        // A string may be shorter than its maximum.
        c.download(OCTETS, 0, false, &[1, 2, 3]).unwrap();
        assert_eq!(c.upload(OCTETS, 0, false).unwrap(), [1, 2, 3]);
        // An expedited 4-byte value cut to 7 bytes of mailbox data.
        let replies = c.raw(&[0x00, 0x20, 0x23, 0x04, 0x20, 0x00, 0x01]);
        assert!(matches!(
            sdo_reply(&replies[0]),
            SdoResponse::Abort {
                code: AbortCode::LengthTooLow,
                ..
            }
        ));
        // More data than the complete size announces.
        let replies = c.raw(&[0x00, 0x20, 0x21, 0x10, 0x20, 0x00, 1, 0, 0, 0, 1, 2]);
        assert!(matches!(
            sdo_reply(&replies[0]),
            SdoResponse::Abort {
                code: AbortCode::LengthTooHigh,
                ..
            }
        ));
    }

    #[test]
    fn segments_must_add_up_to_the_complete_size() {
        let mut c = Client::new(128);
        let seg = |last, data| SdoRequest::DownloadSegment {
            toggle: false,
            last,
            data,
        };
        // Last segment arrives with fewer bytes than announced.
        c.one(&normal(BLOB, 0, false, 300, &[1; 100]));
        assert_eq!(c.abort_of(&seg(true, &[2; 50])), AbortCode::LengthMismatch);
        // A segment pushes past the announced size.
        c.one(&normal(BLOB, 0, false, 150, &[1; 100]));
        assert_eq!(c.abort_of(&seg(false, &[2; 51])), AbortCode::LengthMismatch);
        assert!(!c.server.in_transfer());
        assert_eq!(c.dict.write_count(BLOB), 0);
    }

    #[test]
    fn range_aborts() {
        let mut c = Client::new(128);
        assert_eq!(
            c.abort_of(&down(0x2005, 0, &101i16.to_le_bytes())),
            AbortCode::ValueTooHigh
        );
        assert_eq!(
            c.abort_of(&down(0x2005, 0, &(-101i16).to_le_bytes())),
            AbortCode::ValueTooLow
        );
        c.download(0x2005, 0, false, &(-100i16).to_le_bytes())
            .unwrap();
        assert_eq!(c.dict.get::<i16>(0x2005, 0).unwrap(), -100);
        // SI0 above the capacity (8 mapping entries).
        c.download(0x1600, 0, false, &[0]).unwrap();
        assert_eq!(c.abort_of(&down(0x1600, 0, &[9])), AbortCode::ValueTooHigh);
        // BIT2 holds 0..=3.
        assert_eq!(c.abort_of(&down(0x2050, 3, &[4])), AbortCode::ValueTooHigh);
    }

    #[test]
    fn pdo_entries_need_si0_zero() {
        // Strict spec-notes §coe.pdo: mapping and assignment entries change only while SI0 = 0.
        let mut c = Client::new(128);
        let entry = PdoEntry::new(0x7000, 0, 16).to_u32().to_le_bytes();
        assert_eq!(
            c.abort_of(&down(0x1600, 1, &entry)),
            AbortCode::SubindexNotWritable
        );
        assert_eq!(
            c.abort_of(&down(0x1C12, 1, &[0x00, 0x16])),
            AbortCode::SubindexNotWritable
        );
        // Complete access from subindex 1 leaves SI0 as it is, so the same rule applies ...
        let image: Vec<u8> = entry.to_vec();
        assert_eq!(
            c.download(0x1600, 1, true, &image),
            Err(AbortCode::SubindexNotWritable)
        );
        // ... while from subindex 0 it replaces the whole object.
        c.download(0x1C12, 0, true, &[1, 0, 0x00, 0x16]).unwrap();
    }

    #[test]
    fn complete_access_aborts() {
        let mut c = Client::new(128);
        // A DOMAIN has no declared length to lay out (strings do: see
        // `complete_access_lays_strings_out_at_their_declared_length`).
        assert_eq!(
            c.abort_of(&ca_up(BLOB, 0)),
            AbortCode::CompleteAccessUnsupported
        );
        // A string field cut short.
        assert_eq!(
            c.download(0x2060, 0, true, &[2, 0, 1, b'x']),
            Err(AbortCode::LengthMismatch)
        );
        // Only subindex 0 or 1.
        assert_eq!(c.abort_of(&ca_up(0x1018, 2)), AbortCode::UnsupportedAccess);
        assert_eq!(c.abort_of(&ca_up(0x5555, 0)), AbortCode::ObjectDoesNotExist);
        // The image length must match exactly.
        assert_eq!(
            c.download(0x1C12, 0, true, &[1, 0, 0x00]),
            Err(AbortCode::LengthMismatch)
        );
        assert_eq!(
            c.download(0x1C12, 0, true, &[1, 0, 0x00, 0x16, 0x00]),
            Err(AbortCode::LengthMismatch)
        );
        // SI0 in the image above the capacity.
        assert_eq!(
            c.download(0x1C12, 0, true, &[5, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]),
            Err(AbortCode::ValueTooHigh)
        );
        // Everything read-only.
        assert_eq!(
            c.download(0x1018, 1, true, &[0; 16]),
            Err(AbortCode::ReadOnly)
        );
        // A segmented complete-access download longer than the whole object.
        assert_eq!(
            c.abort_of(&normal(0x1C12, 0, true, 200, &[0; 50])),
            AbortCode::LengthMismatch
        );
        // PREOP-only entries in OP.
        c.ctx.state = AlState::Op;
        assert_eq!(
            c.download(0x1C12, 0, true, &[1, 0, 0x00, 0x16]),
            Err(AbortCode::DeviceState)
        );
    }

    #[test]
    fn complete_access_lays_strings_out_at_their_declared_length() {
        let mut c = Client::new(128);
        // 0x2060: SI0 = 2 (16 bits), :01 u8 = 1, :02 VISIBLE_STRING of 16 bytes = "abc".
        let mut expected = vec![2, 0, 1];
        expected.extend_from_slice(b"abc");
        expected.resize(3 + 16, 0);
        assert_eq!(c.upload(0x2060, 0, true).unwrap(), expected);
        assert_eq!(c.upload(0x2060, 1, true).unwrap(), expected[2..]);
        // A VAR string: its value at its declared length (0x1008 declares its own length).
        assert_eq!(c.upload(0x1008, 0, true).unwrap(), b"ecatd test slave");
        // Download: the zero padding is not part of the stored text.
        let mut image = vec![2, 0, 7];
        image.extend_from_slice(b"xy");
        image.resize(3 + 16, 0);
        c.download(0x2060, 0, true, &image).unwrap();
        assert_eq!(c.upload(0x2060, 1, false).unwrap(), [7]);
        assert_eq!(c.upload(0x2060, 2, false).unwrap(), b"xy");
        // An OCTET_STRING keeps every byte of its field.
        let octets: Vec<u8> = (0..100).collect();
        c.download(OCTETS, 0, true, &octets).unwrap();
        assert_eq!(c.upload(OCTETS, 0, false).unwrap(), octets);
    }

    #[test]
    fn protocol_aborts() {
        let mut c = Client::new(128);
        // Block upload (ccs 5 = 0xA0) and block download (ccs 6 = 0xC0): unknown specifier.
        for command in [0xA0u8, 0xC0] {
            let replies = c.raw(&[0x00, 0x20, command, 0x18, 0x10, 0x00, 0, 0, 0, 0]);
            assert_eq!(
                sdo_reply(&replies[0]),
                SdoResponse::Abort {
                    index: 0x1018,
                    subindex: 0,
                    code: AbortCode::UnknownCommand
                }
            );
        }
        // Segments with no transfer in progress.
        assert_eq!(
            c.abort_of(&SdoRequest::UploadSegment { toggle: false }),
            AbortCode::UnknownCommand
        );
        assert_eq!(
            c.abort_of(&SdoRequest::DownloadSegment {
                toggle: false,
                last: true,
                data: &[1]
            }),
            AbortCode::UnknownCommand
        );
        // An upload segment during a download, and the other way round.
        c.one(&normal(BLOB, 0, false, 300, &[1; 100]));
        assert_eq!(
            c.abort_of(&SdoRequest::UploadSegment { toggle: false }),
            AbortCode::UnknownCommand
        );
        assert!(!c.server.in_transfer());
        c.one(&up(BLOB, 0));
        assert_eq!(
            c.abort_of(&SdoRequest::DownloadSegment {
                toggle: false,
                last: false,
                data: &[1; 7]
            }),
            AbortCode::UnknownCommand
        );
    }

    #[test]
    fn initiate_during_a_transfer_restarts_cleanly() {
        let mut c = Client::new(128);
        c.one(&up(BLOB, 0));
        assert!(c.server.in_transfer());
        // A new upload is served as if nothing was pending ...
        assert_eq!(c.upload(0x2002, 0, false).unwrap(), [0x22, 0x22]);
        // ... and the old transfer is gone.
        assert!(!c.server.in_transfer());
        assert_eq!(
            c.abort_of(&SdoRequest::UploadSegment { toggle: false }),
            AbortCode::UnknownCommand
        );
        // A download in the middle of a segmented download starts over too.
        c.one(&normal(BLOB, 0, false, 300, &[1; 100]));
        c.download(BLOB, 0, false, &[7; 300]).unwrap();
        assert_eq!(c.dict.get_bytes(BLOB, 0).unwrap(), &[7; 300][..]);
    }

    #[test]
    fn client_abort_ends_the_transfer_without_reply() {
        let mut c = Client::new(128);
        c.one(&up(BLOB, 0));
        let abort = SdoRequest::Abort {
            index: BLOB,
            subindex: 0,
            code: AbortCode::Timeout,
        };
        assert!(c.raw(&sdo_bytes(&abort)).is_empty());
        assert!(!c.server.in_transfer());
        // A truncated abort is still an abort.
        c.one(&up(BLOB, 0));
        assert!(
            c.raw(&[0x00, 0x20, 0x80, 0x20, 0x20, 0x00, 0x00])
                .is_empty()
        );
        assert!(!c.server.in_transfer());
    }

    #[test]
    fn non_sdo_requests_get_an_outcome() {
        let mut c = Client::new(128);
        let mut sink = |_: &[u8]| panic!("no reply expected");
        let mut handle = |c: &mut Client, bytes: &[u8]| {
            let ctx = c.ctx;
            c.server.handle(&mut c.dict, bytes, ctx, &mut sink)
        };
        assert_eq!(handle(&mut c, &[0x00]), Outcome::Malformed);
        assert_eq!(handle(&mut c, &[0x00, 0x20, 0x40]), Outcome::Malformed);
        assert_eq!(handle(&mut c, &[0x00, 0x80, 0x01]), Outcome::Malformed);
        assert_eq!(
            handle(&mut c, &[0x01, 0x50, 0xAA, 0xBB]),
            Outcome::Unsupported(CoeService::RxPdo)
        );
        assert_eq!(
            handle(&mut c, &[0x00, 0x30, 0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0]),
            Outcome::Unsupported(CoeService::SdoResponse)
        );
        // A request longer than SM0 could carry.
        assert_eq!(handle(&mut c, &[0u8; 123]), Outcome::Malformed);
        c.ctx = ServerContext::new(15, AlState::PreOp);
        assert_eq!(
            handle(&mut c, &sdo_bytes(&up(0x1000, 0))),
            Outcome::MailboxTooSmall
        );
    }

    #[test]
    fn smallest_mailbox_still_transfers() {
        // M = 16: no data fits an initiate frame, 7 bytes per segment.
        let mut c = Client::new(16);
        let data: Vec<u8> = (0..50).collect();
        c.download(OCTETS, 0, false, &data).unwrap();
        assert_eq!(c.upload(OCTETS, 0, false).unwrap(), data);
        assert_eq!(c.upload(0x1008, 0, false).unwrap(), b"ecatd test slave");
    }
}
