//! The EoE side of a simulated slave (mailbox type 2, ETG.1000.6, spec-notes §eoe).
//!
//! - [`ip_config`]: what Set IP parameter stored;
//! - [`endpoint`]: the slave's own IPv4 host (ARP and ICMP echo, built with etherparse);
//! - [`tcp_host`]: optionally, a TCP endpoint beside it (smoltcp: ARP, an HTTP server of a
//!   known payload), which then takes the ARP and TCP frames;
//! - [`host_port`]: the slave's Ethernet side handed to the host instead (ecat-sim's TAP
//!   bridge): once attached, every frame goes there and neither host above sees any;
//! - here: [`EoeService`].
//!
//! Frames from the master arrive as fragments and are put together by the codec's
//! [`Reassembler`]; a fragment that does not continue the frame in progress drops it
//! (counted in [`EoeCounters::reassembly_errors`]). Every complete frame is offered to the
//! endpoint, and kept (bounded, oldest dropped) for a test to [`EoeService::take_received`].
//! Frames to the master — the endpoint's answers and frames a test queues with
//! [`EoeService::queue_frame`] — are cut by the codec's [`Fragmenter`] for the SM1 size, with
//! a frame number counting mod 16, and posted all fragments at once or not at all.
//!
//! Set IP parameter stores the fields present and answers result 0; Get IP parameter answers
//! the stored fields. Address filters are not implemented: Set answers 0x0401 ("no filter
//! support"), Get answers type 9 with 0x0401. Timestamps (time request / appended) are not
//! produced. Frame types a master does not send (responses, unknown types) → mailbox error
//! 0x0004.

pub mod endpoint;
pub mod host_port;
pub mod ip_config;
pub mod tcp_host;

use std::any::Any;
use std::collections::VecDeque;

use ecat_wire::eoe::{EoeFrameType, EoePacket, EoeRepr, EoeResult, Fragmenter, Reassembler};
use ecat_wire::mailbox::{self, MailboxErrorCode, MailboxHeader, MailboxType};
use ecat_wire::{Emit, WireError};

use crate::device::mailbox::{MailboxService, ReplySink};
use crate::device::{DeviceContext, OutboxFull};

pub use endpoint::Answer;
pub use host_port::{HostEvent, HostPort};
pub use ip_config::{IpConfig, factory_mac};
use tcp_host::TcpHost;

/// Frames kept for [`EoeService::take_received`] before the oldest are dropped.
pub const RECEIVED_CAPACITY: usize = 64;

/// Frames waiting to go to the master before [`EoeService::queue_frame`] refuses.
pub const TX_CAPACITY: usize = 32;

/// Frame counters of one EoE service.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct EoeCounters {
    /// Complete frames received from the master.
    pub frames_in: u64,
    /// Frames sent to the master (all fragments posted).
    pub frames_out: u64,
    /// Frames that could not be sent (too large, or the queue was full).
    pub frames_dropped: u64,
    /// Partial frames dropped because a fragment did not fit the sequence.
    pub reassembly_errors: u64,
    /// ARP replies the endpoint built.
    pub arp_replies: u64,
    /// ICMP echo replies the endpoint built.
    pub icmp_replies: u64,
}

/// The EoE service.
#[derive(Debug, Clone)]
pub struct EoeService {
    reassembler: Reassembler,
    config: IpConfig,
    endpoint: bool,
    tx_queue: VecDeque<Vec<u8>>,
    received: VecDeque<Vec<u8>>,
    next_frame_number: u8,
    counters: EoeCounters,
    tcp_enabled: bool,
    tcp: HostSlot,
    port: PortSlot,
    /// Whether Set address filter is supported (`None`: answered "no filter support").
    filter: Option<FilterSlot>,
}

/// The address filter the master set: with MAC filters, frames to other unicast
/// addresses are not passed to the device (masks are not applied: spec-notes §eoe).
#[derive(Debug, Clone, Default)]
struct FilterSlot(Option<ecat_wire::eoe::AddressFilter>);

impl FilterSlot {
    fn passes(&self, frame: &[u8]) -> bool {
        let (Some(filter), Some(destination)) = (&self.0, frame.get(..6)) else {
            return true;
        };
        if destination[0] & 1 == 1 {
            // Broadcast and multicast.
            return !filter.no_broadcasts;
        }
        let count = usize::from(filter.filter_count).min(filter.filters.len());
        count == 0 || filter.filters[..count].iter().any(|mac| mac == destination)
    }
}

/// The host port. A clone of the service (a snapshot) gets a port of its own, never
/// attached: frames for the host stay with the original.
#[derive(Debug, Default)]
struct PortSlot(HostPort);

impl Clone for PortSlot {
    fn clone(&self) -> PortSlot {
        PortSlot::default()
    }
}

/// The TCP host, made once the slave has a MAC and an IP address. A clone of the service
/// (a snapshot of the simulator) gets none: the connection state stays with the original,
/// and the clone makes its own host when it is first needed.
#[derive(Debug, Default)]
struct HostSlot(Option<Box<TcpHost>>);

impl Clone for HostSlot {
    fn clone(&self) -> HostSlot {
        HostSlot(None)
    }
}

impl Default for EoeService {
    fn default() -> Self {
        Self::new(IpConfig::default())
    }
}

/// Builds an EoE message with the codec.
fn build(repr: &EoeRepr<'_>) -> Result<Vec<u8>, WireError> {
    repr.to_vec()
}

impl EoeService {
    /// A service that starts with `config` (e.g. a MAC address set at the factory) and
    /// answers ARP and ICMP echo once it has a MAC and an IP address.
    pub fn new(config: IpConfig) -> Self {
        EoeService {
            reassembler: Reassembler::default(),
            config,
            endpoint: true,
            tx_queue: VecDeque::new(),
            received: VecDeque::new(),
            next_frame_number: 0,
            counters: EoeCounters::default(),
            tcp_enabled: false,
            tcp: HostSlot::default(),
            port: PortSlot::default(),
            filter: None,
        }
    }

    /// The service supporting Set address filter: the filter decides which frames reach
    /// the device.
    pub fn with_address_filter(mut self) -> Self {
        self.filter = Some(FilterSlot::default());
        self
    }

    /// The service with `port` as its host port (see [`host_port`]); a port made by
    /// default is never attached.
    pub fn with_host_port(mut self, port: HostPort) -> Self {
        self.port = PortSlot(port);
        self
    }

    /// The host port, if the slave's Ethernet side is handed to the host.
    fn attached_port(&self) -> Option<&HostPort> {
        Some(&self.port.0).filter(|port| port.is_attached())
    }

    /// Whether a TCP endpoint ([`tcp_host`]) runs behind the slave (default: no). With it,
    /// ARP and TCP frames go to it, ICMP echo still to the endpoint.
    pub fn with_tcp_host(mut self, enabled: bool) -> Self {
        self.tcp_enabled = enabled;
        self
    }

    /// The TCP host for the current settings, made or made anew as they change; none
    /// without a MAC and an IP address.
    fn tcp_host(&mut self) -> Option<&mut TcpHost> {
        if !self.tcp_enabled {
            return None;
        }
        let (Some(mac), Some(ip)) = (self.config.station_mac(), self.config.ip) else {
            self.tcp.0 = None;
            return None;
        };
        let prefix = self
            .config
            .subnet_mask
            .map_or(24, |mask| u32::from(mask).leading_ones() as u8);
        if !self
            .tcp
            .0
            .as_ref()
            .is_some_and(|h| h.is_for(mac, ip, prefix))
        {
            self.tcp.0 = Some(Box::new(TcpHost::new(mac, ip, prefix)));
        }
        self.tcp.0.as_deref_mut()
    }

    /// Sends what the TCP host has for the master while the mailbox has room.
    fn flush_tcp(&mut self, replies: &mut ReplySink) {
        loop {
            if self.tx_queue.len() >= TX_CAPACITY {
                return;
            }
            let Some(host) = self.tcp.0.as_deref_mut() else {
                return;
            };
            host.poll();
            let Some(frame) = host.take_frame() else {
                return;
            };
            self.send_or_queue(frame, replies);
        }
    }

    /// Whether the slave answers ARP and ICMP echo itself (default: yes).
    pub fn with_endpoint(mut self, enabled: bool) -> Self {
        self.endpoint = enabled;
        self
    }

    /// The current IP settings.
    pub fn config(&self) -> &IpConfig {
        &self.config
    }

    /// Replaces the IP settings.
    pub fn set_config(&mut self, config: IpConfig) {
        self.config = config;
    }

    /// The frame counters.
    pub fn counters(&self) -> EoeCounters {
        self.counters
    }

    /// Takes the frames received from the master so far, oldest first.
    pub fn take_received(&mut self) -> Vec<Vec<u8>> {
        self.received.drain(..).collect()
    }

    /// Queues an Ethernet frame (without FCS) to send to the master; it goes out from
    /// [`MailboxService::poll`] when the mailbox has room.
    pub fn queue_frame(&mut self, frame: Vec<u8>) -> Result<(), OutboxFull> {
        if self.tx_queue.len() >= TX_CAPACITY {
            return Err(OutboxFull);
        }
        self.tx_queue.push_back(frame);
        Ok(())
    }

    /// A frame from the master is complete.
    fn frame_received(&mut self, frame: Vec<u8>, replies: &mut ReplySink) {
        self.counters.frames_in += 1;
        if self.filter.as_ref().is_some_and(|f| !f.passes(&frame)) {
            return;
        }
        if let Some(port) = self.attached_port() {
            // The device is the host's: it answers, not the slave (nor is the frame kept
            // for `take_received`, which would copy every frame of a bulk transfer).
            port.deliver(HostEvent::Frame(frame));
            return;
        }
        if tcp_host::wants(&frame)
            && let Some(host) = self.tcp_host()
        {
            host.receive(frame.clone());
            self.flush_tcp(replies);
        } else if self.endpoint {
            match endpoint::answer(&frame, &self.config) {
                Some(Answer::Arp(reply)) => {
                    self.counters.arp_replies += 1;
                    self.send_or_queue(reply, replies);
                }
                Some(Answer::IcmpEcho(reply)) => {
                    self.counters.icmp_replies += 1;
                    self.send_or_queue(reply, replies);
                }
                None => {}
            }
        }
        if self.received.len() >= RECEIVED_CAPACITY {
            self.received.pop_front();
        }
        self.received.push_back(frame);
    }

    fn send_or_queue(&mut self, frame: Vec<u8>, replies: &mut ReplySink) {
        if !self.tx_queue.is_empty() {
            // Keep the order: older frames go first.
            if self.queue_frame(frame).is_err() {
                self.counters.frames_dropped += 1;
            }
            return;
        }
        match self.transmit(&frame, replies) {
            Ok(true) => {}
            Ok(false) => {
                if self.queue_frame(frame).is_err() {
                    self.counters.frames_dropped += 1;
                }
            }
            Err(()) => self.counters.frames_dropped += 1,
        }
    }

    /// Posts all fragments of `frame`: `Ok(false)` when the mailbox has no room for all of
    /// them (nothing posted), `Err` when the frame can never be sent.
    fn transmit(&mut self, frame: &[u8], replies: &mut ReplySink) -> Result<bool, ()> {
        let mailbox_size = replies.max_data_len() + mailbox::HEADER_LEN;
        let fragmenter =
            Fragmenter::new(frame, mailbox_size, self.next_frame_number).map_err(|_| ())?;
        let messages: Result<Vec<_>, _> =
            fragmenter.map(|f| build(&EoeRepr::Fragment(f))).collect();
        let messages = messages.map_err(|_| ())?;
        if messages.len() > replies.room() {
            return Ok(false);
        }
        for message in messages {
            let _ = replies.send(message);
        }
        self.next_frame_number = (self.next_frame_number + 1) % 16;
        self.counters.frames_out += 1;
        Ok(true)
    }

    /// One frame from the host port, and only once nothing waits for SM1: the master reads
    /// the stream as fast as it reads at all, and an answer to its next request (an SDO
    /// upload) waits behind one frame's fragments at most, not behind a queue of them.
    fn poll_port(&mut self, replies: &mut ReplySink) {
        if replies.ahead() > 0 {
            return;
        }
        let frame = match self.tx_queue.pop_front() {
            Some(frame) => frame,
            None => match self.port.0.take_for_master() {
                Some(frame) => frame,
                None => return,
            },
        };
        match self.transmit(&frame, replies) {
            Ok(true) => {}
            Ok(false) => self.tx_queue.push_front(frame),
            Err(()) => self.counters.frames_dropped += 1,
        }
    }

    fn respond(replies: &mut ReplySink, repr: &EoeRepr<'_>) {
        let _ = replies.send_emitted(build(repr));
    }
}

impl MailboxService for EoeService {
    fn mailbox_type(&self) -> MailboxType {
        MailboxType::Eoe
    }

    fn handle(
        &mut self,
        _request: &MailboxHeader,
        data: &[u8],
        _ctx: &DeviceContext,
        replies: &mut ReplySink,
    ) {
        let parsed = EoePacket::new_checked(data).and_then(|p| EoeRepr::parse(&p));
        let request = match parsed {
            Ok(request) => request,
            Err(e) => {
                let _ = replies.reject(&e);
                return;
            }
        };
        match request {
            EoeRepr::Fragment(fragment) => match self.reassembler.push(&fragment) {
                Ok(Some(frame)) => {
                    let frame = frame.frame.to_vec();
                    self.frame_received(frame, replies);
                }
                Ok(None) => {}
                Err(_) => self.counters.reassembly_errors += 1,
            },
            EoeRepr::SetIpRequest { port, params } => {
                self.config.apply(&params);
                if let Some(host) = self.attached_port() {
                    host.deliver(HostEvent::IpConfig(self.config.clone()));
                }
                let result = EoeResult::Success;
                Self::respond(replies, &EoeRepr::SetIpResponse { port, result });
            }
            EoeRepr::GetIpRequest { port } => {
                let params = self.config.as_params();
                let result = EoeResult::Success;
                Self::respond(
                    replies,
                    &EoeRepr::GetIpResponse {
                        port,
                        result,
                        params,
                    },
                );
            }
            EoeRepr::SetAddressFilterRequest { port, filter } => {
                let result = match &mut self.filter {
                    Some(slot) => {
                        slot.0 = Some(filter);
                        EoeResult::Success
                    }
                    None => EoeResult::NoFilterSupport,
                };
                Self::respond(replies, &EoeRepr::SetAddressFilterResponse { port, result });
            }
            EoeRepr::Other {
                frame_type: EoeFrameType::GetAddressFilterRequest,
                port,
                ..
            } => Self::respond(
                replies,
                &EoeRepr::Other {
                    frame_type: EoeFrameType::GetAddressFilterResponse,
                    port,
                    info: u16::from(EoeResult::NoFilterSupport),
                    body: &[],
                },
            ),
            _ => {
                let _ = replies.mailbox_error(MailboxErrorCode::ServiceNotSupported);
            }
        }
    }

    fn poll(&mut self, _ctx: &DeviceContext, replies: &mut ReplySink) {
        if self.attached_port().is_some() {
            return self.poll_port(replies);
        }
        while let Some(frame) = self.tx_queue.pop_front() {
            match self.transmit(&frame, replies) {
                Ok(true) => {}
                Ok(false) => {
                    self.tx_queue.push_front(frame);
                    return;
                }
                Err(()) => self.counters.frames_dropped += 1,
            }
        }
        // The TCP host's timers (retransmission) and the data its window now allows.
        if self.tcp_host().is_some() {
            self.flush_tcp(replies);
        }
    }

    fn reset(&mut self) {
        self.reassembler.reset();
        self.tx_queue.clear();
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
