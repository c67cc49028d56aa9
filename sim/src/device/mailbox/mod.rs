//! The slave's mailbox layer (spec-notes §mbx.header): what a slave's firmware does with a message the
//! master wrote into SM0, before any protocol sees it.
//!
//! [`MailboxStack`] is a [`Device`] that
//!
//! 1. validates the 6-byte header (spec-notes §mbx.error — the codes follow SOES where the standard leaves
//!    a choice):
//!    - fewer than 6 bytes → 0x0006 `MBXERR_SIZETOOSHORT` (there is no header to read);
//!    - length 0, or length > SM0 length − 6 → 0x0005 `MBXERR_INVALIDHEADER`;
//!    - length beyond the bytes actually delivered → 0x0008 `MBXERR_INVALIDSIZE`;
//! 2. applies the counter rule (spec-notes §mbx.counter): a non-zero counter equal to the last accepted one is a
//!    repetition and is discarded without a reply; counter 0 is always accepted;
//! 3. checks the channel (≠ 0 → 0x0003 `MBXERR_INVALIDCHANNEL`) and the type (0 → 0x0005 as
//!    SOES does; no registered service → 0x0002 `MBXERR_UNSUPPORTEDPROTOCOL`);
//! 4. dispatches the data to the [`MailboxService`] registered for the type;
//! 5. wraps every reply in a header: its length, the request's address echoed (spec-notes §mbx.header
//!    recommendation; unsolicited messages carry 0), channel and priority 0, the slave's own
//!    counter 1..7 (incremented per posted message, never 0), and the type. A reply larger
//!    than SM1 can hold is a bug in the service: the master gets a mailbox error 0x0007
//!    `MBXERR_NOMOREMEMORY` instead of a message it cannot read.
//!
//! Replies wait in a bounded backlog until the ESC's [`Outbox`] takes them, so a service may
//! post several messages for one request (SoE fragments, EoE fragments) even when the outbox
//! holds only one. With a response delay ([`MailboxStack::with_response_delay`]) a message
//! becomes ready for the outbox only that long after it was posted, as with a slave whose
//! firmware answers slowly; nothing waits for it, so frames keep passing (the ESC looks
//! again at every frame's end).
//!
//! Every reply a master can cause is built with the `ecat_wire` codecs; nothing a
//! master sends can make the layer panic (checked by a property test).
//!
//! # Services
//!
//! EoE, FoE, SoE and VoE are in this folder's siblings (`device::{eoe, foe, soe, voe}`).
//! CoE has its slot but no service here yet: the CoE server (shared with the master's object
//! dictionary) implements [`MailboxService`] with [`MailboxType::Coe`] and is added with
//! [`MailboxStack::register`]; until then a CoE request is answered with 0x0002 like any
//! protocol the slave lacks, and SII word 0x1C ([`MailboxStack::supported_protocols`]) does
//! not claim CoE.

mod service;
mod stats;

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::{Duration, Instant};

use ecat_wire::mailbox::{HEADER_LEN, Mailbox, MailboxErrorCode, MailboxHeader, MailboxType};
use ecat_wire::register::al::AlState;
use ecat_wire::register::al_status_code::AlStatusCode;

use crate::device::{Device, DeviceContext, Outbox};

pub use service::{MailboxService, ReplySink};
pub use stats::{MailboxCounters, MailboxStackStats};

use service::{MIN_TX_MAILBOX, PendingReply, error_reply_data};

/// The bit of `mailbox_type` in the SII "mailbox protocols supported" word 0x1C (spec-notes §sii.fixed):
/// AoE 0x01, EoE 0x02, CoE 0x04, FoE 0x08, SoE 0x10, VoE 0x20; 0 for anything else.
pub fn protocol_bit(mailbox_type: MailboxType) -> u16 {
    match mailbox_type {
        MailboxType::Aoe => 0x01,
        MailboxType::Eoe => 0x02,
        MailboxType::Coe => 0x04,
        MailboxType::Foe => 0x08,
        MailboxType::Soe => 0x10,
        MailboxType::Voe => 0x20,
        MailboxType::Error | MailboxType::Unknown(_) => 0,
    }
}

/// A slave's mailbox layer: header checks, counter rule, dispatch, reply headers.
pub struct MailboxStack {
    services: Vec<Box<dyn MailboxService>>,
    /// Counter of the last accepted request; 0 until one with a non-zero counter came.
    last_counter: u8,
    /// Counter of the last posted message; 0 before the first, then 1..7.
    slave_counter: u8,
    /// Messages with the time they may go to the outbox.
    backlog: VecDeque<(Vec<u8>, Instant)>,
    backlog_capacity: usize,
    response_delay: Duration,
    stats: Arc<MailboxStackStats>,
}

impl Default for MailboxStack {
    fn default() -> Self {
        Self::new()
    }
}

impl std::fmt::Debug for MailboxStack {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let types: Vec<&str> = self
            .services
            .iter()
            .map(|s| s.mailbox_type().name())
            .collect();
        f.debug_struct("MailboxStack")
            .field("services", &types)
            .field("last_counter", &self.last_counter)
            .field("slave_counter", &self.slave_counter)
            .field("backlog", &self.backlog.len())
            .finish()
    }
}

/// Why a message was refused before dispatch: the error code and the address to answer.
struct Refusal {
    code: MailboxErrorCode,
    address: u16,
}

impl MailboxStack {
    /// Messages the layer holds for SM1 by default beyond what the outbox takes: enough for
    /// a full-size EoE frame in 32-byte fragments (48) or a long SoE read.
    pub const DEFAULT_BACKLOG: usize = 128;

    /// A stack without services (every request is answered with 0x0002).
    pub fn new() -> Self {
        Self::with_backlog(Self::DEFAULT_BACKLOG)
    }

    /// A stack whose backlog holds at most `capacity` messages.
    pub fn with_backlog(capacity: usize) -> Self {
        MailboxStack {
            services: Vec::new(),
            last_counter: 0,
            slave_counter: 0,
            backlog: VecDeque::new(),
            backlog_capacity: capacity,
            response_delay: Duration::ZERO,
            stats: Arc::new(MailboxStackStats::default()),
        }
    }

    /// Every message reaches the outbox only `delay` after it was posted (a slow firmware).
    pub fn with_response_delay(mut self, delay: Duration) -> Self {
        self.response_delay = delay;
        self
    }

    /// Registers `service` for its mailbox type; a service registered before for the same
    /// type is replaced and returned.
    pub fn register(
        &mut self,
        service: Box<dyn MailboxService>,
    ) -> Option<Box<dyn MailboxService>> {
        let ty = service.mailbox_type();
        match self.services.iter_mut().find(|s| s.mailbox_type() == ty) {
            Some(slot) => Some(std::mem::replace(slot, service)),
            None => {
                self.services.push(service);
                None
            }
        }
    }

    /// Builder form of [`Self::register`].
    pub fn with(mut self, service: impl MailboxService + 'static) -> Self {
        self.register(Box::new(service));
        self
    }

    /// The SII word 0x1C value for the registered services.
    pub fn supported_protocols(&self) -> u16 {
        self.services
            .iter()
            .fold(0, |bits, s| bits | protocol_bit(s.mailbox_type()))
    }

    /// The registered service of concrete type `T`, if any.
    pub fn service<T: 'static>(&self) -> Option<&T> {
        self.services
            .iter()
            .find_map(|s| s.as_any().downcast_ref::<T>())
    }

    /// The registered service of concrete type `T`, mutably.
    pub fn service_mut<T: 'static>(&mut self) -> Option<&mut T> {
        self.services
            .iter_mut()
            .find_map(|s| s.as_any_mut().downcast_mut::<T>())
    }

    /// The live counters (a shared handle that stays valid while the stack is boxed away).
    pub fn stats(&self) -> Arc<MailboxStackStats> {
        Arc::clone(&self.stats)
    }

    /// A snapshot of the counters.
    pub fn counters(&self) -> MailboxCounters {
        self.stats.snapshot()
    }

    /// Messages waiting in the backlog (not yet taken by the outbox).
    pub fn backlog_len(&self) -> usize {
        self.backlog.len()
    }

    /// Forgets the counter history, queued messages and every service's transfer in
    /// progress, as a slave does when its mailbox is switched off (fall back to INIT).
    pub fn reset(&mut self) {
        self.last_counter = 0;
        self.slave_counter = 0;
        self.backlog.clear();
        for service in &mut self.services {
            service.reset();
        }
    }

    /// Step 1: the header can be read and its length is consistent.
    fn check_header(message: &[u8], ctx: &DeviceContext) -> Result<MailboxHeader, Refusal> {
        if message.len() < HEADER_LEN {
            return Err(Refusal {
                code: MailboxErrorCode::SizeTooShort,
                address: 0,
            });
        }
        let view = Mailbox::new_unchecked(message);
        let address = view.address();
        let length = usize::from(view.length());
        let sm0_data = usize::from(ctx.rx_mailbox_size).saturating_sub(HEADER_LEN);
        if length == 0 || length > sm0_data {
            return Err(Refusal {
                code: MailboxErrorCode::InvalidHeader,
                address,
            });
        }
        Mailbox::new_checked(message)
            .and_then(|view| MailboxHeader::parse(&view))
            .map_err(|_| Refusal {
                code: MailboxErrorCode::InvalidSize,
                address,
            })
    }

    /// Steps 3 and 4 for an accepted request.
    fn dispatch(&mut self, header: &MailboxHeader, data: &[u8], ctx: &DeviceContext) {
        let refuse = |code| Refusal {
            code,
            address: header.address,
        };
        if header.channel != 0 {
            return self.post_refusal(refuse(MailboxErrorCode::InvalidChannel), ctx);
        }
        if header.mailbox_type == MailboxType::Error {
            // A master never sends type 0 (SOES: invalid header).
            return self.post_refusal(refuse(MailboxErrorCode::InvalidHeader), ctx);
        }
        let room = self.room();
        let Some(service) = self
            .services
            .iter_mut()
            .find(|s| s.mailbox_type() == header.mailbox_type)
        else {
            return self.post_refusal(refuse(MailboxErrorCode::UnsupportedProtocol), ctx);
        };
        let mut sink = ReplySink::new(header.mailbox_type, header.address, max_data_len(ctx), room);
        service.handle(header, data, ctx, &mut sink);
        self.absorb(sink, ctx);
    }

    fn room(&self) -> usize {
        self.backlog_capacity.saturating_sub(self.backlog.len())
    }

    fn post_refusal(&mut self, refusal: Refusal, ctx: &DeviceContext) {
        self.post(
            PendingReply {
                mailbox_type: MailboxType::Error,
                address: refusal.address,
                data: error_reply_data(refusal.code),
            },
            ctx,
        );
    }

    fn absorb(&mut self, sink: ReplySink, ctx: &DeviceContext) {
        let (replies, faults) = sink.into_parts();
        self.stats.count_faults(faults);
        for reply in replies {
            self.post(reply, ctx);
        }
    }

    /// Step 5: wraps one reply in its header and queues it.
    fn post(&mut self, mut reply: PendingReply, ctx: &DeviceContext) {
        if usize::from(ctx.tx_mailbox_size) < MIN_TX_MAILBOX || self.room() == 0 {
            // Not even an error reply could be read by the master.
            self.stats.count_dropped();
            return;
        }
        if reply.data.len() > max_data_len(ctx) {
            self.stats.count_faults(1);
            reply.mailbox_type = MailboxType::Error;
            reply.data = error_reply_data(MailboxErrorCode::NoMoreMemory);
        }
        let counter = next_counter(self.slave_counter);
        let header = MailboxHeader {
            // Fits: at most the SM1 length − 6, a u16.
            length: u16::try_from(reply.data.len()).unwrap_or(u16::MAX),
            address: reply.address,
            channel: 0,
            priority: 0,
            mailbox_type: reply.mailbox_type,
            counter,
        };
        let mut message = vec![0u8; HEADER_LEN + reply.data.len()];
        let mut view = Mailbox::new_unchecked(&mut message[..]);
        if header.emit(&mut view).is_err() {
            // Only a service claiming a type wider than 4 bits gets here.
            self.stats.count_faults(1);
            self.stats.count_dropped();
            return;
        }
        view.data_mut().copy_from_slice(&reply.data);
        self.slave_counter = counter;
        let ready = Instant::now() + self.response_delay;
        self.backlog.push_back((message, ready));
        self.stats
            .count_posted(reply.mailbox_type == MailboxType::Error);
    }

    /// Moves queued messages whose time has come into the outbox, oldest first, while it
    /// takes them.
    fn flush(&mut self, outbox: &mut Outbox) {
        let now = Instant::now();
        while let Some((front, ready)) = self.backlog.front() {
            if *ready > now {
                break;
            }
            // The outbox consumes what it refuses, so it gets a copy until it accepts.
            if outbox.push(front.clone()).is_err() {
                break;
            }
            self.backlog.pop_front();
        }
    }
}

/// The slave's counter after `previous`: 1, 2, ..., 7, 1, ... (0 is never produced).
fn next_counter(previous: u8) -> u8 {
    previous % 7 + 1
}

fn max_data_len(ctx: &DeviceContext) -> usize {
    usize::from(ctx.tx_mailbox_size).saturating_sub(HEADER_LEN)
}

impl Device for MailboxStack {
    fn mailbox_received(&mut self, message: &[u8], ctx: &DeviceContext, outbox: &mut Outbox) {
        self.stats.count_received();
        match Self::check_header(message, ctx) {
            Err(refusal) => self.post_refusal(refusal, ctx),
            Ok(header) => {
                if header.counter != 0 && header.counter == self.last_counter {
                    self.stats.count_duplicate();
                } else {
                    self.last_counter = header.counter;
                    let end = HEADER_LEN + usize::from(header.length);
                    // check_header guaranteed `end <= message.len()`.
                    let data = message.get(HEADER_LEN..end).unwrap_or_default();
                    self.dispatch(&header, data, ctx);
                }
            }
        }
        self.flush(outbox);
    }

    fn poll(&mut self, ctx: &DeviceContext, outbox: &mut Outbox) {
        self.flush(outbox);
        let max_data = max_data_len(ctx);
        // One service at a time, so each sees the room the previous ones left.
        for i in 0..self.services.len() {
            let room = self.room();
            let Some(service) = self.services.get_mut(i) else {
                break;
            };
            let ahead = self.backlog.len() + outbox.len();
            let mut sink =
                ReplySink::new(service.mailbox_type(), 0, max_data, room).with_ahead(ahead);
            service.poll(ctx, &mut sink);
            self.absorb(sink, ctx);
        }
        self.flush(outbox);
    }

    fn state_change(
        &mut self,
        from: AlState,
        to: AlState,
        ctx: &DeviceContext,
    ) -> Result<(), AlStatusCode> {
        let _ = (from, ctx);
        if to == AlState::Init {
            self.reset();
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slave_counter_runs_one_to_seven() {
        let mut c = 0;
        let seq: Vec<u8> = (0..9)
            .map(|_| {
                c = next_counter(c);
                c
            })
            .collect();
        assert_eq!(seq, [1, 2, 3, 4, 5, 6, 7, 1, 2]);
    }

    #[test]
    fn protocol_bits_follow_sii_word_0x1c() {
        assert_eq!(protocol_bit(MailboxType::Coe), 0x04);
        assert_eq!(protocol_bit(MailboxType::Voe), 0x20);
        assert_eq!(protocol_bit(MailboxType::Unknown(9)), 0);
    }
}
