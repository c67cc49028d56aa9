//! Counters of the mailbox layer, shared with tests through an `Arc` so they can be read
//! while the stack sits inside an emulated ESC.

use std::sync::atomic::{AtomicU64, Ordering};

/// Live counters of one [`super::MailboxStack`].
#[derive(Debug, Default)]
pub struct MailboxStackStats {
    received: AtomicU64,
    replies_posted: AtomicU64,
    errors: AtomicU64,
    duplicates_discarded: AtomicU64,
    dropped: AtomicU64,
    service_faults: AtomicU64,
}

/// A snapshot of [`MailboxStackStats`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MailboxCounters {
    /// Messages handed to the layer by the ESC (valid or not, duplicates included).
    pub received: u64,
    /// Messages (replies, error replies, unsolicited) queued for SM1.
    pub replies_posted: u64,
    /// Mailbox error replies (type 0) among them.
    pub errors: u64,
    /// Requests discarded as repetitions (same non-zero counter as the last accepted).
    pub duplicates_discarded: u64,
    /// Messages lost because the outbox and the layer's backlog were full.
    pub dropped: u64,
    /// Replies a service built wrongly (too large for SM1, refused by a codec); each was
    /// replaced by a mailbox error 0x0007.
    pub service_faults: u64,
}

impl MailboxStackStats {
    /// Reads every counter.
    pub fn snapshot(&self) -> MailboxCounters {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        MailboxCounters {
            received: get(&self.received),
            replies_posted: get(&self.replies_posted),
            errors: get(&self.errors),
            duplicates_discarded: get(&self.duplicates_discarded),
            dropped: get(&self.dropped),
            service_faults: get(&self.service_faults),
        }
    }

    pub(crate) fn count_received(&self) {
        self.received.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn count_posted(&self, is_error: bool) {
        self.replies_posted.fetch_add(1, Ordering::Relaxed);
        if is_error {
            self.errors.fetch_add(1, Ordering::Relaxed);
        }
    }

    pub(crate) fn count_duplicate(&self) {
        self.duplicates_discarded.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn count_dropped(&self) {
        self.dropped.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn count_faults(&self, n: u64) {
        self.service_faults.fetch_add(n, Ordering::Relaxed);
    }
}
