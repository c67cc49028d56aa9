//! What the engine and the handles share about one slave, and the public handle.

use std::any::Any;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, AtomicUsize, Ordering};
use std::time::Duration;

use tokio::sync::{Notify, broadcast, watch};

use crate::mailbox::config::{MailboxConfig, SlaveMailboxConfig};

use super::events::{Emergency, EoeFrame, Events, SoeNotification};
use super::report::LogLimit;
use super::stats::{MailboxStats, Stats};
use super::turn::Mailbox;

/// Shared between the slave's owner task, its exchange and every handle.
pub(crate) struct SlaveShared {
    pub config: SlaveMailboxConfig,
    pub engine: MailboxConfig,
    /// Requests waiting for their turn at the mailbox (not the one under way); at most
    /// [`MailboxConfig::queue_len`].
    pub waiting: AtomicUsize,
    /// The feed of the owner's last run of writes (EoE fragments): a request that comes
    /// takes back the batch that joined it and has not started, so it waits for the batch
    /// under way only ([`SlaveShared::request_waits`]).
    pub run: std::sync::Mutex<Option<crate::bus::ChainFeed>>,
    /// The engine's runtime: where a request whose caller went away finishes its work.
    pub runtime: tokio::runtime::Handle,
    /// The engine stopped: requests that get their turn afterwards are not started.
    pub engine_stop: watch::Receiver<bool>,
    /// The sending end of the side traffic's queue (EoE frames), of a type its protocol
    /// module knows ([`SideTraffic::queue`](super::hook::SideTraffic::queue)).
    pub side_queue: Box<dyn Any + Send + Sync>,
    pub events: Events,
    pub stats: Stats,
    /// Wakes the owner to read the send mailbox now (a "mailbox full" seen elsewhere).
    pub mail: Notify,
    /// Ends the pause of a request waiting for its answer (the same notice).
    pub answer: Notify,
    /// Tells the owner to stop (the slave was removed); requests that get their turn
    /// afterwards are not started.
    pub stop: watch::Sender<bool>,
    /// Counter of the last request written (0 before the first): an owner that replaces
    /// this one on a live mailbox continues the sequence from it.
    pub last_tx: AtomicU8,
    /// Keeps a broken slave from flooding the log with its failures.
    pub log_limit: LogLimit,
    /// The engine's sub-millisecond pauses (the poll back-off).
    pub timer: super::timer::Timer,
}

impl SlaveShared {
    /// Says the send mailbox has something: a request waiting for its answer reads at
    /// once (or after the read under way), and the owner once it is idle. Each notice is
    /// kept for its party if it is busy, which costs at most one read.
    pub fn notify_mail(&self) {
        self.answer.notify_one();
        self.mail.notify_one();
    }

    /// A request now waits for its turn: the batch of writes that joined the owner's run
    /// and has not started is taken back (its fragments are written again in a later
    /// turn), so the request waits for the batch under way only.
    pub fn request_waits(&self) {
        let run = self
            .run
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(feed) = run.as_ref() {
            feed.take_back();
        }
    }

    /// The slave was removed or the engine stopped: requests are not started any more.
    pub fn stopped(&self) -> bool {
        *self.stop.borrow() || *self.engine_stop.borrow()
    }
}

/// A handle on one slave's mailbox: the entry point of every protocol client
/// (`sdo_upload`, `soe_read`, `foe_write`, `voe`, `eoe_send`, `raw`, ...).
///
/// Cheap to clone; usable from any thread and any executor. A request runs inside the
/// caller's own future once it has its turn at the slave's mailbox: one request at a time
/// per slave, in the order called, at most [`MailboxConfig::queue_len`] waiting; requests
/// to different slaves proceed in parallel. A request dropped before it is done finishes
/// on the engine's thread (see the protocol clients on cancellation).
#[derive(Clone)]
pub struct SlaveMailbox {
    shared: Arc<SlaveShared>,
    mailbox: Mailbox,
    timeout: Duration,
    /// With progress deadlines: the cap on the whole request (see
    /// [`SlaveMailbox::with_progress_deadlines`]).
    cap: Option<Duration>,
}

impl std::fmt::Debug for SlaveMailbox {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SlaveMailbox")
            .field("config", &self.shared.config)
            .field("timeout", &self.timeout)
            .field("cap", &self.cap)
            .finish()
    }
}

impl SlaveMailbox {
    pub(crate) fn new(shared: Arc<SlaveShared>, mailbox: Mailbox) -> SlaveMailbox {
        let timeout = shared.engine.timeout;
        SlaveMailbox {
            shared,
            mailbox,
            timeout,
            cap: None,
        }
    }

    pub(crate) fn shared(&self) -> &Arc<SlaveShared> {
        &self.shared
    }

    pub(crate) fn mailbox(&self) -> &Mailbox {
        &self.mailbox
    }

    /// The same handle with another deadline for its requests (counted from each call,
    /// covering queueing and the whole transfer).
    pub fn with_timeout(&self, timeout: Duration) -> SlaveMailbox {
        SlaveMailbox {
            shared: Arc::clone(&self.shared),
            mailbox: Arc::clone(&self.mailbox),
            timeout,
            cap: None,
        }
    }

    /// The same handle with deadlines that follow a transfer's progress: a request may wait
    /// `exchange` for its turn and then `exchange` for each answer, the window starting
    /// again whenever the transfer moves on (an FoE ACK, DATA or BUSY, an SDO segment), and
    /// the whole request ends at the latest `cap` after the call. A multi-megabyte FoE
    /// transfer then runs as long as the slave keeps answering, and a stalled one still
    /// fails after `exchange`.
    pub fn with_progress_deadlines(&self, exchange: Duration, cap: Duration) -> SlaveMailbox {
        SlaveMailbox {
            shared: Arc::clone(&self.shared),
            mailbox: Arc::clone(&self.mailbox),
            timeout: exchange,
            cap: Some(cap.max(exchange)),
        }
    }

    /// The deadline requests through this handle get (with progress deadlines: the window
    /// of each exchange).
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// The cap on a whole request with progress deadlines, `None` without them.
    pub fn progress_cap(&self) -> Option<Duration> {
        self.cap
    }

    /// The slave's station address.
    pub fn station(&self) -> u16 {
        self.shared.config.station
    }

    /// The slave's mailbox configuration.
    pub fn config(&self) -> &SlaveMailboxConfig {
        &self.shared.config
    }

    /// Requests waiting for their turn at the slave's mailbox (not counting the one under
    /// way).
    pub fn queued(&self) -> usize {
        self.shared.waiting.load(Ordering::Relaxed)
    }

    /// The slave's mailbox counters.
    pub fn stats(&self) -> MailboxStats {
        self.shared.stats.snapshot()
    }

    /// The CoE emergencies kept (the last [`MailboxConfig::emergency_history`]), oldest
    /// first.
    pub fn emergencies(&self) -> Vec<Emergency> {
        self.shared.events.emergencies()
    }

    /// Emergencies from now on, as they are read.
    pub fn subscribe_emergencies(&self) -> broadcast::Receiver<Emergency> {
        self.shared.events.emergencies.subscribe()
    }

    /// Ethernet frames the slave sends over EoE from now on, reassembled.
    pub fn subscribe_eoe(&self) -> broadcast::Receiver<EoeFrame> {
        self.shared.events.eoe_frames.subscribe()
    }

    /// SoE notifications from now on.
    pub fn subscribe_soe_notifications(&self) -> broadcast::Receiver<SoeNotification> {
        self.shared.events.soe_notifications.subscribe()
    }

    /// Reads the send mailbox now instead of at the next poll (the process-data path saw
    /// the "mailbox full" bit of SM1).
    pub fn notify_mailbox_full(&self) {
        self.shared.notify_mail();
    }
}
