//! The task that owns one slave's mailbox: takes requests from the slave's queue one at a
//! time, sends the side traffic (EoE frames) in turns with them, and reads the send mailbox
//! for what the slave sends on its own.
//!
//! Turns: after a request, one message of the side traffic goes before the next request,
//! so neither a stream of requests nor a full EoE queue holds the other up (a request waits
//! at most one fragment). Reads are driven by demand: an idle read that found something is
//! followed by another at once, so a slave streaming frames is served as fast as the bus
//! allows; only an empty read falls back to the idle poll interval.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Instant;

use tokio::sync::{mpsc, watch};

use crate::bus::BusHandle;

use super::exchange::Exchange;
use super::hook::{Background, Reassembly};
use super::job::Job;
use super::slave::SlaveShared;
use super::stats::inc;

/// What the owner task receives.
pub(crate) struct Inputs {
    pub requests: mpsc::Receiver<Job>,
    /// The side traffic sent while no request waits (EoE frames).
    pub background: Box<dyn Background>,
    /// Where the messages routed to the side traffic go (EoE fragments).
    pub reassembly: Box<dyn Reassembly>,
    pub stop: watch::Receiver<bool>,
    pub engine_stop: watch::Receiver<bool>,
}

/// Runs until the slave is removed or the engine stops. Requests still queued then are
/// dropped, which their callers see as [`MailboxError::Shutdown`](crate::mailbox::MailboxError::Shutdown).
pub(crate) async fn run(shared: Arc<SlaveShared>, bus: BusHandle, inputs: Inputs) {
    let Inputs {
        mut requests,
        background: mut side,
        reassembly,
        mut stop,
        mut engine_stop,
    } = inputs;
    let mut exchange = Exchange::new(Arc::clone(&shared), bus, reassembly);
    let idle_poll = shared.engine.idle_poll;
    let mut next_poll = Instant::now();
    // The last idle read found something: the slave may have more, read again at once.
    let mut reading = false;
    // A request just ran: the side traffic has the next turn if it has work.
    let mut side_turn = false;
    loop {
        if *stop.borrow() || *engine_stop.borrow() {
            break;
        }
        if !side.busy() {
            side.try_start();
        }
        if side_turn && side.busy() {
            side_turn = false;
            side.step(&mut exchange).await;
            continue;
        }
        match requests.try_recv() {
            Ok(job) => {
                run_job(&mut exchange, job).await;
                side_turn = true;
                continue;
            }
            Err(mpsc::error::TryRecvError::Disconnected) => break,
            Err(mpsc::error::TryRecvError::Empty) => {}
        }
        if side.busy() {
            // One fragment, then the request queue is looked at again.
            side.step(&mut exchange).await;
            continue;
        }
        let now = Instant::now();
        if reading || (idle_poll.is_some() && now >= next_poll) {
            // A failed idle read (the slave unplugged, say) is retried at the next poll.
            reading = matches!(exchange.poll_idle().await, Ok(true));
            if let Some(interval) = idle_poll {
                next_poll = Instant::now() + interval;
            }
            continue;
        }
        let sleep = tokio::time::sleep_until(next_poll.into());
        tokio::select! {
            biased;
            changed = stop.changed() => if changed.is_err() { break },
            changed = engine_stop.changed() => if changed.is_err() { break },
            job = requests.recv() => match job {
                Some(job) => {
                    run_job(&mut exchange, job).await;
                    side_turn = true;
                }
                None => break,
            },
            () = side.start_next(), if !side.busy() => {},
            () = shared.mail.notified() => {
                reading = matches!(exchange.poll_idle().await, Ok(true));
            },
            () = sleep, if idle_poll.is_some() => {}
        }
    }
    requests.close();
    side.close();
}

async fn run_job(exchange: &mut Exchange, job: Job) {
    inc(&exchange.stats().requests);
    if job.cancelled.load(Ordering::Relaxed) {
        // Not started: nothing to clean up. Dropping the job drops its reply channel.
        exchange.count_cancelled();
        return;
    }
    exchange.begin(job.deadline, job.progress, Some(Arc::clone(&job.cancelled)));
    job.run(exchange).await;
    if exchange.cancelled() {
        exchange.count_cancelled();
    }
    exchange.end().await;
}
