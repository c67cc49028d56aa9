//! The boundary between the mailbox layer and one protocol: [`MailboxService`] and the
//! [`ReplySink`] a service answers into.
//!
//! A service sees only its own protocol's bytes (the mailbox data after the 6-byte header) and
//! hands back mailbox *data*; the layer ([`super::MailboxStack`]) owns every header field, so no
//! service can get the length, the counter or the address echo wrong.

use std::any::Any;

use ecat_wire::mailbox::{ErrorReplyRepr, HEADER_LEN, MailboxErrorCode};
use ecat_wire::mailbox::{MailboxHeader, MailboxType};
use ecat_wire::{Emit, WireError};

use crate::device::{DeviceContext, OutboxFull};

/// One mailbox protocol of a slave (CoE, EoE, FoE, SoE, VoE, ...).
///
/// The CoE server is meant to plug in here too: it implements this trait with
/// [`MailboxType::Coe`] and is registered like any other service.
pub trait MailboxService: Send {
    /// The mailbox type this service answers (header byte 5, bits 0-3).
    fn mailbox_type(&self) -> MailboxType;

    /// A request of this service's type passed the layer's checks (header, channel, counter).
    /// `data` is exactly the mailbox data (`request.length` bytes). Replies go into `replies`.
    fn handle(
        &mut self,
        request: &MailboxHeader,
        data: &[u8],
        ctx: &DeviceContext,
        replies: &mut ReplySink,
    );

    /// Called when the master may read again: post unsolicited messages (EoE frames,
    /// notifications) or continue deferred work. The sink's address is 0 (the master).
    fn poll(&mut self, ctx: &DeviceContext, replies: &mut ReplySink) {
        let _ = (ctx, replies);
    }

    /// The mailbox was reset (fall back to INIT): forget transfers in progress.
    fn reset(&mut self) {}

    /// The service as [`Any`], so a test can reach its concrete type through the stack.
    fn as_any(&self) -> &dyn Any;

    /// The service as mutable [`Any`].
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

/// A reply waiting to be wrapped in a mailbox header.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct PendingReply {
    pub(crate) mailbox_type: MailboxType,
    pub(crate) address: u16,
    pub(crate) data: Vec<u8>,
}

/// Where a service puts its replies: mailbox data only, the layer adds the header.
///
/// Bounded like the outbox behind it: [`ReplySink::room`] says how many more messages fit, so
/// a service that must post several (SoE fragments, EoE fragments of one frame) can check
/// first and post all or nothing.
#[derive(Debug)]
pub struct ReplySink {
    mailbox_type: MailboxType,
    address: u16,
    max_data_len: usize,
    room: usize,
    ahead: usize,
    replies: Vec<PendingReply>,
    faults: u64,
}

impl ReplySink {
    /// A sink for a service of `mailbox_type`; replies are addressed to `address` (the
    /// request's address, echoed; 0 for unsolicited messages) and may carry at most
    /// `max_data_len` bytes of data; at most `room` messages fit.
    pub fn new(mailbox_type: MailboxType, address: u16, max_data_len: usize, room: usize) -> Self {
        ReplySink {
            mailbox_type,
            address,
            max_data_len,
            room,
            ahead: 0,
            replies: Vec::new(),
            faults: 0,
        }
    }

    /// The same sink, told that `ahead` messages already wait for SM1 before its own.
    pub(crate) fn with_ahead(mut self, ahead: usize) -> Self {
        self.ahead = ahead;
        self
    }

    /// Messages that wait for SM1 before the ones posted through this sink (posted earlier
    /// by any service): a service streaming unsolicited messages (EoE) posts only when this
    /// is 0, so an answer to a request never waits behind a long stream.
    pub fn ahead(&self) -> usize {
        self.ahead
    }

    /// Posts mailbox data of the service's own type.
    pub fn send(&mut self, data: Vec<u8>) -> Result<(), OutboxFull> {
        self.push(self.mailbox_type, data)
    }

    /// Posts the result of emitting a reply with a wire codec. An emit error is a bug in the
    /// service (it built a representation the codec refuses); the master gets a mailbox
    /// error 0x0007 instead of nothing, so it does not wait for a timeout.
    pub fn send_emitted(&mut self, built: Result<Vec<u8>, WireError>) -> Result<(), OutboxFull> {
        match built {
            Ok(data) => self.send(data),
            Err(_) => {
                self.faults += 1;
                self.mailbox_error(MailboxErrorCode::NoMoreMemory)
            }
        }
    }

    /// Posts a mailbox error reply (type 0) with `code`.
    pub fn mailbox_error(&mut self, code: MailboxErrorCode) -> Result<(), OutboxFull> {
        self.push(MailboxType::Error, error_reply_data(code))
    }

    /// Answers a request the service could not parse with the mailbox error that names the
    /// problem: too short → 0x0006, inconsistent length → 0x0008, anything else → 0x0005.
    pub fn reject(&mut self, error: &WireError) -> Result<(), OutboxFull> {
        self.mailbox_error(code_for(error))
    }

    /// Most mailbox data bytes one message may carry: the SM1 length − 6.
    pub fn max_data_len(&self) -> usize {
        self.max_data_len
    }

    /// How many more messages fit.
    pub fn room(&self) -> usize {
        self.room - self.replies.len()
    }

    /// The address replies carry.
    pub fn address(&self) -> u16 {
        self.address
    }

    /// Replies posted so far through this sink.
    pub fn len(&self) -> usize {
        self.replies.len()
    }

    /// True when nothing was posted.
    pub fn is_empty(&self) -> bool {
        self.replies.is_empty()
    }

    fn push(&mut self, mailbox_type: MailboxType, data: Vec<u8>) -> Result<(), OutboxFull> {
        if self.room() == 0 {
            return Err(OutboxFull);
        }
        self.replies.push(PendingReply {
            mailbox_type,
            address: self.address,
            data,
        });
        Ok(())
    }

    /// Takes the replies and the number of service faults seen.
    pub(crate) fn into_parts(self) -> (Vec<PendingReply>, u64) {
        (self.replies, self.faults)
    }
}

/// The mailbox error code for a request whose protocol header did not parse.
pub(crate) fn code_for(error: &WireError) -> MailboxErrorCode {
    match error {
        WireError::Truncated { .. } => MailboxErrorCode::SizeTooShort,
        WireError::BadLength { .. } => MailboxErrorCode::InvalidSize,
        _ => MailboxErrorCode::InvalidHeader,
    }
}

/// The 4 data bytes of a mailbox error reply, built with the codec.
pub(crate) fn error_reply_data(code: MailboxErrorCode) -> Vec<u8> {
    // Exactly its length: the one condition the emit checks, so never the empty default.
    ErrorReplyRepr { detail: code }.to_vec().unwrap_or_default()
}

/// Smallest SM1 that can carry a mailbox error reply.
pub(crate) const MIN_TX_MAILBOX: usize = HEADER_LEN + ecat_wire::mailbox::ERROR_REPLY_LEN;
