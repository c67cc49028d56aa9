//! Shared by the gateway tests: a scanned master on the in-process simulator with its
//! mailbox gateway on 127.0.0.1, and a UDP client that speaks ETG.8200 through our wire
//! codecs (CoE SDO transfers driven segment by segment, SDO Information with fragments).
#![allow(dead_code)]

#[path = "../master_support/mod.rs"]
pub mod master_support;

use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::sync::Arc;
use std::time::{Duration, Instant};

use master_core::gateway::{AllowedNet, ClientNet, GatewayConfig, GatewayRole, MailboxGateway};
use master_core::master::{Master, MasterConfig};
use master_core::wire::Emit;
use master_core::wire::coe::info::entry::{EntryDescription, ValueInfo};
use master_core::wire::coe::info::object::ObjectDescription;
use master_core::wire::coe::info::od_list::{OdList, OdListType};
use master_core::wire::coe::info::{SdoInfoFrame, SdoInfoOpcode, SdoInfoRepr, SdoInfoService};
use master_core::wire::coe::{
    AbortCode, CoeRepr, SdoFrame, SdoPayload, SdoRequest, SdoResponse, max_initiate_data,
    max_segment_data,
};
use master_core::wire::gateway::{GatewayMessage, GatewayRepr};
use master_core::wire::mailbox::{MailboxHeader, MailboxType};
use sim::link::InProcessLink;
use sim::topology::Topology;

pub use master_support::{PATIENCE, block_on};

/// Station address of the slave at `position` (the master's default base 1001).
pub fn station(position: usize) -> u16 {
    1001 + position as u16
}

pub const DRIVE: usize = 0;
pub const DO8: usize = 1;
pub const COE_STORE: usize = 3;
pub const EOE_PORT: usize = 4;

/// A scanned master and its gateway. Dropping it stops the gateway, the master and the
/// bus, in that order.
pub struct GwRig {
    pub gateway: Option<MailboxGateway>,
    pub master: Option<Arc<Master>>,
    pub topology: Topology,
    pub handles: Vec<sim::topology::SlaveHandles>,
    rig: Option<master_support::Rig<InProcessLink>>,
}

/// The test configuration: any free port on loopback. Every test client is on the one host
/// 127.0.0.1, which the in-flight cap counts as one client: the cap is the overall one.
pub fn test_config() -> GatewayConfig {
    GatewayConfig {
        bind: Ipv4Addr::LOCALHOST.into(),
        port: Some(0),
        max_in_flight_per_client: GatewayConfig::default().max_in_flight,
        ..GatewayConfig::default()
    }
}

impl GwRig {
    /// The default segment, scanned to OP, with a gateway started with `config`.
    pub fn start(config: GatewayConfig) -> GwRig {
        GwRig::with_topology(Topology::default_segment(), config)
    }

    pub fn with_topology(topology: Topology, config: GatewayConfig) -> GwRig {
        let mut rig = master_support::rig(topology.clone(), MasterConfig::default());
        let report = block_on(rig.master().scan()).expect("scan");
        assert!(report.failures.is_empty(), "{:?}", report.failures);
        let master = Arc::new(rig.master.take().expect("master"));
        let handles = std::mem::take(&mut rig.handles);
        let mut gateway = MailboxGateway::new(Arc::clone(&master), config);
        gateway.start().expect("gateway starts");
        GwRig {
            gateway: Some(gateway),
            master: Some(master),
            topology,
            handles,
            rig: Some(rig),
        }
    }

    pub fn gateway(&self) -> &MailboxGateway {
        self.gateway.as_ref().expect("gateway")
    }

    pub fn gateway_mut(&mut self) -> &mut MailboxGateway {
        self.gateway.as_mut().expect("gateway")
    }

    pub fn master(&self) -> &Master {
        self.master.as_ref().expect("master")
    }

    pub fn addr(&self) -> SocketAddr {
        self.gateway().local_addr().expect("gateway running")
    }

    pub fn client(&self) -> Client {
        Client::new(self.addr())
    }

    /// The simulated segment, for looking at slaves directly.
    pub fn segment(&self) -> std::sync::MutexGuard<'_, sim::segment::Segment> {
        self.rig.as_ref().expect("rig").segment()
    }
}

impl Drop for GwRig {
    fn drop(&mut self) {
        drop(self.gateway.take());
        if let Some(master) = self.master.take() {
            let bus = master.bus().clone();
            // The gateway is gone, so this is the last reference: the master stops here.
            drop(master);
            bus.shutdown();
        }
        drop(self.rig.take());
    }
}

/// The bytes of 0x2000:00 in the CoE store slave ([`COE_STORE`]), read in the simulator.
pub fn stored(rig: &GwRig) -> Vec<u8> {
    let dict = rig.handles[COE_STORE].dictionary.as_ref().unwrap();
    dict.lock().unwrap().get_bytes(0x2000, 0).unwrap().to_vec()
}

/// One client downloads `new` into 0x2000:00 of the CoE store while `readers` clients each
/// upload it `reads` times, all let go at once: the download finishes, and every upload
/// finishes with a whole value, the one before (`original`) or `new`, never a mix of two
/// segmented transfers.
pub fn one_download_against_uploads(rig: &GwRig, new: &[u8], readers: usize, reads: usize) {
    let address = station(COE_STORE);
    let original = stored(rig);
    let start = std::sync::Barrier::new(readers + 1);
    std::thread::scope(|s| {
        let writer = s.spawn(|| {
            let mut client = rig.client();
            start.wait();
            client.download(address, 0x2000, 0, new)
        });
        let readers: Vec<_> = (0..readers)
            .map(|_| {
                s.spawn(|| {
                    let mut client = rig.client();
                    start.wait();
                    (0..reads)
                        .map(|_| client.upload(address, 0x2000, 0))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        assert_eq!(writer.join().unwrap(), Ok(()), "the download finished");
        for reader in readers {
            for value in reader.join().unwrap() {
                let value = value.expect("every upload finished");
                assert!(
                    value == original || value == new,
                    "a whole value, never a mix of two transfers"
                );
            }
        }
    });
    assert_eq!(stored(rig), new);
}

/// A reply datagram, parsed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    pub header: MailboxHeader,
    pub data: Vec<u8>,
    pub from: SocketAddr,
}

impl Reply {
    /// The SDO response in the reply.
    pub fn sdo(&self) -> SdoResponse<'_> {
        assert_eq!(self.header.mailbox_type, MailboxType::Coe, "{self:?}");
        SdoResponse::parse(&SdoFrame::new_checked(&self.data[..]).expect("SDO frame"))
            .expect("SDO response")
    }
}

/// An ETG.8200 client on its own UDP socket.
pub struct Client {
    pub socket: UdpSocket,
    pub gateway: SocketAddr,
    counter: u8,
    /// SDO segment sizes, from the slave's mailbox size (128 for every simulated slave).
    pub mailbox_size: usize,
}

/// A datagram for `address` of `ty` carrying `data`, with counter `counter`.
pub fn datagram(address: u16, ty: MailboxType, counter: u8, data: &[u8]) -> Vec<u8> {
    let repr = GatewayRepr {
        header: MailboxHeader {
            length: data.len() as u16,
            address,
            channel: 0,
            priority: 0,
            mailbox_type: ty,
            counter,
        },
        data,
    };
    repr.to_vec().expect("emit")
}

/// CoE mailbox data of a CoE message.
pub fn coe(repr: &CoeRepr<'_>) -> Vec<u8> {
    repr.to_vec().expect("emit")
}

pub fn sdo(request: SdoRequest<'_>) -> Vec<u8> {
    coe(&CoeRepr::SdoRequest(request))
}

pub fn info(service: SdoInfoService<'_>) -> Vec<u8> {
    coe(&CoeRepr::SdoInfo(SdoInfoRepr {
        incomplete: false,
        fragments_left: 0,
        service,
    }))
}

impl Client {
    pub fn new(gateway: SocketAddr) -> Client {
        let socket = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).expect("client socket");
        socket
            .set_read_timeout(Some(Duration::from_millis(200)))
            .expect("timeout");
        Client {
            socket,
            gateway,
            counter: 0,
            mailbox_size: 128,
        }
    }

    pub fn local_addr(&self) -> SocketAddr {
        self.socket.local_addr().expect("local")
    }

    pub fn send_raw(&self, bytes: &[u8]) {
        self.socket.send_to(bytes, self.gateway).expect("send");
    }

    pub fn send(&mut self, address: u16, ty: MailboxType, data: &[u8]) {
        self.counter = self.counter % 7 + 1;
        let bytes = datagram(address, ty, self.counter, data);
        self.send_raw(&bytes);
    }

    /// The next reply, or `None` if none comes within `wait`.
    pub fn recv_within(&self, wait: Duration) -> Option<Reply> {
        let deadline = Instant::now() + wait;
        // Any reply fits (a gateway message is at most 2 + 2047 bytes); on the stack, so a
        // benchmark's client costs no 64 KiB allocation per reply.
        let mut buf = [0u8; 4096];
        while Instant::now() < deadline {
            match self.socket.recv_from(&mut buf) {
                Ok((len, from)) => {
                    let msg = GatewayMessage::new_checked(&buf[..len]).expect("reply parses");
                    let repr = GatewayRepr::parse(&msg).expect("reply parses");
                    return Some(Reply {
                        header: repr.header,
                        data: repr.data.to_vec(),
                        from,
                    });
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) => {}
                Err(e) => panic!("recv: {e}"),
            }
        }
        None
    }

    /// The next reply; fails the test if none comes within `PATIENCE`.
    pub fn recv(&self) -> Reply {
        self.recv_within(PATIENCE).expect("a reply in time")
    }

    pub fn request(&mut self, address: u16, ty: MailboxType, data: &[u8]) -> Reply {
        self.send(address, ty, data);
        self.recv()
    }

    /// A whole SDO upload (expedited, normal or segmented), driven segment by segment.
    pub fn upload(&mut self, address: u16, index: u16, subindex: u8) -> Result<Vec<u8>, AbortCode> {
        self.upload_with(address, index, subindex, false)
    }

    pub fn upload_with(
        &mut self,
        address: u16,
        index: u16,
        subindex: u8,
        complete_access: bool,
    ) -> Result<Vec<u8>, AbortCode> {
        let request = sdo(SdoRequest::InitiateUpload {
            index,
            subindex,
            complete_access,
        });
        let reply = self.request(address, MailboxType::Coe, &request);
        let (size, mut data) = match reply.sdo() {
            SdoResponse::InitiateUpload {
                payload: SdoPayload::Expedited(value),
                ..
            } => return Ok(value.to_vec()),
            SdoResponse::InitiateUpload {
                payload:
                    SdoPayload::Normal {
                        complete_size,
                        data,
                    },
                ..
            } => (complete_size as usize, data.to_vec()),
            SdoResponse::Abort { code, .. } => return Err(code),
            other => panic!("unexpected {other:?}"),
        };
        let mut toggle = false;
        while data.len() < size {
            let reply = self.request(
                address,
                MailboxType::Coe,
                &sdo(SdoRequest::UploadSegment { toggle }),
            );
            match reply.sdo() {
                SdoResponse::UploadSegment {
                    toggle: t,
                    last,
                    data: part,
                } => {
                    assert_eq!(t, toggle, "toggle echoed");
                    data.extend_from_slice(part);
                    if last {
                        break;
                    }
                }
                SdoResponse::Abort { code, .. } => return Err(code),
                other => panic!("unexpected {other:?}"),
            }
            toggle = !toggle;
        }
        assert_eq!(data.len(), size, "the announced size arrived");
        Ok(data)
    }

    /// A whole SDO download: expedited up to 4 bytes, else normal and segmented.
    pub fn download(
        &mut self,
        address: u16,
        index: u16,
        subindex: u8,
        value: &[u8],
    ) -> Result<(), AbortCode> {
        let first = if value.len() <= 4 {
            value.len()
        } else {
            value.len().min(max_initiate_data(self.mailbox_size))
        };
        let payload = if value.len() <= 4 {
            SdoPayload::Expedited(value)
        } else {
            SdoPayload::Normal {
                complete_size: value.len() as u32,
                data: &value[..first],
            }
        };
        let reply = self.request(
            address,
            MailboxType::Coe,
            &sdo(SdoRequest::InitiateDownload {
                index,
                subindex,
                complete_access: false,
                payload,
            }),
        );
        match reply.sdo() {
            SdoResponse::InitiateDownload { .. } => {}
            SdoResponse::Abort { code, .. } => return Err(code),
            other => panic!("unexpected {other:?}"),
        }
        let mut sent = first;
        let mut toggle = false;
        let step = max_segment_data(self.mailbox_size);
        while sent < value.len() {
            let end = (sent + step).min(value.len());
            let last = end == value.len();
            let reply = self.request(
                address,
                MailboxType::Coe,
                &sdo(SdoRequest::DownloadSegment {
                    toggle,
                    last,
                    data: &value[sent..end],
                }),
            );
            match reply.sdo() {
                SdoResponse::DownloadSegment { toggle: t } => assert_eq!(t, toggle),
                SdoResponse::Abort { code, .. } => return Err(code),
                other => panic!("unexpected {other:?}"),
            }
            sent = end;
            toggle = !toggle;
        }
        Ok(())
    }

    /// An SDO Information request; returns the concatenated service data of the answer
    /// (every fragment is its own datagram) and how many datagrams it took.
    pub fn info(
        &mut self,
        address: u16,
        service: SdoInfoService<'_>,
    ) -> Result<(Vec<u8>, usize), AbortCode> {
        self.send(address, MailboxType::Coe, &info(service));
        let mut data = Vec::new();
        let mut count = 0;
        loop {
            let reply = self.recv();
            count += 1;
            let frame = SdoInfoFrame::new_checked(&reply.data[..]).expect("SDO Info");
            if frame.opcode() == SdoInfoOpcode::Error {
                let repr = SdoInfoRepr::parse(&frame).expect("SDO Info error");
                match repr.service {
                    SdoInfoService::Error { code } => return Err(code),
                    _ => unreachable!(),
                }
            }
            data.extend_from_slice(frame.data());
            if !frame.incomplete() {
                return Ok((data, count));
            }
        }
    }

    /// Get OD List (all objects).
    pub fn od_list(&mut self, address: u16) -> Vec<u16> {
        let (data, _) = self
            .info(
                address,
                SdoInfoService::OdListRequest {
                    list_type: OdListType::All,
                },
            )
            .expect("OD list");
        let (ty, rest) = OdList(&data).first_fragment().expect("list type");
        assert_eq!(ty, OdListType::All);
        rest.words().collect()
    }

    /// Get Object Description: (name, object code, max subindex, data type).
    pub fn object(&mut self, address: u16, index: u16) -> Result<ObjectSummary, AbortCode> {
        let (data, _) = self.info(address, SdoInfoService::ObjectDescriptionRequest { index })?;
        let d = ObjectDescription::parse(&data).expect("object description");
        Ok(ObjectSummary {
            index: d.index,
            name: String::from_utf8_lossy(d.name).into_owned(),
            object_code: d.object_code,
            max_subindex: d.max_subindex,
        })
    }

    /// Get Entry Description: (data type, bit length, access, name).
    pub fn entry(
        &mut self,
        address: u16,
        index: u16,
        subindex: u8,
    ) -> Result<EntrySummary, AbortCode> {
        let (data, _) = self.info(
            address,
            SdoInfoService::EntryDescriptionRequest {
                index,
                subindex,
                value_info: ValueInfo(0),
            },
        )?;
        let e = EntryDescription::parse(&data).expect("entry description");
        Ok(EntrySummary {
            data_type: e.data_type,
            bit_length: e.bit_length,
            access: e.access,
            name: String::from_utf8_lossy(e.description).into_owned(),
        })
    }
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObjectSummary {
    pub index: u16,
    pub name: String,
    pub object_code: master_core::wire::coe::ObjectCode,
    pub max_subindex: u8,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EntrySummary {
    pub data_type: master_core::wire::coe::DataType,
    pub bit_length: u16,
    pub access: master_core::wire::coe::ObjectAccess,
    pub name: String,
}

/// A config allowing only `net`, with the write role.
pub fn allowing(net: &str) -> GatewayConfig {
    allowing_as(net, GatewayRole::Write)
}

/// A config allowing only `net`, with `role`.
pub fn allowing_as(net: &str, role: GatewayRole) -> GatewayConfig {
    GatewayConfig {
        allow: vec![AllowedNet::new(
            net.parse::<ClientNet>().expect("network"),
            role,
        )],
        ..test_config()
    }
}
