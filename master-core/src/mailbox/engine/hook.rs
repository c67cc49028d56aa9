//! The hooks through which a protocol that uses the mailbox beside the requests (EoE) plugs
//! into the owner task, so the engine knows these traits and not the protocol: the
//! protocol's module implements them, and the mailbox's root hands them to
//! [`MailboxEngine::add_slave`](super::MailboxEngine::add_slave) through [`SideTraffic`].

use std::any::Any;
use std::time::Instant;

use super::exchange::Exchange;
use super::job::BoxFuture;

/// Takes the messages the demux routes to it without a request waiting (EoE fragments,
/// spec-notes §mbx.demux) and puts them back together. `Sync`: the exchange that holds it
/// is borrowed across the awaits of request futures, which must be `Send`.
pub(crate) trait Reassembly: Send + Sync {
    /// Drops a partial message that can no longer complete: its next part is overdue, or
    /// `next` (the message about to be pushed) starts a new one. True if one was dropped.
    fn expire(&mut self, now: Instant, next: Option<&[u8]>) -> bool;

    /// Takes the data of one routed message; call [`Self::expire`] first.
    fn push(&mut self, data: &[u8], now: Instant) -> Pushed;
}

/// What one message given to a [`Reassembly`] did.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Pushed {
    /// A frame is complete.
    Frame(Vec<u8>),
    /// More parts are needed.
    Partial,
    /// The message was refused and a frame is lost: the partial frame in progress, or the
    /// frame this part belongs to (its first part never came).
    Dropped,
    /// A later part of a frame already counted as lost; nothing more is lost.
    Orphan,
    /// Nothing to put together (a timestamp response).
    Ignored,
}

/// Traffic the owner task sends while no request waits (EoE frames), from a queue of its
/// own, one short step per turn (a few messages) so a request that arrives meanwhile goes
/// first.
pub(crate) trait Background: Send {
    /// Whether a send is under way.
    fn busy(&self) -> bool;

    /// Starts the next queued send, if one waits; does not wait.
    fn try_start(&mut self);

    /// Waits for the next queued send and starts it (nothing if the queue is closed).
    fn start_next(&mut self) -> BoxFuture<'_, ()>;

    /// Writes the next messages of the send under way (one step: a few at most).
    fn step<'a>(&'a mut self, exchange: &'a mut Exchange) -> BoxFuture<'a, ()>;

    /// Closes the queue: sends still queued fail when dropped.
    fn close(&mut self);
}

/// One slave's side traffic, as the protocol makes it for [`MailboxEngine::add_slave`](super::MailboxEngine::add_slave).
pub(crate) struct SideTraffic {
    /// What the protocol's calls on the slave's handle feed the queue through (it knows the
    /// type; the engine only keeps it).
    pub queue: Box<dyn Any + Send + Sync>,
    /// The owner task's end of the queue.
    pub background: Box<dyn Background>,
    /// The receiver of the routed messages.
    pub reassembly: Box<dyn Reassembly>,
}
