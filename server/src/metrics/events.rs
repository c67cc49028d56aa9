//! Events by kind (`ecat_events_total{kind}`): a background task follows the merged event
//! stream both APIs serve (topology, AL state, AL errors, CoE emergencies) and counts each
//! event by its `kind`, so an alert sees a burst of slave losses or emergencies without a
//! client on the stream.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use prometheus::proto::{MetricFamily, MetricType};
use tokio::sync::broadcast::error::RecvError;
use tokio::task::JoinHandle;

use super::family::Family;
use crate::service::Core;

/// Events counted by kind.
#[derive(Debug, Default)]
pub struct EventCounts {
    by_kind: Mutex<BTreeMap<String, u64>>,
}

impl EventCounts {
    fn lock(&self) -> MutexGuard<'_, BTreeMap<String, u64>> {
        // Each update is one increment: a poisoned lock still holds valid counts.
        self.by_kind.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Counts one event of `kind`.
    pub fn record(&self, kind: &str) {
        let mut counts = self.lock();
        match counts.get_mut(kind) {
            Some(count) => *count += 1,
            None => {
                counts.insert(kind.to_owned(), 1);
            }
        }
    }

    /// Follows `core`'s event stream until it ends or the handle is aborted. Events the
    /// task fell behind on are counted under `lagged` (one per event missed).
    pub fn start(self: &Arc<Self>, core: &Core) -> JoinHandle<()> {
        let counts = Arc::clone(self);
        let mut events = core.events();
        tokio::spawn(async move {
            loop {
                match events.recv().await {
                    Ok(event) => counts.record(&event.kind),
                    Err(RecvError::Lagged(missed)) => {
                        *counts.lock().entry("lagged".to_owned()).or_default() += missed;
                    }
                    Err(RecvError::Closed) => return,
                }
            }
        })
    }

    /// The family (absent until the first event).
    pub fn collect(&self) -> Vec<Option<MetricFamily>> {
        let counts = self.lock().clone();
        let family = counts.iter().fold(
            Family::new(
                "ecat_events_total",
                "Events on the event stream by kind (slave_found, slave_lost, state_changed, al_error, emergency, ...).",
                MetricType::COUNTER,
            ),
            |family, (kind, n)| family.counter(&[("kind", kind)], *n as f64),
        );
        vec![family.done()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_count_apart() {
        let counts = EventCounts::default();
        counts.record("slave_lost");
        counts.record("slave_lost");
        counts.record("emergency");
        let text = {
            let mut out = Vec::new();
            prometheus::Encoder::encode(
                &prometheus::TextEncoder::new(),
                &counts.collect().into_iter().flatten().collect::<Vec<_>>(),
                &mut out,
            )
            .unwrap();
            String::from_utf8(out).unwrap()
        };
        assert!(
            text.contains("ecat_events_total{kind=\"slave_lost\"} 2\n"),
            "{text}"
        );
        assert!(
            text.contains("ecat_events_total{kind=\"emergency\"} 1\n"),
            "{text}"
        );
    }
}
