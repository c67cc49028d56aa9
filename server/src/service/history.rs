//! The event history: every event the hub publishes is numbered and stamped with the UTC
//! time here, the last [`CAPACITY`] that are worth keeping stay in memory, and a subscriber
//! can start from any number it saw (`Last-Event-ID`) without a gap or a repeat.
//!
//! Progress ticks (`foe_progress`) and the note that a subscriber fell behind (`lagged`) are
//! live only: they are numbered and sent, not kept.

use std::collections::VecDeque;
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::SystemTime;

use tokio::sync::broadcast;

use super::journal::{Journal, Restored};
use super::view::EventView;

/// Events kept in memory unless `[events] history` says otherwise.
pub const CAPACITY: usize = 10_000;
/// Events a history query answers when it names no limit (REST and gRPC alike).
pub const DEFAULT_LIMIT: usize = 1000;

/// Whether events of `kind` are kept in the history.
fn kept(kind: &str) -> bool {
    !matches!(kind, "foe_progress" | "lagged")
}

/// Which kept events a history query wants; every field narrows it.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct EventFilter {
    /// Published at or after this time.
    pub since: Option<SystemTime>,
    /// Of this kind (`state_changed`, ...).
    pub kind: Option<String>,
    /// Of the slave at this ring position.
    pub position: Option<u16>,
    /// At most this many, the newest.
    pub limit: Option<usize>,
}

/// A history query as a caller asks it: the slave by any name ([`super::Core::event_history`]
/// finds its position).
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct EventQuery {
    /// Published at or after this time.
    pub since: Option<SystemTime>,
    /// Of this kind.
    pub kind: Option<String>,
    /// Of this slave; a position also names a slave lost since.
    pub slave: Option<crate::input::address::SlaveName>,
    /// At most this many, the newest.
    pub limit: Option<usize>,
}

struct Kept {
    at: SystemTime,
    view: EventView,
}

struct Inner {
    last_id: u64,
    kept: VecDeque<Kept>,
}

/// Numbers, stamps, keeps and sends the events; see the [module documentation](self).
pub struct EventLog {
    inner: Mutex<Inner>,
    capacity: usize,
    tx: broadcast::Sender<EventView>,
    journal: Option<Journal>,
}

impl std::fmt::Debug for EventLog {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EventLog")
            .field("capacity", &self.capacity)
            .field("journal", &self.journal.is_some())
            .finish_non_exhaustive()
    }
}

impl EventLog {
    /// A log keeping `capacity` events (at least one) that sends every event on `tx`.
    pub fn new(capacity: usize, tx: broadcast::Sender<EventView>) -> EventLog {
        EventLog::with_journal(capacity, tx, None)
    }

    /// A log that starts from what `journal` held and appends every kept event to it.
    pub fn with_journal(
        capacity: usize,
        tx: broadcast::Sender<EventView>,
        journal: Option<(Journal, Restored)>,
    ) -> EventLog {
        let capacity = capacity.max(1);
        let (journal, restored) = match journal {
            Some((journal, restored)) => (Some(journal), restored),
            None => (None, Restored::default()),
        };
        let skip = restored.events.len().saturating_sub(capacity);
        let kept = restored
            .events
            .into_iter()
            .skip(skip)
            .map(|view| Kept {
                // An unreadable time sorts as the oldest: `since` leaves it out.
                at: humantime::parse_rfc3339(&view.time).unwrap_or(SystemTime::UNIX_EPOCH),
                view,
            })
            .collect();
        EventLog {
            inner: Mutex::new(Inner {
                last_id: restored.last_id,
                kept,
            }),
            capacity,
            tx,
            journal,
        }
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Numbers and stamps `view`, keeps it (unless it is live only) and sends it to the
    /// subscribers.
    pub fn publish(&self, mut view: EventView) {
        let now = SystemTime::now();
        let mut inner = self.lock();
        inner.last_id += 1;
        view.id = inner.last_id;
        view.time = humantime::format_rfc3339_millis(now).to_string();
        if kept(&view.kind) {
            if inner.kept.len() == self.capacity {
                inner.kept.pop_front();
            }
            if let Some(journal) = &self.journal {
                journal.append(&view);
            }
            inner.kept.push_back(Kept {
                at: now,
                view: view.clone(),
            });
        }
        // Sent under the lock, as `replay` subscribes under it: a subscriber that starts
        // from the history sees every event once. Nobody listening is fine.
        let _ = self.tx.send(view);
    }

    /// Events from now on.
    pub fn subscribe(&self) -> broadcast::Receiver<EventView> {
        self.tx.subscribe()
    }

    /// The kept events numbered after `after`, oldest first, and every event from then on.
    pub fn replay(&self, after: u64) -> (Vec<EventView>, broadcast::Receiver<EventView>) {
        let inner = self.lock();
        let live = self.tx.subscribe();
        let past = inner
            .kept
            .iter()
            .filter(|k| k.view.id > after)
            .map(|k| k.view.clone())
            .collect();
        (past, live)
    }

    /// The kept events `filter` wants, oldest first.
    pub fn query(&self, filter: &EventFilter) -> Vec<EventView> {
        let inner = self.lock();
        let wanted = |k: &&Kept| {
            filter.since.is_none_or(|since| k.at >= since)
                && filter
                    .kind
                    .as_deref()
                    .is_none_or(|kind| k.view.kind == kind)
                && filter.position.is_none_or(|p| k.view.position == p)
        };
        let mut found: Vec<EventView> = inner
            .kept
            .iter()
            .rev()
            .filter(wanted)
            .take(filter.limit.unwrap_or(usize::MAX))
            .map(|k| k.view.clone())
            .collect();
        found.reverse();
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn event(kind: &str, position: u16) -> EventView {
        EventView {
            kind: kind.into(),
            position,
            ..EventView::lagged(0)
        }
    }

    #[test]
    fn events_are_numbered_stamped_and_the_oldest_leave_first() {
        let (tx, mut rx) = broadcast::channel(16);
        let log = EventLog::new(3, tx);
        for position in 0..5 {
            log.publish(event("state_changed", position));
        }
        // Live only: numbered and sent, not kept.
        log.publish(event("foe_progress", 9));
        let sent: Vec<EventView> = std::iter::from_fn(|| rx.try_recv().ok()).collect();
        assert_eq!(
            sent.iter().map(|e| e.id).collect::<Vec<_>>(),
            [1, 2, 3, 4, 5, 6]
        );
        assert!(sent.iter().all(|e| e.time.ends_with('Z')), "{sent:?}");
        let kept = log.query(&EventFilter::default());
        assert_eq!(kept.iter().map(|e| e.id).collect::<Vec<_>>(), [3, 4, 5]);
    }

    #[test]
    fn a_query_narrows_by_kind_slave_time_and_keeps_the_newest() {
        let (tx, _rx) = broadcast::channel(16);
        let log = EventLog::new(100, tx);
        log.publish(event("slave_found", 1));
        log.publish(event("state_changed", 1));
        log.publish(event("state_changed", 2));
        log.publish(event("state_changed", 1));
        let ids =
            |filter: EventFilter| -> Vec<u64> { log.query(&filter).iter().map(|e| e.id).collect() };
        let kind = Some("state_changed".to_owned());
        assert_eq!(
            ids(EventFilter {
                kind: kind.clone(),
                ..EventFilter::default()
            }),
            [2, 3, 4]
        );
        assert_eq!(
            ids(EventFilter {
                kind,
                position: Some(1),
                limit: Some(1),
                ..EventFilter::default()
            }),
            [4]
        );
        let later = SystemTime::now() + std::time::Duration::from_secs(60);
        assert!(
            ids(EventFilter {
                since: Some(later),
                ..EventFilter::default()
            })
            .is_empty()
        );
    }

    #[test]
    fn a_replay_then_the_live_stream_misses_nothing_and_repeats_nothing() {
        let (tx, _rx) = broadcast::channel(16);
        let log = EventLog::new(100, tx);
        for position in 0..3 {
            log.publish(event("state_changed", position));
        }
        let (past, mut live) = log.replay(1);
        log.publish(event("slave_lost", 7));
        assert_eq!(past.iter().map(|e| e.id).collect::<Vec<_>>(), [2, 3]);
        assert_eq!(live.try_recv().unwrap().id, 4);
        assert!(live.try_recv().is_err());
    }
}
