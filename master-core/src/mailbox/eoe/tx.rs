//! Sending Ethernet frames over EoE: the fragments are written by the bus thread one after
//! the other as the slave takes them, in a run the owner task hands batches of up to
//! [`CHAIN`] ([`Exchange::start_chain`], [`Exchange::join_chain`]; spec-notes §mbx.chain).
//! While one batch is written the next joins the run, unless a request waits for the
//! mailbox; a request that arrives meanwhile takes back the batch that joined and has not
//! started, so it waits for the batch under way (EoE uses the mailbox only when nothing
//! else waits).

use std::collections::VecDeque;
use std::time::Instant;

use tokio::sync::{mpsc, oneshot};

use crate::mailbox::engine::exchange::{Exchange, WriteBatch};
use crate::mailbox::engine::hook::Background;
use crate::mailbox::engine::job::BoxFuture;
use crate::mailbox::engine::stats::{add, inc};
use crate::mailbox::error::{MailboxError, Result};
use crate::wire::eoe::{EoeRepr, Fragmenter};
use crate::wire::mailbox::MailboxType;
use crate::wire::{Emit, WireError};

/// The most fragments of one batch. Each costs a frame round trip; a batch of one fragment
/// would wake the owner after each write, which on a busy two-core machine costs as much as
/// the round trip itself. While a batch of four is written the owner has four round trips
/// to hand the run the next; a request waits behind the batch under way (two if the bus
/// thread had just taken the next).
pub(crate) const CHAIN: usize = 4;

/// The most fragments one turn writes in batches that join each other: a turn ends now and
/// then even while nobody waits, so the owner task sees a stop between two.
pub(crate) const TURN: usize = 64;

/// Message `k` of `plan` (a fragment of a frame in `sending`) into `buf`.
fn emit(
    sending: &VecDeque<Sending>,
    plan: &[(usize, usize)],
    size: usize,
    k: usize,
    buf: &mut [u8],
) -> core::result::Result<usize, WireError> {
    let missing = |declared| WireError::BadLength {
        what: "EoE fragment",
        declared,
        available: plan.len(),
    };
    let &(f, i) = plan.get(k).ok_or_else(|| missing(k))?;
    let s = sending.get(f).ok_or_else(|| missing(f))?;
    let fragment = Fragmenter::new(&s.send.frame, size, s.number)?
        .with_port(s.send.port)
        .nth(i)
        .ok_or(WireError::BadLength {
            what: "EoE fragment",
            declared: i,
            available: s.fragments,
        })?;
    EoeRepr::Fragment(fragment).emit_into(buf)
}

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

    /// Takes frames from the queue while fewer than `want` fragments are left to write in
    /// the frames taken (and SM0 was not found full).
    fn take_queued(&mut self, want: usize, size: usize) {
        while !self.full && self.left() < want {
            let Ok(send) = self.queue.try_recv() else {
                break;
            };
            self.start(send);
            self.cut(size);
        }
    }

    /// The next `n` fragments after the first `skip` left to write, as (frame in
    /// `sending`, fragment), in the order they go out.
    fn plan(&self, skip: usize, n: usize) -> Vec<(usize, usize)> {
        self.sending
            .iter()
            .enumerate()
            .flat_map(|(f, s)| (s.next..s.fragments).map(move |i| (f, i)))
            .skip(skip)
            .take(n)
            .collect()
    }

    /// Writes the next fragments of the frames taken (and of frames still queued): a
    /// batch of up to [`CHAIN`], and while it is written the next batch joins it
    /// ([`Exchange::join_chain`]) unless a request waits for the mailbox, up to [`TURN`]
    /// fragments in the turn. The bus thread then goes from one batch to the next without
    /// waiting for this task, which it wakes once per batch; a request that comes takes
    /// back a batch that joined and has not started
    /// ([`SlaveShared::request_waits`](crate::mailbox::engine::slave::SlaveShared::request_waits)).
    pub async fn step(&mut self, exchange: &mut Exchange) {
        let deadline = Instant::now() + exchange.config().timeout;
        exchange.begin(deadline, None, None);
        let size = exchange.write_size();
        self.cut(size);
        self.take_queued(CHAIN, size);
        if self.full {
            // The last turn found SM0 full: one fragment, waiting for room.
            let plan = self.plan(0, 1);
            if !plan.is_empty() {
                let sent = exchange
                    .send(MailboxType::Eoe, |buf| {
                        emit(&self.sending, &plan, size, 0, buf)
                    })
                    .await;
                self.full = false;
                self.count(exchange, usize::from(sent.is_ok()), sent);
            }
            exchange.end().await;
            return;
        }
        let plan = self.plan(0, CHAIN);
        if plan.is_empty() {
            exchange.end().await;
            return;
        }
        let started = exchange
            .start_chain(MailboxType::Eoe, plan.len(), |k, buf| {
                emit(&self.sending, &plan, size, k, buf)
            })
            .await;
        let (run, mut batch) = match started {
            Ok(started) => started,
            Err(err) => {
                self.count(exchange, 0, Err(err));
                exchange.end().await;
                return;
            }
        };
        // Fragments in the batches handed to the bus and not yet counted.
        let mut planned = batch.len();
        let mut written_in_turn = 0;
        let mut joining = true;
        loop {
            let mut next = None;
            if joining && written_in_turn + planned < TURN && exchange.queued_requests() == 0 {
                self.take_queued(planned + CHAIN, size);
                let plan = self.plan(planned, CHAIN);
                if !plan.is_empty() {
                    next = exchange.join_chain(&run, plan.len(), |k, buf| {
                        emit(&self.sending, &plan, size, k, buf)
                    });
                }
            }
            let expected = batch.len();
            planned += next.as_ref().map_or(0, WriteBatch::len);
            let (written, full, result) = exchange.finish_batch(batch).await;
            planned -= expected;
            written_in_turn += written;
            let stopped = written < expected || result.is_err();
            // A batch stopped by a full SM0 at its first write: wait for room next turn.
            self.full = full && written == 0 && result.is_ok();
            self.count(exchange, written, result);
            // The batch that joined a stopped run was not written: the next turn plans
            // its fragments again.
            match next {
                Some(joined) if !stopped => {
                    if exchange.read_beside(&run).await.is_err() {
                        // Finish the batch under way, join no more.
                        joining = false;
                    }
                    batch = joined;
                }
                _ => break,
            }
        }
        exchange.end().await;
    }

    /// Counts `written` fragments as gone in, in order; a failed write fails the frame it
    /// belongs to.
    fn count(&mut self, exchange: &Exchange, written: usize, result: Result<()>) {
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
