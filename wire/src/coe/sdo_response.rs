//! SDO responses, server → client (CoE service 3; ETG.1000.6, spec-notes §coe.sdo).
//!
//! The same command byte means something else here than in a request (0x60 is an initiate
//! download response here, an upload segment request there); the CoE service decides.

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

const WHAT: &str = "SDO response";

/// Server command specifiers (bits 5-7 of the command byte in service 3).
mod scs {
    pub const UPLOAD_SEGMENT: u8 = 0;
    pub const DOWNLOAD_SEGMENT: u8 = 1;
    pub const INITIATE_UPLOAD: u8 = 2;
    pub const INITIATE_DOWNLOAD: u8 = 3;
    pub const ABORT: u8 = 4;
}

/// An SDO response (every form a server sends).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SdoResponse<'a> {
    /// Initiate download response: 0x60 (0x70 when the server echoes complete access).
    InitiateDownload {
        /// Object index (echoed).
        index: u16,
        /// Subindex (echoed).
        subindex: u8,
        /// Complete access echoed in bit 4 (SOES does; the standard reserves the bit).
        complete_access: bool,
    },
    /// Download segment response: 0x20 | toggle.
    DownloadSegment {
        /// Toggle bit, echo of the request's.
        toggle: bool,
    },
    /// Initiate upload response: 0x43/0x47/0x4B/0x4F expedited, 0x41 normal.
    InitiateUpload {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Complete access (bit 4).
        complete_access: bool,
        /// The value or its first part.
        payload: SdoPayload<'a>,
    },
    /// Upload segment response: toggle (bit 4), unused count (bits 1-3), last (bit 0).
    UploadSegment {
        /// Toggle bit, echo of the request's.
        toggle: bool,
        /// No more segments follow.
        last: bool,
        /// Segment data.
        data: &'a [u8],
    },
    /// Abort transfer: 0x80 (how a server refuses any request).
    Abort {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Why.
        code: AbortCode,
    },
}

impl<'a> SdoResponse<'a> {
    /// Parses an SDO response from mailbox data (CoE header included; service must be 3).
    /// Reserved command bits and reserved bytes are ignored.
    pub fn parse(frame: &SdoFrame<&'a [u8]>) -> Result<Self> {
        frame.check_len()?;
        expect_service(
            "CoE service of an SDO response",
            frame,
            CoeService::SdoResponse,
        )?;
        let command = frame.command();
        let complete_access = command & cmd::COMPLETE_ACCESS != 0;
        let toggle = command & cmd::TOGGLE != 0;
        Ok(match frame.specifier() {
            scs::INITIATE_DOWNLOAD => SdoResponse::InitiateDownload {
                index: frame.index(),
                subindex: frame.subindex(),
                complete_access,
            },
            scs::DOWNLOAD_SEGMENT => SdoResponse::DownloadSegment { toggle },
            scs::INITIATE_UPLOAD => SdoResponse::InitiateUpload {
                index: frame.index(),
                subindex: frame.subindex(),
                complete_access,
                payload: SdoPayload::decode(WHAT, frame)?,
            },
            scs::UPLOAD_SEGMENT => SdoResponse::UploadSegment {
                toggle,
                last: command & cmd::LAST != 0,
                data: frame.segment_data_ref(),
            },
            scs::ABORT => {
                let (index, subindex, code) = frame.abort_fields()?;
                SdoResponse::Abort {
                    index,
                    subindex,
                    code,
                }
            }
            other => {
                return Err(WireError::UnknownType {
                    what: "SDO response command specifier",
                    value: u32::from(other),
                });
            }
        })
    }

    /// Mailbox length of the response (CoE header included).
    pub fn buffer_len(&self) -> usize {
        match self {
            SdoResponse::InitiateUpload { payload, .. } => payload.frame_len(),
            SdoResponse::UploadSegment { data, .. } => segment_len(data.len()),
            _ => SDO_INITIATE_LEN,
        }
    }

    /// Writes the response (CoE header included) into the first `buffer_len()` bytes, with
    /// the same padding and refusals as [`super::sdo_request::SdoRequest::emit`].
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, frame: &mut SdoFrame<T>) -> Result<()> {
        if let SdoResponse::InitiateUpload { payload, .. } = self {
            payload.validate(WHAT)?;
        }
        let len = self.buffer_len();
        let buf = frame.buffer_mut();
        room(WHAT, buf, len)?;
        let buf = &mut buf[..len];
        let svc = CoeService::SdoResponse;
        let ca = |on: bool| if on { cmd::COMPLETE_ACCESS } else { 0 };
        let tg = |on: bool| if on { cmd::TOGGLE } else { 0 };
        match *self {
            SdoResponse::InitiateDownload {
                index,
                subindex,
                complete_access,
            } => {
                let command =
                    (scs::INITIATE_DOWNLOAD << cmd::SPECIFIER_SHIFT) | ca(complete_access);
                write_initiate(buf, svc, command, index, subindex, [0; 4], &[]);
            }
            SdoResponse::DownloadSegment { toggle } => {
                write_bare(
                    buf,
                    svc,
                    (scs::DOWNLOAD_SEGMENT << cmd::SPECIFIER_SHIFT) | tg(toggle),
                );
            }
            SdoResponse::InitiateUpload {
                index,
                subindex,
                complete_access,
                payload,
            } => {
                let command = (scs::INITIATE_UPLOAD << cmd::SPECIFIER_SHIFT)
                    | ca(complete_access)
                    | payload.command_bits();
                let (field, data) = payload.field_and_data();
                write_initiate(buf, svc, command, index, subindex, field, data);
            }
            SdoResponse::UploadSegment { toggle, last, data } => {
                let command = (scs::UPLOAD_SEGMENT << cmd::SPECIFIER_SHIFT)
                    | tg(toggle)
                    | if last { cmd::LAST } else { 0 };
                write_segment(buf, svc, command, data);
            }
            SdoResponse::Abort {
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

impl fmt::Display for SdoResponse<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ca = |on: bool| if on { " CA" } else { "" };
        match self {
            SdoResponse::InitiateDownload {
                index,
                subindex,
                complete_access,
            } => write!(
                f,
                "CoE SDO download rsp {}{}",
                ObjAddr(*index, *subindex),
                ca(*complete_access)
            ),
            SdoResponse::DownloadSegment { toggle } => {
                write!(
                    f,
                    "CoE SDO download segment rsp toggle {}",
                    u8::from(*toggle)
                )
            }
            SdoResponse::InitiateUpload {
                index,
                subindex,
                complete_access,
                payload,
            } => write!(
                f,
                "CoE SDO upload rsp {}{} {payload}",
                ObjAddr(*index, *subindex),
                ca(*complete_access)
            ),
            SdoResponse::UploadSegment { toggle, last, data } => write!(
                f,
                "CoE SDO upload segment rsp toggle {}{} {} bytes {}",
                u8::from(*toggle),
                if *last { " last" } else { "" },
                data.len(),
                Hex(data)
            ),
            SdoResponse::Abort {
                index,
                subindex,
                code,
            } => write!(f, "CoE SDO abort {} {code}", ObjAddr(*index, *subindex)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coe::sdo_request::tests::{arb_payload_parts, payload_from};
    use crate::mailbox::{HEADER_LEN, Mailbox, MailboxHeader, MailboxType};
    use proptest::prelude::*;

    fn parse(data: &[u8]) -> Result<SdoResponse<'_>> {
        SdoResponse::parse(&SdoFrame::new_checked(data)?)
    }

    fn emit(rsp: &SdoResponse<'_>) -> Vec<u8> {
        let mut out = vec![0xa5u8; rsp.buffer_len()];
        rsp.emit(&mut SdoFrame::new_unchecked(&mut out[..]))
            .unwrap();
        out
    }

    fn download_ack(index: u16, subindex: u8) -> SdoResponse<'static> {
        SdoResponse::InitiateDownload {
            index,
            subindex,
            complete_access: false,
        }
    }

    // The worked upload response (ETG.1000.6, spec-notes §coe.sdo), read from SM1.
    static C6_RESPONSE: [u8; 16] = [
        0x0a, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x30, 0x43, 0x18, 0x10, 0x01, 0x02, 0x00, 0x00,
        0x00,
    ];

    #[test]
    fn c6_upload_response() {
        let mbx = Mailbox::new_checked(&C6_RESPONSE[..]).unwrap();
        let header = MailboxHeader::parse(&mbx).unwrap();
        assert_eq!((header.mailbox_type, header.counter), (MailboxType::Coe, 1));
        let rsp = parse(mbx.data()).unwrap();
        let expected = SdoResponse::InitiateUpload {
            index: 0x1018,
            subindex: 1,
            complete_access: false,
            payload: SdoPayload::Expedited(&[0x02, 0x00, 0x00, 0x00]),
        };
        assert_eq!(rsp, expected);
        assert_eq!(
            rsp.to_string(),
            "CoE SDO upload rsp 0x1018:01 expedited 4 bytes [02 00 00 00]"
        );
        let mut out = [0xa5u8; 16];
        let mut mbx = Mailbox::new_unchecked(&mut out[..]);
        header.emit(&mut mbx).unwrap();
        expected
            .emit(&mut SdoFrame::new_unchecked(mbx.data_mut()))
            .unwrap();
        assert_eq!(out, C6_RESPONSE);
    }

    #[test]
    fn c7_download_responses() {
        // `00 30 | 60 12 1c ss | 00 00 00 00` for ss = 00, 01, 00.
        for ss in [0u8, 1, 0] {
            let bytes = [0x00, 0x30, 0x60, 0x12, 0x1c, ss, 0, 0, 0, 0];
            assert_eq!(parse(&bytes).unwrap(), download_ack(0x1C12, ss));
            assert_eq!(emit(&download_ack(0x1C12, ss)), bytes);
        }
        assert_eq!(
            download_ack(0x1C12, 1).to_string(),
            "CoE SDO download rsp 0x1C12:01"
        );
    }

    #[test]
    fn c8_abort() {
        let bytes = [
            0x0a, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x30, 0x80, 0x00, 0x20, 0x00, 0x00, 0x00,
            0x02, 0x06,
        ];
        let mbx = Mailbox::new_checked(&bytes[..]).unwrap();
        let rsp = parse(mbx.data()).unwrap();
        let expected = SdoResponse::Abort {
            index: 0x2000,
            subindex: 0,
            code: AbortCode::ObjectDoesNotExist,
        };
        assert_eq!(rsp, expected);
        assert_eq!(emit(&expected), bytes[HEADER_LEN..]);
        assert_eq!(
            rsp.to_string(),
            "CoE SDO abort 0x2000:00 0x06020000 Object does not exist in the object dictionary"
        );
    }

    #[test]
    fn c9_responses() {
        // Initiate response `00 30 | 60 00 80 00 00 00 00 00`.
        let bytes = [0x00, 0x30, 0x60, 0x00, 0x80, 0x00, 0, 0, 0, 0];
        assert_eq!(parse(&bytes).unwrap(), download_ack(0x8000, 0));
        assert_eq!(emit(&download_ack(0x8000, 0)), bytes);
        // Segment response `00 30 | 20 00 00 00 00 00 00 00`, toggle 0.
        let bytes = [0x00, 0x30, 0x20, 0, 0, 0, 0, 0, 0, 0];
        let rsp = SdoResponse::DownloadSegment { toggle: false };
        assert_eq!(parse(&bytes).unwrap(), rsp);
        assert_eq!(emit(&rsp), bytes);
        assert_eq!(rsp.to_string(), "CoE SDO download segment rsp toggle 0");
        // Toggle 1: 0x30.
        let rsp = SdoResponse::DownloadSegment { toggle: true };
        assert_eq!(emit(&rsp)[2], 0x30);
    }

    #[test]
    fn segmented_upload() {
        // 0x1008 name of 20 bytes, M = 24: 8 bytes in the initiate response (0x41, size 20),
        // then segments of up to 15 bytes: 12 remain → one last segment of 12 bytes.
        let name = b"ecatd simulated dev!";
        let initiate = [
            0x00, 0x30, 0x41, 0x08, 0x10, 0x00, 0x14, 0x00, 0x00, 0x00, b'e', b'c', b'a', b't',
            b'd', b' ', b's', b'i',
        ];
        let rsp = SdoResponse::InitiateUpload {
            index: 0x1008,
            subindex: 0,
            complete_access: false,
            payload: SdoPayload::Normal {
                complete_size: 20,
                data: &name[..8],
            },
        };
        assert_eq!(parse(&initiate).unwrap(), rsp);
        assert_eq!(emit(&rsp), initiate);
        assert_eq!(rsp.buffer_len(), 10 + 8);

        // Segment response, toggle 0, last, 12 bytes: cmd 0x01, length 3 + 12 = 15.
        let mut seg = vec![0x00, 0x30, 0x01];
        seg.extend_from_slice(&name[8..]);
        let rsp = SdoResponse::UploadSegment {
            toggle: false,
            last: true,
            data: &name[8..],
        };
        assert_eq!(parse(&seg).unwrap(), rsp);
        assert_eq!(emit(&rsp), seg);

        // A not-last segment with toggle 1 and 7 bytes: cmd 0x10, length 10.
        let bytes = [0x00, 0x30, 0x10, 1, 2, 3, 4, 5, 6, 7];
        let rsp = SdoResponse::UploadSegment {
            toggle: true,
            last: false,
            data: &[1, 2, 3, 4, 5, 6, 7],
        };
        assert_eq!(parse(&bytes).unwrap(), rsp);
        assert_eq!(emit(&rsp), bytes);

        // Last segment with toggle 1 and 3 bytes: cmd 0x10 | (7-3)<<1 | 1 = 0x19, padded.
        let bytes = [0x00, 0x30, 0x19, 0xaa, 0xbb, 0xcc, 0, 0, 0, 0];
        let rsp = SdoResponse::UploadSegment {
            toggle: true,
            last: true,
            data: &[0xaa, 0xbb, 0xcc],
        };
        assert_eq!(parse(&bytes).unwrap(), rsp);
        assert_eq!(emit(&rsp), bytes);
        assert_eq!(
            rsp.to_string(),
            "CoE SDO upload segment rsp toggle 1 last 3 bytes [aa bb cc]"
        );
    }

    #[test]
    fn expedited_upload_sizes() {
        // 0x4F / 0x4B / 0x47: 1 / 2 / 3 bytes.
        for (command, n) in [(0x4F, 1usize), (0x4B, 2), (0x47, 3), (0x43, 4)] {
            let bytes = [0x00, 0x30, command, 0x00, 0x10, 0x00, 1, 2, 3, 4];
            let value = [1u8, 2, 3, 4];
            let expected = SdoResponse::InitiateUpload {
                index: 0x1000,
                subindex: 0,
                complete_access: false,
                payload: SdoPayload::Expedited(&value[..n]),
            };
            assert_eq!(parse(&bytes).unwrap(), expected);
            let mut padded = bytes;
            padded[6 + n..].fill(0);
            assert_eq!(emit(&expected), padded);
        }
        // 0x42: expedited, size not indicated → all 4 bytes.
        let bytes = [0x00, 0x30, 0x42, 0x00, 0x10, 0x00, 1, 2, 3, 4];
        assert!(matches!(
            parse(&bytes).unwrap(),
            SdoResponse::InitiateUpload {
                payload: SdoPayload::Expedited(&[1, 2, 3, 4]),
                ..
            }
        ));
    }

    #[test]
    fn errors() {
        // A request service is refused.
        assert!(matches!(
            parse(&[0x00, 0x20, 0x60, 0x00, 0x80, 0x00, 0, 0, 0, 0]),
            Err(WireError::UnknownType { value: 2, .. })
        ));
        assert!(matches!(
            parse(&[0x00, 0x30, 0xa0, 0x00, 0x80, 0x00, 0, 0, 0, 0]),
            Err(WireError::UnknownType { value: 5, .. })
        ));
        assert!(parse(&[0x00, 0x30, 0x80, 0x00, 0x80, 0x00, 0, 0]).is_err());
        let mut out = [0u8; 12];
        let bad = SdoResponse::InitiateUpload {
            index: 0,
            subindex: 0,
            complete_access: false,
            payload: SdoPayload::Expedited(&[]),
        };
        assert!(
            bad.emit(&mut SdoFrame::new_unchecked(&mut out[..]))
                .is_err()
        );
        assert_eq!(out, [0u8; 12]);
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
            seg in proptest::collection::vec(any::<u8>(), 0..40),
            code in any::<u32>(),
        ) {
            let rsp = match which {
                0 => SdoResponse::InitiateDownload { index, subindex, complete_access: flag },
                1 => SdoResponse::DownloadSegment { toggle: flag },
                2 => SdoResponse::InitiateUpload {
                    index, subindex, complete_access: flag,
                    payload: payload_from(kind, slack, &bytes),
                },
                3 => SdoResponse::UploadSegment { toggle: flag, last: flag2, data: &seg },
                _ => SdoResponse::Abort { index, subindex, code: AbortCode::from(code) },
            };
            let out = emit(&rsp);
            prop_assert_eq!(out.len(), rsp.buffer_len());
            prop_assert_eq!(parse(&out).unwrap(), rsp);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
            if let Ok(frame) = SdoFrame::new_checked(&bytes[..])
                && let Ok(rsp) = SdoResponse::parse(&frame) {
                    let _ = rsp.to_string();
                }
        }
    }
}
