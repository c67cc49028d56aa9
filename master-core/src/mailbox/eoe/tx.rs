//! Sending Ethernet frames over EoE: up to [`CHAIN`] fragments per turn of the owner task,
//! written by the bus thread one after the other as the slave takes them
//! ([`Exchange::send_chain`]), so a request that arrives meanwhile waits at most that many
//! frame round trips (EoE uses the mailbox only when nothing else waits).

use std::collections::VecDeque;
use std::time::Instant;

use tokio::sync::{mpsc, oneshot};

use crate::mailbox::engine::exchange::Exchange;
use crate::mailbox::engine::hook::Background;
use crate::mailbox::engine::job::BoxFuture;
use crate::mailbox::engine::stats::{add, inc};
use crate::mailbox::error::{MailboxError, Result};
use crate::wire::eoe::{EoeRepr, Fragmenter};
use crate::wire::mailbox::MailboxType;
use crate::wire::{Emit, WireError};

/// The most fragments one turn writes. Each costs a frame round trip; a turn of one
/// fragment adds two thread hand-offs per fragment (the owner woken after each write to
/// send the next), which on a busy two-core machine cost as much as the round trip itself.
/// Four halve that and keep a request's wait behind EoE to four round trips.
pub(crate) const CHAIN: usize = 4;

/// A frame queued for sending, and who to tell when it is out.
pub(crate) struct EoeSend {
    pub frame: Vec<u8>,
    pub port: u8,
    pub done: oneshot::Sender<Result<()>>,
}

/// A frame taken from the queue: its EoE frame number and its next fragment.
struct Sending {
    send: EoeSend,
    number: u8,
    next: usize,
    fragments: usize,
}

/// The queue of frames to send, the frames being sent and the EoE frame number (4 bits,
/// per slave).
pub(crate) struct EoeTx {
    queue: mpsc::Receiver<EoeSend>,
    sending: VecDeque<Sending>,
    frame_number: u8,
    /// The last turn found SM0 full at its first write: the next one writes a single
    /// fragment, waiting for room ([`Exchange::send`]).
    full: bool,
}

impl EoeTx {
    /// A sender taking its frames from `queue`, starting at frame number 0.
    pub fn new(queue: mpsc::Receiver<EoeSend>) -> EoeTx {
        EoeTx {
            queue,
            sending: VecDeque::with_capacity(CHAIN),
            frame_number: 0,
            full: false,
        }
    }

    /// Whether a frame is being sent.
    pub fn busy(&self) -> bool {
        !self.sending.is_empty()
    }

    /// Starts sending `send`.
    pub fn start(&mut self, send: EoeSend) {
        let number = self.frame_number;
        self.frame_number = (self.frame_number + 1) % 16;
        self.sending.push_back(Sending {
            send,
            number,
            next: 0,
            fragments: 0,
        });
    }

    /// Fragments left to write in the frames taken.
    fn left(&self) -> usize {
        self.sending.iter().map(|s| s.fragments - s.next).sum()
    }

    /// Counts the fragments of the frames taken for a mailbox of `size` bytes; a frame that
    /// cannot be cut (too long) fails now.
    fn cut(&mut self, size: usize) {
        let mut i = 0;
        while let Some(s) = self.sending.get_mut(i) {
            if s.fragments == 0 {
                let counted = Fragmenter::new(&s.send.frame, size, s.number).map(Iterator::count);
                match counted {
                    Ok(n) if n > 0 => s.fragments = n,
                    other => {
                        let err = other.err().unwrap_or(WireError::BadLength {
                            what: "EoE frame",
                            declared: 0,
                            available: 0,
                        });
                        if let Some(failed) = self.sending.remove(i) {
                            let _ = failed.send.done.send(Err(MailboxError::Invalid(err)));
                        }
                        continue;
                    }
                }
            }
            i += 1;
        }
    }

    /// Writes the next fragments of the frames taken (and of frames still queued, while
    /// the turn has room).
    pub async fn step(&mut self, exchange: &mut Exchange) {
        let deadline = Instant::now() + exchange.config().timeout;
        exchange.begin(deadline, None, None);
        let size = exchange.write_size();
        self.cut(size);
        while !self.full && self.left() < CHAIN {
            let Ok(send) = self.queue.try_recv() else {
                break;
            };
            self.start(send);
            self.cut(size);
        }
        // (frame in `sending`, fragment) in the order they go out.
        let plan: Vec<(usize, usize)> = self
            .sending
            .iter()
            .enumerate()
            .flat_map(|(f, s)| (s.next..s.fragments).map(move |i| (f, i)))
            .take(if self.full { 1 } else { CHAIN })
            .collect();
        if plan.is_empty() {
            exchange.end().await;
            return;
        }
        let sending = &self.sending;
        let emit = |k: usize, buf: &mut [u8]| {
            let (f, i) = plan[k];
            let s = &sending[f];
            let fragment = Fragmenter::new(&s.send.frame, size, s.number)?
                .with_port(s.send.port)
                .nth(i)
                .ok_or(WireError::BadLength {
                    what: "EoE fragment",
                    declared: i,
                    available: s.fragments,
                })?;
            EoeRepr::Fragment(fragment).emit_into(buf)
        };
        let (written, result) = if self.full {
            let sent = exchange.send(MailboxType::Eoe, |buf| emit(0, buf)).await;
            (usize::from(sent.is_ok()), sent)
        } else {
            exchange
                .send_chain(MailboxType::Eoe, plan.len(), emit)
                .await
        };
        exchange.end().await;
        // A chain stopped by a full SM0 at its first write: wait for room next turn.
        self.full = written == 0 && result.is_ok();
        for _ in 0..written {
            self.advance(exchange);
        }
        if let Err(err) = result
            && let Some(failed) = self.sending.pop_front()
        {
            // The fragment whose write has no answer belongs to the frame now first.
            let _ = failed.send.done.send(Err(err));
        }
    }

    /// One fragment of the first frame went in; a frame complete is reported.
    fn advance(&mut self, exchange: &Exchange) {
        let Some(first) = self.sending.front_mut() else {
            return;
        };
        first.next += 1;
        if first.next < first.fragments {
            return;
        }
        if let Some(done) = self.sending.pop_front() {
            inc(&exchange.stats().eoe_frames_out);
            add(&exchange.stats().eoe_bytes_out, done.send.frame.len());
            let _ = done.send.done.send(Ok(()));
        }
    }
}

/// The owner task drives EoE sending through the engine's hook.
impl Background for EoeTx {
    fn busy(&self) -> bool {
        EoeTx::busy(self)
    }

    fn try_start(&mut self) {
        if let Ok(send) = self.queue.try_recv() {
            self.start(send);
        }
    }

    fn start_next(&mut self) -> BoxFuture<'_, ()> {
        // Cancel-safe: a frame is taken from the queue only when `recv` completes.
        Box::pin(async move {
            if let Some(send) = self.queue.recv().await {
                self.start(send);
            }
        })
    }

    fn step<'a>(&'a mut self, exchange: &'a mut Exchange) -> BoxFuture<'a, ()> {
        Box::pin(EoeTx::step(self, exchange))
    }

    fn close(&mut self) {
        self.queue.close();
    }
}
