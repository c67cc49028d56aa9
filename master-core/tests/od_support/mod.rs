//! Shared by the `od_*` tests (included with `#[path]`): a test dictionary and a small SDO
//! client that builds requests and reads replies only through the wire codecs.
#![allow(dead_code)]

use master_core::od::access::presets::{RO_TX, RW_PREOP, RW_RX, WO};
use master_core::od::{
    Identity, Outcome, PdoEntry, SdoServer, ServerContext, SmType, StaticDictionary,
};
use master_core::wire::Emit;
use master_core::wire::coe::info::{SdoInfoFrame, SdoInfoRepr, SdoInfoService};
use master_core::wire::coe::sdo::SdoFrame;
use master_core::wire::coe::sdo_payload::SdoPayload;
use master_core::wire::coe::sdo_request::SdoRequest;
use master_core::wire::coe::sdo_response::SdoResponse;
use master_core::wire::coe::{
    AbortCode, CoeFrame, CoeRepr, DataType, ObjectAccess, max_initiate_data, max_segment_data,
};
use master_core::wire::register::AlState;

/// Identity values of the test dictionary.
pub const VENDOR: u32 = 0x0000_0002;
/// Product code of the test dictionary.
pub const PRODUCT: u32 = 0x07D4_3052;
/// Revision of the test dictionary.
pub const REVISION: u32 = 0x0011_0000;
/// Serial number of the test dictionary.
pub const SERIAL: u32 = 0x1234_5678;

/// Index of the 4 KiB DOMAIN.
pub const BLOB: u16 = 0x2020;
/// Index of the 100-byte OCTET_STRING.
pub const OCTETS: u16 = 0x2010;

/// The dictionary most tests use.
pub fn test_dictionary() -> StaticDictionary {
    StaticDictionary::builder()
        .device_type(0x0001_0192)
        .device_name("ecatd test slave")
        .hardware_version("01")
        .software_version("1.2.3")
        .identity(Identity {
            vendor_id: VENDOR,
            product_code: PRODUCT,
            revision: REVISION,
            serial: SERIAL,
        })
        .var(
            0x2001,
            "u8 value",
            DataType::Unsigned8,
            ObjectAccess::RW,
            0x11u8,
        )
        .var(
            0x2002,
            "u16 value",
            DataType::Unsigned16,
            ObjectAccess::RW,
            0x2222u16,
        )
        .var(
            0x2003,
            "u24 value",
            DataType::Unsigned24,
            ObjectAccess::RW,
            0x33_3333u32,
        )
        .var(
            0x2004,
            "u32 value",
            DataType::Unsigned32,
            ObjectAccess::RW,
            0x4444_4444u32,
        )
        .var(
            0x2005,
            "Limited",
            DataType::Integer16,
            ObjectAccess::RW,
            5i16,
        )
        .range(-100i16, 100i16)
        .default_value(5i16)
        .unit(0x00_01_00_00)
        .bytes(
            OCTETS,
            "Octets",
            DataType::OctetString,
            ObjectAccess::RW,
            vec![0; 100],
            100,
        )
        .bytes(
            BLOB,
            "Blob",
            DataType::Domain,
            ObjectAccess::RW,
            vec![0xEE; 4096],
            4096,
        )
        .var(
            0x2030,
            "Read only",
            DataType::Unsigned32,
            ObjectAccess::RO,
            7u32,
        )
        .var(0x2031, "Write only", DataType::Unsigned32, WO, 0u32)
        .var(0x2032, "PREOP only", DataType::Unsigned16, RW_PREOP, 0u16)
        .var(
            0x2033,
            "u64 value",
            DataType::Unsigned64,
            ObjectAccess::RW,
            1u64,
        )
        .record(0x2040, "With gap", |r| {
            r.entry(
                1,
                "First",
                DataType::Unsigned16,
                ObjectAccess::RW,
                0x0101u16,
            )
            .entry(
                2,
                "Second",
                DataType::Unsigned32,
                ObjectAccess::RW,
                0x0202_0202u32,
            )
            .entry(4, "Fourth", DataType::Unsigned8, ObjectAccess::RW, 4u8)
        })
        .record(0x2050, "Bits", |r| {
            r.entry(1, "Flag A", DataType::Boolean, ObjectAccess::RW, true)
                .entry(2, "Flag B", DataType::Boolean, ObjectAccess::RW, false)
                .entry(3, "Two bits", DataType::Bit2, ObjectAccess::RW, 2u8)
                .entry(4, "Byte", DataType::Unsigned8, ObjectAccess::RW, 0xABu8)
                .entry(5, "Flag C", DataType::Boolean, ObjectAccess::RO, true)
        })
        .record(0x2060, "With string", |r| {
            r.entry(1, "Number", DataType::Unsigned8, ObjectAccess::RW, 1u8)
                .string(2, "Text", ObjectAccess::RW, "abc", 16)
        })
        .var(0x6000, "Input", DataType::Unsigned16, RO_TX, 0x6000u16)
        .var(0x7000, "Output", DataType::Unsigned16, RW_RX, 0u16)
        .pdo_mapping(0x1600, "RxPDO 1", &[PdoEntry::new(0x7000, 0, 16)], 8)
        .pdo_mapping(0x1A00, "TxPDO 1", &[PdoEntry::new(0x6000, 0, 16)], 8)
        .rx_pdo_assign(&[0x1600], 4)
        .tx_pdo_assign(&[0x1A00], 4)
        .sm_types(&[
            SmType::MailboxOut,
            SmType::MailboxIn,
            SmType::Outputs,
            SmType::Inputs,
        ])
        .build()
        .expect("test dictionary")
}

/// Emits an SDO request through the codec.
pub fn sdo_bytes(req: &SdoRequest<'_>) -> Vec<u8> {
    req.to_vec().expect("request emits")
}

/// Emits an SDO Info request through the codec.
pub fn info_bytes(service: SdoInfoService<'_>) -> Vec<u8> {
    let repr = SdoInfoRepr {
        incomplete: false,
        fragments_left: 0,
        service,
    };
    repr.to_vec().expect("info request emits")
}

/// Parses a reply as an SDO response.
pub fn sdo_reply(bytes: &[u8]) -> SdoResponse<'_> {
    SdoResponse::parse(&SdoFrame::new_checked(bytes).expect("SDO frame")).expect("SDO response")
}

/// Parses a reply as an SDO Info message.
pub fn info_reply(bytes: &[u8]) -> SdoInfoRepr<'_> {
    SdoInfoRepr::parse(&SdoInfoFrame::new_checked(bytes).expect("info frame")).expect("info")
}

/// A server, its dictionary and a mailbox configuration, driven like a master would.
pub struct Client {
    /// The server under test.
    pub server: SdoServer,
    /// Its dictionary.
    pub dict: StaticDictionary,
    /// Mailbox sizes and AL state passed with every request.
    pub ctx: ServerContext,
}

impl Client {
    /// The test dictionary behind mailboxes of `mailbox_size` bytes, in PREOP.
    pub fn new(mailbox_size: usize) -> Self {
        Self::with(test_dictionary(), mailbox_size)
    }

    /// `dict` behind mailboxes of `mailbox_size` bytes, in PREOP.
    pub fn with(dict: StaticDictionary, mailbox_size: usize) -> Self {
        Client {
            server: SdoServer::new(),
            dict,
            ctx: ServerContext::new(mailbox_size, AlState::PreOp),
        }
    }

    /// The same client in another AL state.
    pub fn state(mut self, state: AlState) -> Self {
        self.ctx.state = state;
        self
    }

    /// Sends raw CoE mailbox data; returns the replies, checking that each fits SM1,
    /// parses with the CoE codec, and that the outcome counts them.
    pub fn raw(&mut self, request: &[u8]) -> Vec<Vec<u8>> {
        let mut replies = Vec::new();
        let outcome = self
            .server
            .handle(&mut self.dict, request, self.ctx, &mut |r: &[u8]| {
                replies.push(r.to_vec())
            });
        for r in &replies {
            assert!(r.len() + 6 <= self.ctx.mailbox_size, "reply exceeds SM1");
            CoeRepr::parse(&CoeFrame::new_checked(&r[..]).unwrap()).expect("reply parses");
        }
        if let Outcome::Replied(n) = outcome {
            assert_eq!(n, replies.len());
        } else {
            assert!(replies.is_empty());
        }
        replies
    }

    /// Sends an SDO request and expects exactly one reply.
    pub fn one(&mut self, req: &SdoRequest<'_>) -> Vec<u8> {
        let mut replies = self.raw(&sdo_bytes(req));
        assert_eq!(replies.len(), 1, "one reply to {req}");
        replies.remove(0)
    }

    /// Sends a request and returns the abort code of its reply (panics if not an abort).
    pub fn abort_of(&mut self, req: &SdoRequest<'_>) -> AbortCode {
        let reply = self.one(req);
        match sdo_reply(&reply) {
            SdoResponse::Abort { code, .. } => code,
            other => panic!("expected an abort for {req}, got {other}"),
        }
    }

    /// A complete upload as a master does it (expedited, normal or segmented).
    pub fn upload(
        &mut self,
        index: u16,
        subindex: u8,
        complete_access: bool,
    ) -> Result<Vec<u8>, AbortCode> {
        let reply = self.one(&SdoRequest::InitiateUpload {
            index,
            subindex,
            complete_access,
        });
        let (size, mut data) = match sdo_reply(&reply) {
            SdoResponse::Abort { code, .. } => return Err(code),
            SdoResponse::InitiateUpload {
                index: i,
                subindex: s,
                complete_access: ca,
                payload,
            } => {
                assert_eq!((i, s, ca), (index, subindex, complete_access));
                match payload {
                    SdoPayload::Expedited(v) => return Ok(v.to_vec()),
                    SdoPayload::Normal {
                        complete_size,
                        data,
                    } => {
                        assert!(data.len() <= max_initiate_data(self.ctx.mailbox_size));
                        (complete_size as usize, data.to_vec())
                    }
                    other => panic!("unexpected payload {other}"),
                }
            }
            other => panic!("unexpected reply {other}"),
        };
        let mut toggle = false;
        while data.len() < size {
            let reply = self.one(&SdoRequest::UploadSegment { toggle });
            match sdo_reply(&reply) {
                SdoResponse::UploadSegment {
                    toggle: t,
                    last,
                    data: seg,
                } => {
                    assert_eq!(t, toggle);
                    assert!(seg.len() <= max_segment_data(self.ctx.mailbox_size));
                    data.extend_from_slice(seg);
                    assert_eq!(last, data.len() == size, "last bit at the end only");
                }
                SdoResponse::Abort { code, .. } => return Err(code),
                other => panic!("unexpected reply {other}"),
            }
            toggle = !toggle;
        }
        Ok(data)
    }

    /// A complete download as a master does it: expedited for 1-4 bytes (unless complete
    /// access or `force_normal`), else normal with segments as the SM0 size requires.
    pub fn download(
        &mut self,
        index: u16,
        subindex: u8,
        complete_access: bool,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        let first = data.len().min(max_initiate_data(self.ctx.rx_mailbox_size));
        let payload = if (1..=4).contains(&data.len()) && !complete_access {
            SdoPayload::Expedited(data)
        } else {
            SdoPayload::Normal {
                complete_size: data.len() as u32,
                data: &data[..first],
            }
        };
        let reply = self.one(&SdoRequest::InitiateDownload {
            index,
            subindex,
            complete_access,
            payload,
        });
        match sdo_reply(&reply) {
            SdoResponse::InitiateDownload {
                index: i,
                subindex: s,
                ..
            } => assert_eq!((i, s), (index, subindex)),
            SdoResponse::Abort { code, .. } => return Err(code),
            other => panic!("unexpected reply {other}"),
        }
        if matches!(payload, SdoPayload::Expedited(_)) {
            return Ok(());
        }
        let mut sent = first;
        let mut toggle = false;
        let per_segment = max_segment_data(self.ctx.rx_mailbox_size);
        while sent < data.len() {
            let n = (data.len() - sent).min(per_segment);
            let last = sent + n == data.len();
            let reply = self.one(&SdoRequest::DownloadSegment {
                toggle,
                last,
                data: &data[sent..sent + n],
            });
            match sdo_reply(&reply) {
                SdoResponse::DownloadSegment { toggle: t } => assert_eq!(t, toggle),
                SdoResponse::Abort { code, .. } => return Err(code),
                other => panic!("unexpected reply {other}"),
            }
            sent += n;
            toggle = !toggle;
        }
        Ok(())
    }

    /// Sends an SDO Info request and returns the replies.
    pub fn info(&mut self, service: SdoInfoService<'_>) -> Vec<Vec<u8>> {
        self.raw(&info_bytes(service))
    }
}
