//! A request on its way from a caller to the slave's mailbox, and back.
//!
//! The caller's protocol work is a closure that runs against the slave's [`Exchange`]. The
//! request takes a place in the slave's bounded queue, waits for its turn at the mailbox
//! ([`super::turn`]), runs the work and returns its result, all inside the caller's own
//! future: no task is spawned and no channel crossed, so the only other thread a request
//! wakes is the bus thread, for its frames (and the pause thread while a slow slave is
//! polled). It works from any executor: the pauses run on the engine's own timer.
//!
//! Cancellation: dropping the caller's future before the work is done sets the request's
//! `cancelled` flag and hands the rest of the work to the engine's runtime ([`Request`]).
//! A request that had not had its turn yet is skipped there; one under way sees the flag at
//! its next safe point and leaves the slave's mailbox clean (it waits for the answer
//! already asked for, and aborts an open multi-message transfer the protocol's way). Only
//! if the engine's runtime is gone too is the work cut short; the next turn then recovers
//! the mailbox ([`Exchange::recover_interrupted`]).

use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::task::{Context, Poll, ready};
use std::time::{Duration, Instant};

use crate::mailbox::error::{MailboxError, Result};
use crate::wire::mailbox::MailboxType;

use super::exchange::Exchange;
use super::report::Subject;
use super::slave::{SlaveMailbox, SlaveShared};
use super::stats::inc;
use super::turn::{Mailbox, Turn};

/// A boxed future borrowing the exchange.
pub(crate) type BoxFuture<'a, T> = Pin<Box<dyn Future<Output = T> + Send + 'a>>;

/// Runs `work` at the slave's mailbox and returns its result. `protocol` is checked
/// against the slave's announced protocols first.
pub(crate) async fn call<T, F>(
    slave: &SlaveMailbox,
    protocol: Option<MailboxType>,
    work: F,
) -> Result<T>
where
    T: Send + 'static,
    F: for<'a> FnOnce(&'a mut Exchange) -> BoxFuture<'a, Result<T>> + Send + 'static,
{
    call_for(slave, protocol, Subject::None, work).await
}

/// [`call`] for a request that addresses `subject` (an object, an IDN, a file), named in
/// the log line a failure leaves.
pub(crate) async fn call_for<T, F>(
    slave: &SlaveMailbox,
    protocol: Option<MailboxType>,
    subject: Subject,
    work: F,
) -> Result<T>
where
    T: Send + 'static,
    F: for<'a> FnOnce(&'a mut Exchange) -> BoxFuture<'a, Result<T>> + Send + 'static,
{
    let shared = slave.shared();
    if let Some(protocol) = protocol
        && !shared.config.protocols.supports(protocol)
    {
        return Err(MailboxError::Unsupported {
            station: shared.config.station,
            protocol,
        });
    }
    let place = Place::take(shared)?;
    let now = Instant::now();
    let terms = Terms {
        deadline: now + slave.timeout(),
        progress: slave.progress_cap().map(|cap| (slave.timeout(), now + cap)),
        cancelled: Arc::new(AtomicBool::new(false)),
    };
    let cancelled = Arc::clone(&terms.cancelled);
    let what = What {
        protocol,
        subject,
        asked: now,
    };
    let request = run(
        Arc::clone(shared),
        Arc::clone(slave.mailbox()),
        place,
        terms,
        what,
        work,
    );
    Request {
        work: Some(Box::pin(request)),
        cancelled,
        runtime: shared.runtime.clone(),
    }
    .await
}

/// When a request must end, and the caller's flag for going away.
struct Terms {
    /// The request fails with a timeout once this passes (with progress deadlines: unless
    /// the transfer moved on before).
    deadline: Instant,
    /// With progress deadlines: the window of each exchange and the end of the whole request.
    progress: Option<(Duration, Instant)>,
    /// Set when the caller went away.
    cancelled: Arc<AtomicBool>,
}

/// What a request is, for its failure's log line and its refusal.
struct What {
    protocol: Option<MailboxType>,
    subject: Subject,
    /// When the caller asked.
    asked: Instant,
}

/// A place in the slave's queue, given back however the wait for the turn ends.
struct Place(Arc<SlaveShared>);

impl Place {
    /// A place, or a refusal at once: the queue is full, or the slave is gone.
    fn take(shared: &Arc<SlaveShared>) -> Result<Place> {
        let queue_len = shared.engine.queue_len.max(1);
        if shared.waiting.fetch_add(1, Ordering::AcqRel) >= queue_len {
            shared.waiting.fetch_sub(1, Ordering::AcqRel);
            return Err(MailboxError::QueueFull(shared.config.station));
        }
        let place = Place(Arc::clone(shared));
        shared.request_waits();
        if shared.stopped() {
            return Err(MailboxError::Shutdown);
        }
        Ok(place)
    }
}

impl Drop for Place {
    fn drop(&mut self) {
        self.0.waiting.fetch_sub(1, Ordering::AcqRel);
    }
}

/// Waits for the turn at the slave's mailbox and runs `work` in it: counted, skipped if
/// the caller already went away or the slave is gone, and the exchange left clean for the
/// next turn.
async fn run<T, F>(
    shared: Arc<SlaveShared>,
    mailbox: Mailbox,
    place: Place,
    terms: Terms,
    what: What,
    work: F,
) -> Result<T>
where
    F: for<'a> FnOnce(&'a mut Exchange) -> BoxFuture<'a, Result<T>>,
{
    let mut turn = Turn::take(&mailbox).await;
    drop(place);
    if shared.stopped() {
        turn.finish();
        return Err(MailboxError::Shutdown);
    }
    inc(&turn.stats().requests);
    if terms.cancelled.load(Ordering::Relaxed) {
        // Not started: nothing to clean up.
        turn.count_cancelled();
        turn.finish();
        return Err(MailboxError::Cancelled);
    }
    turn.begin(terms.deadline, terms.progress, Some(terms.cancelled));
    let exchange: &mut Exchange = &mut turn;
    // A request whose deadline passed while it waited for its turn is not started: its
    // answer could only arrive after the caller gave up.
    let result = if exchange.expired() {
        Err(MailboxError::NotSent {
            station: exchange.station(),
            waited_ms: u64::try_from(what.asked.elapsed().as_millis()).unwrap_or(u64::MAX),
        })
    } else {
        // With progress deadlines the first exchange gets a whole window.
        exchange.progressed();
        work(&mut *exchange).await
    };
    if let Err(err) = &result
        && *err != MailboxError::Cancelled
    {
        exchange.count_failed();
        exchange.report_failure(what.protocol, &what.subject, err);
    }
    if turn.cancelled() {
        turn.count_cancelled();
    }
    turn.end().await;
    turn.finish();
    result
}

/// The request as the caller awaits it: polled in the caller's own task, so the only
/// thread it crosses is the bus thread's. Dropped before it is done (the caller went
/// away), it sets the caller's flag and hands the rest of the work to the engine's
/// runtime, which finishes it there: the job leaves the slave's mailbox clean.
struct Request<T: Send + 'static> {
    work: Option<BoxFuture<'static, Result<T>>>,
    cancelled: Arc<AtomicBool>,
    runtime: tokio::runtime::Handle,
}

impl<T: Send + 'static> Future for Request<T> {
    type Output = Result<T>;

    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Result<T>> {
        let Some(work) = self.work.as_mut() else {
            return Poll::Ready(Err(MailboxError::Shutdown));
        };
        let done = ready!(work.as_mut().poll(cx));
        self.work = None;
        Poll::Ready(done)
    }
}

impl<T: Send + 'static> Drop for Request<T> {
    fn drop(&mut self) {
        if let Some(work) = self.work.take() {
            self.cancelled.store(true, Ordering::Relaxed);
            // On a runtime already shut down the work is dropped here, in its turn if it
            // had one: the next turn recovers the mailbox (`Exchange::recover_interrupted`).
            drop(self.runtime.spawn(async move {
                let _ = work.await;
            }));
        }
    }
}
