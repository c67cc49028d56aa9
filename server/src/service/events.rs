//! The one event stream both APIs serve: the master's topology and state events merged with
//! the CoE emergencies of every slave's mailbox.
//!
//! The master publishes its events on one channel, the mailbox engine each slave's
//! emergencies on that slave's own channel, and slaves come and go with scans. One task
//! (started with the first subscriber) follows both: it subscribes to the emergencies of
//! every slave the engine owns, looks again on every master event and at a modest period
//! (a rescan may replace a slave's mailbox without a topology event), and republishes
//! everything as [`EventView`]s through the [`EventLog`], which numbers, stamps and keeps
//! them and sends them on one bounded broadcast channel. The same task looks at the bus's
//! fault counters ([`super::bus_fault`]). On a ring a second task looks at the ring's
//! generation every `RING_POLL` ([`super::redundancy`]): a
//! break must reach the operator within milliseconds, not at the next 200 ms look.

use std::sync::{Arc, Weak};
use std::time::Duration;

use master_core::mailbox::Emergency;
use master_core::master::Master;
use tokio::sync::broadcast;
use tokio::sync::broadcast::error::RecvError;
use tokio::task::JoinHandle;
use tokio_stream::StreamExt;
use tokio_stream::StreamMap;
use tokio_stream::wrappers::BroadcastStream;
use tokio_stream::wrappers::errors::BroadcastStreamRecvError;

use super::bus_fault::FaultWatch;
use super::history::{self, EventLog};
use super::redundancy::{RING_POLL, RingEvents};
use super::view::{EmergencyView, EventView};

/// Events a subscriber may fall behind by before it is told it missed some.
const CAPACITY: usize = 256;
/// How often the set of slaves with a mailbox is looked at between master events.
const RESUBSCRIBE: Duration = Duration::from_millis(200);

/// The merged event stream; the tasks stop when the hub is dropped.
pub struct EventHub {
    log: Arc<EventLog>,
    task: JoinHandle<()>,
    /// The ring's watcher, on a ring only.
    ring: Option<JoinHandle<()>>,
}

impl Drop for EventHub {
    fn drop(&mut self) {
        self.task.abort();
        if let Some(ring) = &self.ring {
            ring.abort();
        }
    }
}

impl EventHub {
    /// Starts following `master` (on the current tokio runtime), keeping the default
    /// history and no journal.
    pub fn start(master: &Arc<Master>) -> EventHub {
        let (tx, _) = broadcast::channel(CAPACITY);
        EventHub::start_with(master, EventLog::new(history::CAPACITY, tx))
    }

    /// Starts following `master` with the history and journal of `settings` (the journal
    /// read back first).
    pub fn start_configured(
        master: &Arc<Master>,
        settings: &crate::config::events::EventSettings,
    ) -> Result<EventHub, String> {
        let (tx, _) = broadcast::channel(CAPACITY);
        let journal = super::journal::Journal::open(settings)?;
        if let Some((_, restored)) = &journal {
            tracing::info!(
                events = restored.events.len(),
                last_id = restored.last_id,
                skipped_lines = restored.skipped,
                "event journal read"
            );
        }
        Ok(EventHub::start_with(
            master,
            EventLog::with_journal(settings.history, tx, journal),
        ))
    }

    fn start_with(master: &Arc<Master>, log: EventLog) -> EventHub {
        let log = Arc::new(log);
        let weak = Arc::downgrade(master);
        // Subscribed before the first subscriber gets its receiver: an emergency raised
        // right after subscribing is not missed.
        let mut emergencies = Emergencies::new();
        subscribe_new(&weak, &mut emergencies);
        let task = tokio::spawn(follow(weak, master.events(), emergencies, Arc::clone(&log)));
        let ring = master.bus().ring().map(|watch| {
            tokio::spawn(follow_ring(
                RingEvents::new(watch.clone()),
                Arc::clone(&log),
            ))
        });
        EventHub { log, task, ring }
    }

    /// The history and the stream: where the service layer publishes events of its own
    /// (FoE progress, the application interface's), and where subscribers start.
    pub fn log(&self) -> &Arc<EventLog> {
        &self.log
    }
}

/// Publishes the ring's changes; a look is one atomic load unless the ring changed.
async fn follow_ring(mut ring: RingEvents, log: Arc<EventLog>) {
    let mut look = tokio::time::interval(RING_POLL);
    // A late look catches up once, not with a burst of looks.
    look.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        look.tick().await;
        if let Some(view) = ring.look() {
            log.publish(view);
        }
    }
}

type Emergencies = StreamMap<u16, BroadcastStream<Emergency>>;

async fn follow(
    master: Weak<Master>,
    mut events: broadcast::Receiver<master_core::master::MasterEvent>,
    mut emergencies: Emergencies,
    log: Arc<EventLog>,
) {
    let mut look = tokio::time::interval(RESUBSCRIBE);
    look.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut faults = match master.upgrade() {
        Some(master) => FaultWatch::new(&master.bus().stats()),
        None => return,
    };
    loop {
        tokio::select! {
            event = events.recv() => {
                let view = match event {
                    Ok(event) => EventView::from(&event),
                    Err(RecvError::Lagged(missed)) => EventView::lagged(missed),
                    Err(RecvError::Closed) => return,
                };
                log.publish(view);
                if !subscribe_new(&master, &mut emergencies) {
                    return;
                }
            }
            Some((station, item)) = emergencies.next(), if !emergencies.is_empty() => {
                let view = match item {
                    Ok(emergency) => match master.upgrade() {
                        Some(master) => emergency_view(&master, &emergency),
                        None => return,
                    },
                    Err(BroadcastStreamRecvError::Lagged(missed)) => {
                        let mut view = EventView::lagged(missed);
                        view.station = station;
                        view
                    }
                };
                log.publish(view);
            }
            _ = look.tick() => {
                if !subscribe_new(&master, &mut emergencies) {
                    return;
                }
                if let Some(master) = master.upgrade()
                    && let Some(view) = faults.look(&master.bus().stats())
                {
                    log.publish(view);
                }
            }
        }
    }
}

/// Subscribes to the emergencies of every slave the engine owns that has no subscription
/// (new slaves, and replaced mailboxes whose old channel closed and left the map). False
/// once the master is gone.
fn subscribe_new(master: &Weak<Master>, emergencies: &mut Emergencies) -> bool {
    let Some(master) = master.upgrade() else {
        return false;
    };
    let engine = master.mailbox_engine();
    for station in engine.stations() {
        if emergencies.contains_key(&station) {
            continue;
        }
        if let Ok(mailbox) = engine.slave(station) {
            emergencies.insert(
                station,
                BroadcastStream::new(mailbox.subscribe_emergencies()),
            );
        }
    }
    true
}

/// The event for an emergency, with the slave's position and name from the last scan.
fn emergency_view(master: &Master, emergency: &Emergency) -> EventView {
    let slave = master
        .slaves()
        .into_iter()
        .find(|s| s.station == emergency.station);
    let data = hex::encode(emergency.data);
    let mut view = EventView::lagged(0);
    view.kind = "emergency".into();
    view.position = slave.as_ref().map_or(0, |s| s.position);
    view.station = emergency.station;
    view.name = slave.map(|s| s.name).unwrap_or_default();
    view.text = format!(
        "emergency {:#06x}, error register {:#04x}, data {data}",
        emergency.error_code, emergency.error_register
    );
    view.emergency = Some(EmergencyView {
        error_code: emergency.error_code,
        error_register: emergency.error_register,
        data,
    });
    view
}
