//! The task that looks after one slave's mailbox between requests: it sends the side
//! traffic (EoE frames) and reads the send mailbox for what the slave sends on its own,
//! each piece of work in a turn of its own ([`super::turn`]). Requests do not pass through
//! it: they take their turns from their own tasks ([`super::job`]).
//!
//! Turns: the owner asks for a turn per step of the side traffic (EoE fragments in batches
//! of four, `eoe::tx::CHAIN`, that go on while no request waits, up to `eoe::tx::TURN`) and
//! asks again at once while it has more, so turns alternate with a stream of requests: a
//! request waits for the batch under way (it takes back one that joined and has not
//! started), and a full EoE queue at most the requests queued before it. Reads are
//! driven by demand: an idle read that found something is followed by another at once, so a
//! slave streaming frames is served as fast as the bus allows; only an empty read falls
//! back to the idle poll interval.
//!
//! A "mailbox full" notice (the SM1 status bit in the cyclic frame) is taken only if the
//! mailbox is free: while a request holds it, that request reads SM1 itself (what it finds
//! is routed), and queueing behind it would only add an empty read and a wake-up of this
//! thread between it and the next request. The notices repeat every cycle while SM1 stays
//! full, so a message that arrives after the request's last read is taken at the next one.

use std::sync::Arc;
use std::time::Instant;

use tokio::sync::watch;

use super::hook::Background;
use super::slave::SlaveShared;
use super::turn::{Mailbox, Turn};

/// What the owner task receives.
pub(crate) struct Inputs {
    /// The slave's mailbox, shared with the requests' tasks.
    pub mailbox: Mailbox,
    /// The side traffic sent while no request waits (EoE frames).
    pub background: Box<dyn Background>,
    pub stop: watch::Receiver<bool>,
    pub engine_stop: watch::Receiver<bool>,
}

/// Runs until the slave is removed or the engine stops. Requests still waiting for their
/// turn then are not started, which their callers see as
/// [`MailboxError::Shutdown`](crate::mailbox::MailboxError::Shutdown).
pub(crate) async fn run(shared: Arc<SlaveShared>, inputs: Inputs) {
    let Inputs {
        mailbox,
        background: mut side,
        mut stop,
        mut engine_stop,
    } = inputs;
    let idle_poll = shared.engine.idle_poll;
    let mut next_poll = Instant::now();
    // The last idle read found something: the slave may have more, read again at once.
    let mut reading = false;
    loop {
        if *stop.borrow() || *engine_stop.borrow() {
            break;
        }
        if !side.busy() {
            side.try_start();
        }
        if side.busy() {
            // One fragment per turn; the requests queued meanwhile go first.
            let mut turn = Turn::take(&mailbox).await;
            side.step(&mut turn).await;
            turn.finish();
            continue;
        }
        let now = Instant::now();
        if reading || (idle_poll.is_some() && now >= next_poll) {
            reading = idle_read(Turn::take(&mailbox).await).await;
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
            () = side.start_next() => {},
            () = shared.mail.notified() => {
                if let Some(turn) = Turn::try_take(&mailbox).await {
                    reading = idle_read(turn).await;
                }
            }
            () = sleep, if idle_poll.is_some() => {}
        }
    }
    side.close();
}

/// One read of the send mailbox in a turn of its own; whether it found something (a failed
/// read, the slave unplugged say, is retried at the next poll).
async fn idle_read(mut turn: Turn) -> bool {
    let found = matches!(turn.poll_idle().await, Ok(true));
    turn.finish();
    found
}
