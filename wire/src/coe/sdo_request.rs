//! SDO requests, client → server (CoE service 2; ETG.1000.6, spec-notes §coe.sdo).

use core::fmt;

use super::abort::AbortCode;
use super::display::{Hex, ObjAddr};
use super::header::CoeService;
use super::sdo::{
    SDO_INITIATE_LEN, SdoFrame, cmd, expect_service, segment_len, write_bare, write_initiate,
    write_segment,
};
use super::sdo_payload::SdoPayload;
use crate::error::{Result, WireError, room};

const WHAT: &str = "SDO request";

/// Client command specifiers (bits 5-7 of the command byte in service 2).
mod ccs {
    pub const DOWNLOAD_SEGMENT: u8 = 0;
    pub const INITIATE_DOWNLOAD: u8 = 1;
    pub const INITIATE_UPLOAD: u8 = 2;
    pub const UPLOAD_SEGMENT: u8 = 3;
    pub const ABORT: u8 = 4;
}

/// An SDO request (every form a client sends).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SdoRequest<'a> {
    /// Initiate download (write): ccs 1, e.g. 0x23/0x27/0x2B/0x2F expedited, 0x21 normal.
    InitiateDownload {
        /// Object index.
        index: u16,
        /// Subindex (0 or 1 with complete access).
        subindex: u8,
        /// Complete access (bit 4).
        complete_access: bool,
        /// The value or the first part of it.
        payload: SdoPayload<'a>,
    },
    /// Download segment: ccs 0; toggle starts at 0 and alternates.
    DownloadSegment {
        /// Toggle bit (bit 4).
        toggle: bool,
        /// No more segments follow (bit 0).
        last: bool,
        /// Segment data.
        data: &'a [u8],
    },
    /// Initiate upload (read): ccs 2, 0x40 (0x50 with complete access).
    InitiateUpload {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Complete access (bit 4).
        complete_access: bool,
    },
    /// Upload segment request: ccs 3, 0x60 / 0x70.
    UploadSegment {
        /// Toggle bit (bit 4).
        toggle: bool,
    },
    /// Abort transfer: 0x80.
    Abort {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Why.
        code: AbortCode,
    },
}

impl<'a> SdoRequest<'a> {
    /// Parses an SDO request from mailbox data (CoE header included; service must be 2).
    ///
    /// Reserved command bits are ignored, as are the reserved bytes of an upload request
    /// (which may be missing, see [`super::sdo`]).
    pub fn parse(frame: &SdoFrame<&'a [u8]>) -> Result<Self> {
        frame.check_len()?;
        expect_service(
            "CoE service of an SDO request",
            frame,
            CoeService::SdoRequest,
        )?;
        let command = frame.command();
        let complete_access = command & cmd::COMPLETE_ACCESS != 0;
        let toggle = command & cmd::TOGGLE != 0;
        Ok(match frame.specifier() {
            ccs::INITIATE_DOWNLOAD => SdoRequest::InitiateDownload {
                index: frame.index(),
                subindex: frame.subindex(),
                complete_access,
                payload: SdoPayload::decode(WHAT, frame)?,
            },
            ccs::DOWNLOAD_SEGMENT => SdoRequest::DownloadSegment {
                toggle,
                last: command & cmd::LAST != 0,
                data: frame.segment_data_ref(),
            },
            ccs::INITIATE_UPLOAD => SdoRequest::InitiateUpload {
                index: frame.index(),
                subindex: frame.subindex(),
                complete_access,
            },
            ccs::UPLOAD_SEGMENT => SdoRequest::UploadSegment { toggle },
            ccs::ABORT => {
                let (index, subindex, code) = frame.abort_fields()?;
                SdoRequest::Abort {
                    index,
                    subindex,
                    code,
                }
            }
            other => {
                return Err(WireError::UnknownType {
                    what: "SDO request command specifier",
                    value: u32::from(other),
                });
            }
        })
    }

    /// Mailbox length of the request (CoE header included).
    pub fn buffer_len(&self) -> usize {
        match self {
            SdoRequest::InitiateDownload { payload, .. } => payload.frame_len(),
            SdoRequest::DownloadSegment { data, .. } => segment_len(data.len()),
            _ => SDO_INITIATE_LEN,
        }
    }

    /// Writes the request (CoE header included) into the first `buffer_len()` bytes.
    ///
    /// Expedited values are zero-padded to 4 bytes; segments shorter than 7 bytes are padded
    /// with the unused count in bits 1-3. Refuses an empty or over-long expedited value, more
    /// data than the complete size, and an empty size-unspecified transfer.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, frame: &mut SdoFrame<T>) -> Result<()> {
        if let SdoRequest::InitiateDownload { payload, .. } = self {
            payload.validate(WHAT)?;
        }
        let len = self.buffer_len();
        let buf = frame.buffer_mut();
        room(WHAT, buf, len)?;
        let buf = &mut buf[..len];
        let svc = CoeService::SdoRequest;
        let ca = |on: bool| if on { cmd::COMPLETE_ACCESS } else { 0 };
        let tg = |on: bool| if on { cmd::TOGGLE } else { 0 };
        match *self {
            SdoRequest::InitiateDownload {
                index,
                subindex,
                complete_access,
                payload,
            } => {
                let command = (ccs::INITIATE_DOWNLOAD << cmd::SPECIFIER_SHIFT)
                    | ca(complete_access)
                    | payload.command_bits();
                let (field, data) = payload.field_and_data();
                write_initiate(buf, svc, command, index, subindex, field, data);
            }
            SdoRequest::DownloadSegment { toggle, last, data } => {
                let command = (ccs::DOWNLOAD_SEGMENT << cmd::SPECIFIER_SHIFT)
                    | tg(toggle)
                    | if last { cmd::LAST } else { 0 };
                write_segment(buf, svc, command, data);
            }
            SdoRequest::InitiateUpload {
                index,
                subindex,
                complete_access,
            } => {
                let command = (ccs::INITIATE_UPLOAD << cmd::SPECIFIER_SHIFT) | ca(complete_access);
                write_initiate(buf, svc, command, index, subindex, [0; 4], &[]);
            }
            SdoRequest::UploadSegment { toggle } => {
                write_bare(
                    buf,
                    svc,
                    (ccs::UPLOAD_SEGMENT << cmd::SPECIFIER_SHIFT) | tg(toggle),
                );
            }
            SdoRequest::Abort {
                index,
                subindex,
                code,
            } => {
                let field = u32::from(code).to_le_bytes();
                write_initiate(buf, svc, cmd::ABORT, index, subindex, field, &[]);
            }
        }
        Ok(())
    }
}

impl fmt::Display for SdoRequest<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ca = |on: bool| if on { " CA" } else { "" };
        match self {
            SdoRequest::InitiateDownload {
                index,
                subindex,
                complete_access,
                payload,
            } => write!(
                f,
                "CoE SDO download req {}{} {payload}",
                ObjAddr(*index, *subindex),
                ca(*complete_access)
            ),
            SdoRequest::DownloadSegment { toggle, last, data } => write!(
                f,
                "CoE SDO download segment req toggle {}{} {} bytes {}",
                u8::from(*toggle),
                if *last { " last" } else { "" },
                data.len(),
                Hex(data)
            ),
            SdoRequest::InitiateUpload {
                index,
                subindex,
                complete_access,
            } => write!(
                f,
                "CoE SDO upload req {}{}",
                ObjAddr(*index, *subindex),
                ca(*complete_access)
            ),
            SdoRequest::UploadSegment { toggle } => {
                write!(f, "CoE SDO upload segment req toggle {}", u8::from(*toggle))
            }
            SdoRequest::Abort {
                index,
                subindex,
                code,
            } => write!(f, "CoE SDO abort req {} {code}", ObjAddr(*index, *subindex)),
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::mailbox::{HEADER_LEN, Mailbox, MailboxHeader, MailboxType};
    use proptest::prelude::*;

    /// Parses mailbox data as a request.
    fn parse(data: &[u8]) -> Result<SdoRequest<'_>> {
        SdoRequest::parse(&SdoFrame::new_checked(data)?)
    }

    /// Emits into a 0xa5-filled buffer of exactly `buffer_len()` bytes.
    fn emit(req: &SdoRequest<'_>) -> Vec<u8> {
        let mut out = vec![0xa5u8; req.buffer_len()];
        req.emit(&mut SdoFrame::new_unchecked(&mut out[..]))
            .unwrap();
        out
    }

    fn expedited(index: u16, subindex: u8, value: &[u8]) -> SdoRequest<'_> {
        SdoRequest::InitiateDownload {
            index,
            subindex,
            complete_access: false,
            payload: SdoPayload::Expedited(value),
        }
    }

    // The worked upload request (spec-notes §coe.sdo), as the first 16 bytes of the 128-byte SM0 image.
    static C6_REQUEST: [u8; 16] = [
        0x0a, 0x00, 0x00, 0x00, 0x00, 0x33, 0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0x00, 0x00, 0x00,
        0x00,
    ];

    #[test]
    fn c6_upload_request() {
        let mut image = [0u8; 128];
        image[..16].copy_from_slice(&C6_REQUEST);
        let mbx = Mailbox::new_checked(&image[..]).unwrap();
        let header = MailboxHeader::parse(&mbx).unwrap();
        assert_eq!(header.mailbox_type, MailboxType::Coe);
        assert_eq!(header.counter, 3);
        let req = parse(mbx.data()).unwrap();
        let expected = SdoRequest::InitiateUpload {
            index: 0x1018,
            subindex: 1,
            complete_access: false,
        };
        assert_eq!(req, expected);
        assert_eq!(req.to_string(), "CoE SDO upload req 0x1018:01");

        // Emit header + request into a 0xa5 SM0 image; the rest of the image is untouched.
        let mut out = [0xa5u8; 128];
        let mut mbx = Mailbox::new_unchecked(&mut out[..]);
        MailboxHeader {
            length: expected.buffer_len() as u16,
            counter: 3,
            ..header
        }
        .emit(&mut mbx)
        .unwrap();
        expected
            .emit(&mut SdoFrame::new_unchecked(mbx.data_mut()))
            .unwrap();
        assert_eq!(out[..16], C6_REQUEST);
        assert!(out[16..].iter().all(|&b| b == 0xa5));
    }

    // ETG.1000.6, spec-notes §coe.pdo: 0x1C12 ← {0x1600}.
    static C7: [([u8; 10], u16, u8, &[u8]); 3] = [
        (
            [0x00, 0x20, 0x2f, 0x12, 0x1c, 0x00, 0, 0, 0, 0],
            0x1C12,
            0,
            &[0x00],
        ),
        (
            [0x00, 0x20, 0x2b, 0x12, 0x1c, 0x01, 0x00, 0x16, 0, 0],
            0x1C12,
            1,
            &[0x00, 0x16],
        ),
        (
            [0x00, 0x20, 0x2f, 0x12, 0x1c, 0x00, 0x01, 0, 0, 0],
            0x1C12,
            0,
            &[0x01],
        ),
    ];

    #[test]
    fn c7_expedited_downloads() {
        for (bytes, index, subindex, value) in &C7 {
            let req = expedited(*index, *subindex, value);
            assert_eq!(parse(bytes).unwrap(), req);
            assert_eq!(emit(&req), bytes);
        }
        assert_eq!(
            parse(&C7[1].0).unwrap().to_string(),
            "CoE SDO download req 0x1C12:01 expedited 2 bytes [00 16]"
        );
    }

    #[test]
    fn seed_1c12_1601_assignment() {
        // spec-notes §capture: RxPDO 0x1601 = {0x6040:00 16 bit, 0x6060:00 8 bit}, assigned to SM2.
        // Bytes by hand (spec-notes §coe.sdo): 1 byte → 0x2F, 2 bytes → 0x2B, 4 bytes → 0x23; LE values.
        let cases: [([u8; 10], SdoRequest<'static>); 5] = [
            (
                [0x00, 0x20, 0x2f, 0x12, 0x1c, 0x00, 0x00, 0x00, 0x00, 0x00],
                expedited(0x1C12, 0, &[0x00]),
            ),
            (
                [0x00, 0x20, 0x2b, 0x12, 0x1c, 0x01, 0x01, 0x16, 0x00, 0x00],
                expedited(0x1C12, 1, &[0x01, 0x16]),
            ),
            (
                [0x00, 0x20, 0x2f, 0x12, 0x1c, 0x00, 0x01, 0x00, 0x00, 0x00],
                expedited(0x1C12, 0, &[0x01]),
            ),
            (
                [0x00, 0x20, 0x23, 0x01, 0x16, 0x01, 0x10, 0x00, 0x40, 0x60],
                expedited(0x1601, 1, &[0x10, 0x00, 0x40, 0x60]),
            ),
            (
                [0x00, 0x20, 0x23, 0x01, 0x16, 0x02, 0x08, 0x00, 0x60, 0x60],
                expedited(0x1601, 2, &[0x08, 0x00, 0x60, 0x60]),
            ),
        ];
        for (bytes, req) in &cases {
            assert_eq!(&parse(bytes).unwrap(), req);
            assert_eq!(&emit(req), bytes);
        }
        // The mapping entries decode to 0x60400010 and 0x60600008.
        if let SdoRequest::InitiateDownload {
            payload: SdoPayload::Expedited(v),
            ..
        } = cases[3].1
        {
            assert_eq!(u32::from_le_bytes(v.try_into().unwrap()), 0x6040_0010);
        }
        assert_eq!(
            cases[4].1.to_string(),
            "CoE SDO download req 0x1601:02 expedited 4 bytes [08 00 60 60]"
        );
    }

    #[test]
    fn c9_segmented_download() {
        // Initiate with M = 24: 8 of 10 bytes in the first frame.
        let initiate_mbx = [
            0x12, 0x00, 0x00, 0x00, 0x00, 0x23, 0x00, 0x20, 0x21, 0x00, 0x80, 0x00, 0x0a, 0x00,
            0x00, 0x00, 0xd0, 0xd1, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7,
        ];
        let data = [0xd0, 0xd1, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7];
        let initiate = SdoRequest::InitiateDownload {
            index: 0x8000,
            subindex: 0,
            complete_access: false,
            payload: SdoPayload::Normal {
                complete_size: 10,
                data: &data,
            },
        };
        let mbx = Mailbox::new_checked(&initiate_mbx[..]).unwrap();
        assert_eq!(parse(mbx.data()).unwrap(), initiate);
        assert_eq!(initiate.buffer_len(), 0x12);
        assert_eq!(emit(&initiate), initiate_mbx[HEADER_LEN..]);
        assert_eq!(
            initiate.to_string(),
            "CoE SDO download req 0x8000:00 normal size 10, 8 bytes [d0 d1 d2 d3 d4 d5 d6 d7]"
        );

        // Last segment, 2 bytes, toggle 0: cmd 0x0B, padded to 7, mailbox length 10.
        let segment_mbx = [
            0x0a, 0x00, 0x00, 0x00, 0x00, 0x33, 0x00, 0x20, 0x0b, 0xd8, 0xd9, 0, 0, 0, 0, 0,
        ];
        let segment = SdoRequest::DownloadSegment {
            toggle: false,
            last: true,
            data: &[0xd8, 0xd9],
        };
        let mbx = Mailbox::new_checked(&segment_mbx[..]).unwrap();
        assert_eq!(parse(mbx.data()).unwrap(), segment);
        assert_eq!(emit(&segment), segment_mbx[HEADER_LEN..]);
        assert_eq!(
            segment.to_string(),
            "CoE SDO download segment req toggle 0 last 2 bytes [d8 d9]"
        );
    }

    #[test]
    fn long_segment_has_no_padding() {
        // 9 bytes, toggle 1, not last: cmd 0x10, length 3 + 9 = 12, bits 1-3 zero.
        let data = [1, 2, 3, 4, 5, 6, 7, 8, 9];
        let seg = SdoRequest::DownloadSegment {
            toggle: true,
            last: false,
            data: &data,
        };
        let bytes = [0x00, 0x20, 0x10, 1, 2, 3, 4, 5, 6, 7, 8, 9];
        assert_eq!(emit(&seg), bytes);
        assert_eq!(parse(&bytes).unwrap(), seg);
        // Exactly 7 bytes: length 10, unused 0.
        let seven = [1, 2, 3, 4, 5, 6, 7];
        let seg = SdoRequest::DownloadSegment {
            toggle: false,
            last: true,
            data: &seven,
        };
        assert_eq!(emit(&seg), [0x00, 0x20, 0x01, 1, 2, 3, 4, 5, 6, 7]);
    }

    #[test]
    fn complete_access_and_normal_download() {
        // 0x50: upload with complete access, 0x1C12:00.
        let bytes = [0x00, 0x20, 0x50, 0x12, 0x1c, 0x00, 0, 0, 0, 0];
        let req = SdoRequest::InitiateUpload {
            index: 0x1C12,
            subindex: 0,
            complete_access: true,
        };
        assert_eq!(parse(&bytes).unwrap(), req);
        assert_eq!(emit(&req), bytes);
        assert_eq!(req.to_string(), "CoE SDO upload req 0x1C12:00 CA");

        // 0x31: CA download of 0x1C12 = {SI0 = 1 padded to 16 bits, 0x1601}: 4 bytes.
        let bytes = [
            0x00, 0x20, 0x31, 0x12, 0x1c, 0x00, 0x04, 0x00, 0x00, 0x00, 0x01, 0x00, 0x01, 0x16,
        ];
        let req = SdoRequest::InitiateDownload {
            index: 0x1C12,
            subindex: 0,
            complete_access: true,
            payload: SdoPayload::Normal {
                complete_size: 4,
                data: &[0x01, 0x00, 0x01, 0x16],
            },
        };
        assert_eq!(parse(&bytes).unwrap(), req);
        assert_eq!(emit(&req), bytes);
    }

    #[test]
    fn upload_segment_requests() {
        for (toggle, command) in [(false, 0x60), (true, 0x70)] {
            let bytes = [0x00, 0x20, command, 0, 0, 0, 0, 0, 0, 0];
            let req = SdoRequest::UploadSegment { toggle };
            assert_eq!(parse(&bytes).unwrap(), req);
            assert_eq!(emit(&req), bytes);
        }
        // SOEM puts index/subindex into the reserved bytes; ignored.
        let soem = [0x00, 0x20, 0x70, 0x00, 0x80, 0x00, 0, 0, 0, 0];
        assert_eq!(
            parse(&soem).unwrap(),
            SdoRequest::UploadSegment { toggle: true }
        );
        assert_eq!(
            SdoRequest::UploadSegment { toggle: true }.to_string(),
            "CoE SDO upload segment req toggle 1"
        );
    }

    #[test]
    fn tolerated_sample_client_forms() {
        // 8-byte upload request (mailbox length 8): reserved bytes cut to 2.
        let short_upload = [
            0x08, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0x00, 0x00,
        ];
        let mbx = Mailbox::new_checked(&short_upload[..]).unwrap();
        assert_eq!(mbx.data().len(), 8);
        assert_eq!(
            parse(mbx.data()).unwrap(),
            SdoRequest::InitiateUpload {
                index: 0x1018,
                subindex: 1,
                complete_access: false
            }
        );
        // 0x20 with a 2-byte value, mailbox length 8: expedited 2 bytes.
        let short_download = [
            0x08, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x20, 0x20, 0x00, 0x70, 0x01, 0x34, 0x12,
        ];
        let mbx = Mailbox::new_checked(&short_download[..]).unwrap();
        let req = parse(mbx.data()).unwrap();
        assert_eq!(req, expedited(0x7000, 1, &[0x34, 0x12]));
        // Emit produces the standard 10-byte form 0x2B.
        assert_eq!(
            emit(&req),
            [0x00, 0x20, 0x2b, 0x00, 0x70, 0x01, 0x34, 0x12, 0x00, 0x00]
        );
        // 0x20 with 1 and 4 bytes.
        assert_eq!(
            parse(&[0x00, 0x20, 0x20, 0x00, 0x70, 0x01, 0x7f]).unwrap(),
            expedited(0x7000, 1, &[0x7f])
        );
        assert_eq!(
            parse(&[0x00, 0x20, 0x20, 0x00, 0x70, 0x01, 1, 2, 3, 4]).unwrap(),
            expedited(0x7000, 1, &[1, 2, 3, 4])
        );
        // 0x20 with no data at all is still an error.
        assert!(matches!(
            parse(&[0x00, 0x20, 0x20, 0x00, 0x70, 0x01]),
            Err(WireError::Truncated { .. })
        ));
        // Longer than 10 bytes: a normal transfer without size indication.
        assert_eq!(
            parse(&[0x00, 0x20, 0x20, 0x00, 0x70, 0x01, 0, 0, 0, 0, 9, 8]).unwrap(),
            SdoRequest::InitiateDownload {
                index: 0x7000,
                subindex: 1,
                complete_access: false,
                payload: SdoPayload::SizeUnspecified { data: &[9, 8] }
            }
        );
    }

    #[test]
    fn abort_request() {
        let bytes = [0x00, 0x20, 0x80, 0x00, 0x80, 0x00, 0x00, 0x00, 0x03, 0x05];
        let req = SdoRequest::Abort {
            index: 0x8000,
            subindex: 0,
            code: AbortCode::ToggleBit,
        };
        assert_eq!(parse(&bytes).unwrap(), req);
        assert_eq!(emit(&req), bytes);
        assert_eq!(
            req.to_string(),
            "CoE SDO abort req 0x8000:00 0x05030000 Toggle bit not changed"
        );
    }

    #[test]
    fn errors() {
        // Response service is refused.
        assert!(matches!(
            parse(&[0x00, 0x30, 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]),
            Err(WireError::UnknownType { value: 3, .. })
        ));
        // Block transfer specifiers (5, 6) are not supported.
        assert!(matches!(
            parse(&[0x00, 0x20, 0xc0, 0x18, 0x10, 0x01, 0, 0, 0, 0]),
            Err(WireError::UnknownType { value: 6, .. })
        ));
        // Abort without its code.
        assert!(matches!(
            parse(&[0x00, 0x20, 0x80, 0x00, 0x20, 0x00, 0x00]),
            Err(WireError::Truncated { .. })
        ));
        // Normal download without the complete size.
        assert!(parse(&[0x00, 0x20, 0x21, 0x00, 0x20, 0x00, 0x00]).is_err());
        // Normal download with more data than its complete size.
        assert!(matches!(
            parse(&[0x00, 0x20, 0x21, 0x00, 0x20, 0x00, 0x01, 0, 0, 0, 1, 2]),
            Err(WireError::Invalid { .. })
        ));
        // Expedited 4 bytes (0x23) cut to 7 bytes.
        assert!(parse(&[0x00, 0x20, 0x23, 0x00, 0x20, 0x00, 0x01]).is_err());

        // Emit refusals write nothing.
        let mut out = [0u8; 16];
        for bad in [
            expedited(0x2000, 0, &[]),
            expedited(0x2000, 0, &[1, 2, 3, 4, 5]),
            SdoRequest::InitiateDownload {
                index: 0x2000,
                subindex: 0,
                complete_access: false,
                payload: SdoPayload::Normal {
                    complete_size: 1,
                    data: &[1, 2],
                },
            },
            SdoRequest::InitiateDownload {
                index: 0x2000,
                subindex: 0,
                complete_access: false,
                payload: SdoPayload::SizeUnspecified { data: &[] },
            },
        ] {
            assert!(
                bad.emit(&mut SdoFrame::new_unchecked(&mut out[..]))
                    .is_err()
            );
        }
        assert_eq!(out, [0u8; 16]);
        let mut short = [0u8; 9];
        let req = SdoRequest::UploadSegment { toggle: false };
        assert!(matches!(
            req.emit(&mut SdoFrame::new_unchecked(&mut short[..])),
            Err(WireError::BufferTooSmall { .. })
        ));
        assert_eq!(short, [0u8; 9]);
    }

    fn arb_bytes(min: usize, max: usize) -> impl Strategy<Value = Vec<u8>> {
        proptest::collection::vec(any::<u8>(), min..max)
    }

    /// Payload kind, complete-size slack and bytes; the borrowed payload is built in the test.
    pub(crate) fn arb_payload_parts() -> impl Strategy<Value = (u8, u32, Vec<u8>)> {
        (0u8..3, 0u32..1000, arb_bytes(1, 40)).prop_map(|(kind, slack, mut bytes)| {
            if kind == 0 {
                bytes.truncate(4);
            }
            (kind, slack, bytes)
        })
    }

    pub(crate) fn payload_from(kind: u8, slack: u32, bytes: &[u8]) -> SdoPayload<'_> {
        match kind {
            0 => SdoPayload::Expedited(bytes),
            1 => SdoPayload::Normal {
                complete_size: bytes.len() as u32 + slack,
                data: bytes,
            },
            _ => SdoPayload::SizeUnspecified { data: bytes },
        }
    }

    proptest! {
        #[test]
        fn round_trip(
            which in 0u8..5,
            index in any::<u16>(),
            subindex in any::<u8>(),
            flag in any::<bool>(),
            flag2 in any::<bool>(),
            (kind, slack, bytes) in arb_payload_parts(),
            seg in arb_bytes(0, 40),
            code in any::<u32>(),
        ) {
            let req = match which {
                0 => SdoRequest::InitiateDownload {
                    index, subindex, complete_access: flag,
                    payload: payload_from(kind, slack, &bytes),
                },
                1 => SdoRequest::DownloadSegment { toggle: flag, last: flag2, data: &seg },
                2 => SdoRequest::InitiateUpload { index, subindex, complete_access: flag },
                3 => SdoRequest::UploadSegment { toggle: flag },
                _ => SdoRequest::Abort { index, subindex, code: AbortCode::from(code) },
            };
            let out = emit(&req);
            prop_assert_eq!(out.len(), req.buffer_len());
            prop_assert_eq!(parse(&out).unwrap(), req);
        }

        #[test]
        fn never_panics(bytes in arb_bytes(0, 40)) {
            if let Ok(frame) = SdoFrame::new_checked(&bytes[..])
                && let Ok(req) = SdoRequest::parse(&frame) {
                    let _ = req.to_string();
                }
        }
    }
}
