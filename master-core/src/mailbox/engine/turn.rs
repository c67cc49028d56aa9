//! A turn at a slave's mailbox: whoever works on it (a request, in its caller's future, or the owner task with
//! the side traffic and the idle reads) holds the slave's [`Exchange`] for the whole of one
//! piece of work, so there is still exactly one reader of the slave's send mailbox and one
//! transaction at a time.
//!
//! Turns are taken in the order asked for (tokio's mutex is fair), which gives the
//! alternation the owner used to enforce: a request waits at most one step of the side
//! traffic, and the side traffic at most the requests that queued before it.
//!
//! A turn dropped in the middle of its work (the engine's runtime shut down) leaves the exchange
//! marked interrupted; the next turn settles what was left open before it starts
//! ([`Exchange::recover_interrupted`]).

use std::ops::{Deref, DerefMut};
use std::sync::Arc;

use tokio::sync::{Mutex, OwnedMutexGuard};

use super::exchange::Exchange;

/// The lock every turn at one slave's mailbox goes through.
pub(crate) type Mailbox = Arc<Mutex<Exchange>>;

/// The exchange, held for one piece of work.
pub(crate) struct Turn {
    guard: OwnedMutexGuard<Exchange>,
    finished: bool,
}

impl Turn {
    /// Waits for the mailbox, then clears up after a turn that was interrupted.
    pub async fn take(mailbox: &Mailbox) -> Turn {
        Turn::start(Arc::clone(mailbox).lock_owned().await).await
    }

    /// The mailbox if nobody holds it or waits for it now (then cleared up after a turn
    /// that was interrupted).
    pub async fn try_take(mailbox: &Mailbox) -> Option<Turn> {
        let guard = Arc::clone(mailbox).try_lock_owned().ok()?;
        Some(Turn::start(guard).await)
    }

    /// A turn on the mailbox just locked, after what an interrupted turn left is cleared.
    async fn start(mut guard: OwnedMutexGuard<Exchange>) -> Turn {
        guard.recover_interrupted().await;
        Turn {
            guard,
            finished: false,
        }
    }

    /// The work is done (the exchange is in a clean state): release it as it is.
    pub fn finish(mut self) {
        self.finished = true;
    }
}

impl Drop for Turn {
    fn drop(&mut self) {
        if !self.finished {
            self.guard.interrupted();
        }
    }
}

impl Deref for Turn {
    type Target = Exchange;

    fn deref(&self) -> &Exchange {
        &self.guard
    }
}

impl DerefMut for Turn {
    fn deref_mut(&mut self) -> &mut Exchange {
        &mut self.guard
    }
}
