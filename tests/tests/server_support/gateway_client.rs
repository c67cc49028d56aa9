//! A plain UDP client of ecatd's ETG.8200 gateway for the server tests: messages built and
//! parsed with `master_core::wire` (never by hand), every receive with a deadline.

use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use master_core::wire::Emit;
use master_core::wire::coe::info::{
    EntryDescription, ObjectDescription, OdList, OdListType, SdoInfoOpcode, ValueInfo,
};
use master_core::wire::coe::{
    AbortCode, CoeFrame, CoeRepr, CoeService, DataType, ObjectAccess, ObjectCode, SdoInfoFrame,
    SdoInfoRepr, SdoInfoService, SdoPayload, SdoRequest, SdoResponse, max_initiate_data,
    max_segment_data,
};
use master_core::wire::gateway::{GatewayMessage, GatewayRepr};
use master_core::wire::mailbox::{MailboxHeader, MailboxType};

/// How long a reply may take (the gateway's own request timeout is 5 s).
pub const REPLY_DEADLINE: Duration = Duration::from_secs(10);

/// One reply datagram: its mailbox header and data.
#[derive(Debug, Clone)]
pub struct Reply {
    /// The mailbox header (address: the one the request used, or the slave's station on a
    /// broadcast).
    pub header: MailboxHeader,
    /// The mailbox data.
    pub data: Vec<u8>,
}

impl Reply {
    /// The reply as CoE (panics if it is not CoE: test input).
    pub fn coe(&self) -> CoeRepr<'_> {
        assert_eq!(
            self.header.mailbox_type,
            MailboxType::Coe,
            "not a CoE reply: {self:?}"
        );
        let frame = CoeFrame::new_checked(&self.data[..]).expect("a CoE frame");
        CoeRepr::parse(&frame).expect("parsable CoE")
    }
}

/// The mailbox data of a CoE message.
pub fn coe_bytes(repr: &CoeRepr) -> Vec<u8> {
    repr.to_vec().expect("emit CoE")
}

/// An ETG.8200 datagram carrying `data` of type `ty` for `address`.
pub fn datagram(address: u16, ty: MailboxType, counter: u8, data: &[u8]) -> Vec<u8> {
    let repr = GatewayRepr {
        header: MailboxHeader {
            length: u16::try_from(data.len()).expect("mailbox length"),
            address,
            channel: 0,
            priority: 0,
            mailbox_type: ty,
            counter,
        },
        data,
    };
    repr.to_vec().expect("emit gateway message")
}

/// A UDP socket talking to one gateway.
pub struct GatewayClient {
    /// The socket (bound to a free loopback port).
    pub socket: UdpSocket,
    /// The gateway's address.
    pub server: SocketAddr,
    counter: u8,
}

impl GatewayClient {
    /// A client of the gateway at `server`.
    pub fn new(server: SocketAddr) -> GatewayClient {
        GatewayClient::from_host(Ipv4Addr::LOCALHOST, server)
    }

    /// A client on loopback address `host` (any of 127.0.0.0/8): the gateway's in-flight
    /// cap counts per host, so clients that stand for separate machines take separate
    /// addresses.
    pub fn from_host(host: Ipv4Addr, server: SocketAddr) -> GatewayClient {
        GatewayClient {
            socket: UdpSocket::bind((host, 0)).expect("client socket"),
            server,
            counter: 0,
        }
    }

    /// Sends one message (the mailbox counter cycles 1..=7).
    pub fn send(&mut self, address: u16, ty: MailboxType, data: &[u8]) {
        self.counter = self.counter % 7 + 1;
        let bytes = datagram(address, ty, self.counter, data);
        self.send_raw(&bytes);
    }

    /// Sends bytes as they are (malformed datagrams).
    pub fn send_raw(&self, bytes: &[u8]) {
        self.socket.send_to(bytes, self.server).expect("send");
    }

    /// The next reply within `wait`, or `None`. Panics on a datagram from elsewhere or one
    /// that is not an ETG.8200 message.
    pub fn recv_within(&self, wait: Duration) -> Option<Reply> {
        let deadline = Instant::now() + wait;
        let mut buf = [0u8; 2048];
        let left = deadline.saturating_duration_since(Instant::now());
        self.socket
            .set_read_timeout(Some(left.max(Duration::from_millis(1))))
            .expect("timeout");
        let (len, from) = match self.socket.recv_from(&mut buf) {
            Ok(got) => got,
            Err(err)
                if matches!(
                    err.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                return None;
            }
            Err(err) => panic!("recv: {err}"),
        };
        assert_eq!(from, self.server, "a reply from the gateway's socket");
        let message = GatewayMessage::new_checked(&buf[..len]).expect("a gateway message");
        let repr = GatewayRepr::parse(&message).expect("parsable");
        Some(Reply {
            header: repr.header,
            data: repr.data.to_vec(),
        })
    }

    /// The next reply (panics after [`REPLY_DEADLINE`]).
    pub fn recv(&self) -> Reply {
        self.recv_within(REPLY_DEADLINE)
            .expect("a reply within the deadline")
    }

    /// Sends one message and returns the reply.
    pub fn exchange(&mut self, address: u16, ty: MailboxType, data: &[u8]) -> Reply {
        self.send(address, ty, data);
        self.recv()
    }

    /// Sends one CoE message and returns the reply.
    pub fn coe(&mut self, address: u16, repr: &CoeRepr) -> Reply {
        self.exchange(address, MailboxType::Coe, &coe_bytes(repr))
    }

    /// SDO upload (expedited, normal or segmented): the value, or the abort code.
    pub fn sdo_upload(&mut self, address: u16, index: u16, subindex: u8) -> Result<Vec<u8>, u32> {
        self.sdo_upload_with(address, index, subindex, false)
    }

    /// SDO upload, with complete access when `complete_access` (from `subindex` 0 or 1):
    /// the value, or the abort code. A normal upload must bring exactly the announced size.
    pub fn sdo_upload_with(
        &mut self,
        address: u16,
        index: u16,
        subindex: u8,
        complete_access: bool,
    ) -> Result<Vec<u8>, u32> {
        let reply = self.coe(
            address,
            &CoeRepr::SdoRequest(SdoRequest::InitiateUpload {
                index,
                subindex,
                complete_access,
            }),
        );
        let (mut value, size) = match reply.coe() {
            CoeRepr::SdoResponse(SdoResponse::InitiateUpload { payload, .. }) => match payload {
                SdoPayload::Expedited(v) => return Ok(v.to_vec()),
                SdoPayload::Normal {
                    complete_size,
                    data,
                } => (data.to_vec(), complete_size as usize),
                SdoPayload::SizeUnspecified { data } => (data.to_vec(), usize::MAX),
            },
            CoeRepr::SdoResponse(SdoResponse::Abort { code, .. }) => return Err(u32::from(code)),
            other => panic!("unexpected answer {other:?}"),
        };
        let mut toggle = false;
        // Bounded: one segment carries at least one byte.
        for _ in 0..=size.min(1 << 24) {
            if value.len() >= size {
                break;
            }
            let reply = self.coe(
                address,
                &CoeRepr::SdoRequest(SdoRequest::UploadSegment { toggle }),
            );
            match reply.coe() {
                CoeRepr::SdoResponse(SdoResponse::UploadSegment {
                    toggle: echoed,
                    last,
                    data,
                }) => {
                    assert_eq!(echoed, toggle, "toggle echoed");
                    value.extend_from_slice(data);
                    if last {
                        break;
                    }
                }
                CoeRepr::SdoResponse(SdoResponse::Abort { code, .. }) => {
                    return Err(u32::from(code));
                }
                other => panic!("unexpected segment answer {other:?}"),
            }
            toggle = !toggle;
        }
        if size != usize::MAX {
            assert_eq!(
                value.len(),
                size,
                "{index:#06x}:{subindex:02x}: the announced size"
            );
        }
        Ok(value)
    }

    /// SDO download, expedited up to 4 bytes, else normal with segments sized for a
    /// mailbox of `mailbox_size` bytes: `Ok`, or the abort code.
    pub fn sdo_download(
        &mut self,
        address: u16,
        index: u16,
        subindex: u8,
        data: &[u8],
        mailbox_size: usize,
    ) -> Result<(), u32> {
        let first = if data.len() <= 4 {
            data.len()
        } else {
            data.len().min(max_initiate_data(mailbox_size))
        };
        let payload = if data.len() <= 4 {
            SdoPayload::Expedited(data)
        } else {
            SdoPayload::Normal {
                complete_size: u32::try_from(data.len()).expect("size"),
                data: &data[..first],
            }
        };
        let reply = self.coe(
            address,
            &CoeRepr::SdoRequest(SdoRequest::InitiateDownload {
                index,
                subindex,
                complete_access: false,
                payload,
            }),
        );
        match reply.coe() {
            CoeRepr::SdoResponse(SdoResponse::InitiateDownload { .. }) => {}
            CoeRepr::SdoResponse(SdoResponse::Abort { code, .. }) => return Err(u32::from(code)),
            other => panic!("unexpected answer {other:?}"),
        }
        let mut toggle = false;
        for chunk in data[first..].chunks(max_segment_data(mailbox_size)) {
            let last = chunk.as_ptr_range().end == data.as_ptr_range().end;
            let reply = self.coe(
                address,
                &CoeRepr::SdoRequest(SdoRequest::DownloadSegment {
                    toggle,
                    last,
                    data: chunk,
                }),
            );
            match reply.coe() {
                CoeRepr::SdoResponse(SdoResponse::DownloadSegment { toggle: echoed }) => {
                    assert_eq!(echoed, toggle, "toggle echoed");
                }
                CoeRepr::SdoResponse(SdoResponse::Abort { code, .. }) => {
                    return Err(u32::from(code));
                }
                other => panic!("unexpected segment answer {other:?}"),
            }
            toggle = !toggle;
        }
        Ok(())
    }
}

/// Most fragments one SDO Information answer may take (a bound for the receive loop).
const MAX_FRAGMENTS: usize = 4096;

/// What Get Object Description says of an object.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObjectSummary {
    /// The index the answer names.
    pub index: u16,
    /// Data type (of the entries, for an ARRAY).
    pub data_type: DataType,
    /// Highest subindex.
    pub max_subindex: u8,
    /// VAR, ARRAY or RECORD.
    pub object_code: ObjectCode,
    /// The object's name.
    pub name: String,
}

/// What Get Entry Description says of an entry.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EntrySummary {
    /// The index the answer names.
    pub index: u16,
    /// The subindex the answer names.
    pub subindex: u8,
    /// Data type.
    pub data_type: DataType,
    /// Size in bits (the capacity, for strings).
    pub bit_length: u16,
    /// Access word.
    pub access: ObjectAccess,
    /// The entry's name.
    pub name: String,
}

/// An answer to an SDO Information request: the service data of every fragment, in order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InfoAnswer {
    /// The fragments' service data, concatenated.
    pub data: Vec<u8>,
    /// How many datagrams (fragments) it took.
    pub fragments: usize,
}

impl GatewayClient {
    /// One SDO Information request (built with `master_core::wire`): the answer of
    /// `expected` opcode with every fragment collected (no request between fragments; the
    /// fragments-left count must go down by one each time), or the SDO Info Error's code.
    pub fn sdo_info(
        &mut self,
        address: u16,
        service: SdoInfoService<'_>,
        expected: SdoInfoOpcode,
    ) -> Result<InfoAnswer, u32> {
        let request = CoeRepr::SdoInfo(SdoInfoRepr {
            incomplete: false,
            fragments_left: 0,
            service,
        });
        self.send(address, MailboxType::Coe, &coe_bytes(&request));
        let mut data = Vec::new();
        let mut left: Option<u16> = None;
        for fragments in 1..=MAX_FRAGMENTS {
            let reply = self.recv();
            assert_eq!(reply.header.mailbox_type, MailboxType::Coe, "{reply:?}");
            assert_eq!(reply.header.address, address, "{reply:?}");
            let frame = SdoInfoFrame::new_checked(&reply.data[..]).expect("an SDO Info frame");
            assert_eq!(frame.service(), CoeService::SdoInfo, "{reply:?}");
            if frame.opcode() == SdoInfoOpcode::Error {
                assert!(data.is_empty(), "an error after fragments: {reply:?}");
                let repr = SdoInfoRepr::parse(&frame).expect("an SDO Info Error");
                let SdoInfoService::Error { code } = repr.service else {
                    unreachable!("opcode 7 parses as an error");
                };
                return Err(u32::from(code));
            }
            assert_eq!(frame.opcode(), expected, "{reply:?}");
            if let Some(before) = left {
                assert_eq!(
                    frame.fragments_left() + 1,
                    before,
                    "fragments left counts down"
                );
            }
            left = Some(frame.fragments_left());
            data.extend_from_slice(frame.data());
            if !frame.incomplete() {
                assert_eq!(frame.fragments_left(), 0, "the last fragment has none left");
                return Ok(InfoAnswer { data, fragments });
            }
        }
        panic!("more than {MAX_FRAGMENTS} fragments");
    }

    /// Get OD List of all objects: the indices (the list type word, only at the start of
    /// the first fragment, is checked and dropped) and how many fragments it took.
    pub fn od_list(&mut self, address: u16) -> (Vec<u16>, usize) {
        let answer = self
            .sdo_info(
                address,
                SdoInfoService::OdListRequest {
                    list_type: OdListType::All,
                },
                SdoInfoOpcode::OdListResponse,
            )
            .expect("an object list");
        assert_eq!(answer.data.len() % 2, 0, "whole words");
        let (list_type, indices) = OdList(&answer.data)
            .first_fragment()
            .expect("a list type word");
        assert_eq!(list_type, OdListType::All);
        (indices.words().collect(), answer.fragments)
    }

    /// Get Object Description of `index`, or the SDO Info Error's code.
    pub fn object_description(&mut self, address: u16, index: u16) -> Result<ObjectSummary, u32> {
        let answer = self.sdo_info(
            address,
            SdoInfoService::ObjectDescriptionRequest { index },
            SdoInfoOpcode::ObjectDescriptionResponse,
        )?;
        let d = ObjectDescription::parse(&answer.data).expect("an object description");
        Ok(ObjectSummary {
            index: d.index,
            data_type: d.data_type,
            max_subindex: d.max_subindex,
            object_code: d.object_code,
            name: String::from_utf8(d.name.to_vec()).expect("an ASCII name"),
        })
    }

    /// Get Entry Description of `index:subindex` (no optional values), or the SDO Info
    /// Error's code.
    pub fn entry_description(
        &mut self,
        address: u16,
        index: u16,
        subindex: u8,
    ) -> Result<EntrySummary, u32> {
        let answer = self.sdo_info(
            address,
            SdoInfoService::EntryDescriptionRequest {
                index,
                subindex,
                value_info: ValueInfo(0),
            },
            SdoInfoOpcode::EntryDescriptionResponse,
        )?;
        let e = EntryDescription::parse(&answer.data).expect("an entry description");
        Ok(EntrySummary {
            index: e.index,
            subindex: e.subindex,
            data_type: e.data_type,
            bit_length: e.bit_length,
            access: e.access,
            name: String::from_utf8(e.description.to_vec()).expect("an ASCII name"),
        })
    }
}

/// The abort code of "object does not exist" (the gateway's answer to an unknown address).
pub fn object_missing() -> u32 {
    u32::from(AbortCode::ObjectDoesNotExist)
}
