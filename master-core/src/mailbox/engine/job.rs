//! A request on its way from a caller to a slave's owner task, and back.
//!
//! The caller packs the protocol work into a [`Job`] (a closure that runs against the
//! slave's [`Exchange`] inside the engine), queues it on the slave's bounded channel and
//! awaits a oneshot. Only the engine's runtime ever touches the mailbox, so the public async
//! functions work from any executor.
//!
//! Cancellation: dropping the caller's future sets the job's `cancelled` flag (through
//! [`CancelOnDrop`]). The owner skips a job not started yet; a job under way sees the flag
//! at its next safe point and leaves the slave's mailbox clean (it waits for the answer
//! already asked for, and aborts an open multi-message transfer the protocol's way).

use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use tokio::sync::{mpsc, oneshot};

use crate::mailbox::error::{MailboxError, Result};
use crate::wire::mailbox::MailboxType;

use super::exchange::Exchange;
use super::report::Subject;
use super::slave::SlaveMailbox;

/// A boxed future borrowing the exchange.
pub(crate) type BoxFuture<'a, T> = Pin<Box<dyn Future<Output = T> + Send + 'a>>;

type Work = Box<dyn for<'a> FnOnce(&'a mut Exchange) -> BoxFuture<'a, ()> + Send>;

/// One queued request.
pub(crate) struct Job {
    /// The request fails with a timeout once this passes (with progress deadlines: unless
    /// the transfer moved on before).
    pub deadline: Instant,
    /// With progress deadlines: the window of each exchange and the end of the whole request.
    pub progress: Option<(std::time::Duration, Instant)>,
    /// Set when the caller went away.
    pub cancelled: Arc<AtomicBool>,
    work: Work,
}

impl Job {
    /// Runs the job against the exchange (the owner has set the deadline up).
    pub fn run(self, exchange: &mut Exchange) -> BoxFuture<'_, ()> {
        (self.work)(exchange)
    }
}

/// Sets the flag when dropped unless disarmed: the caller's future was dropped.
struct CancelOnDrop(Option<Arc<AtomicBool>>);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        if let Some(flag) = self.0.take() {
            flag.store(true, Ordering::Relaxed);
        }
    }
}

/// Runs `work` on the slave's owner task and returns its result. `protocol` is checked
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
    let (reply, answer) = oneshot::channel();
    let cancelled = Arc::new(AtomicBool::new(false));
    let now = Instant::now();
    let job = Job {
        deadline: now + slave.timeout(),
        progress: slave.progress_cap().map(|cap| (slave.timeout(), now + cap)),
        cancelled: Arc::clone(&cancelled),
        work: Box::new(move |exchange: &mut Exchange| {
            Box::pin(async move {
                // A request whose deadline passed while it waited in the queue is not
                // started: its answer could only arrive after the caller gave up.
                let result = if exchange.expired() {
                    Err(exchange.timeout("its turn at the mailbox"))
                } else {
                    // With progress deadlines the first exchange gets a whole window.
                    exchange.progressed();
                    work(&mut *exchange).await
                };
                if let Err(err) = &result
                    && *err != MailboxError::Cancelled
                {
                    exchange.count_failed();
                    exchange.report_failure(protocol, &subject, err);
                }
                let _ = reply.send(result);
            })
        }),
    };
    match shared.requests.try_send(job) {
        Ok(()) => {}
        Err(mpsc::error::TrySendError::Full(_)) => {
            return Err(MailboxError::QueueFull(shared.config.station));
        }
        Err(mpsc::error::TrySendError::Closed(_)) => return Err(MailboxError::Shutdown),
    }
    let mut guard = CancelOnDrop(Some(cancelled));
    let result = answer.await;
    guard.0 = None;
    result.unwrap_or(Err(MailboxError::Shutdown))
}
