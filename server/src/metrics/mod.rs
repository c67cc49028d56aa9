//! Prometheus metrics, read from the master at scrape time (`/metrics`). The names are
//! documented in `docs/metrics.md`.
//!
//! Files: `family` (building families), `bus` (link and cycle), `slaves` (AL states and
//! codes), `mailbox` (per-slave mailbox and EoE counters), `gateway` (the mailbox gateway's
//! statistics), `calls` (ecatd's own mailbox requests per slave and protocol), `esc` (the
//! ESC error counters, read in the background), `events` (events by kind, counted in the
//! background), `state` (ready and link up), `process` (the process' CPU, memory, files),
//! `config` (what the segment's configuration found: mismatches and failed start-up commands),
//! `eoe` (the EoE interfaces), `app` (the application interface), `watch` (the watched
//! values), `connections` (the API servers' connections), `redundancy` (the ring of cable
//! redundancy).

mod app;
mod bus;
pub mod calls;
mod capture;
pub mod config;
mod connections;
mod eoe;
pub mod esc;
pub mod events;
pub(crate) mod family;
mod gateway;
mod mailbox;
mod process;
mod redundancy;
mod slaves;
pub mod state;
mod watch;

use std::sync::Arc;

use prometheus::proto::MetricFamily;
use prometheus::{Encoder, TextEncoder};

use crate::service::Core;
use family::Family;

/// Every family, in a stable order: read from the master through `core`, and from what
/// `store` recorded.
pub fn gather(core: &Core, store: &Store) -> Vec<MetricFamily> {
    let mut families: Vec<Option<MetricFamily>> = vec![build_info()];
    families.extend(state::collect(core, &store.link));
    families.extend(bus::collect(core));
    families.extend(redundancy::collect(core));
    families.extend(slaves::collect(core));
    families.extend(mailbox::collect(core));
    families.extend(eoe::collect(core));
    families.extend(calls::collect(&store.calls));
    families.extend(store.esc.collect());
    crate::watch::refresh_pdo(core, &store.watch);
    families.extend(watch::collect(&store.watch));
    families.extend(store.events.collect());
    families.extend(store.config.collect());
    families.extend(gateway::collect(core));
    families.extend(capture::collect(core));
    families.extend(app::collect(core));
    families.extend(connections::collect(&store.connections));
    families.extend(process::collect());
    families.into_iter().flatten().collect()
}

/// What ecatd records for the metrics itself (the rest is read from the master at scrape
/// time).
#[derive(Debug, Default)]
pub struct Store {
    /// Mailbox requests per slave and protocol (the core records them: hand it this).
    pub calls: Arc<crate::service::calls::MailboxCalls>,
    /// The ESC error counters last read.
    pub esc: Arc<esc::EscCounters>,
    /// The watched values (`[[watch]]`).
    pub watch: Arc<crate::watch::WatchValues>,
    /// Events by kind.
    pub events: Arc<events::EventCounts>,
    /// The segment's link, for `ecat_link_up`.
    pub link: state::Link,
    /// Configuration mismatches and failed start-up commands.
    pub config: Arc<config::ConfigFindings>,
    /// The API servers' connections (`[limits]`): open, refused, timed out.
    pub connections: Arc<crate::connections::ServerStats>,
}

/// The background readers behind the metrics; they stop when this is dropped.
pub struct Background {
    tasks: Vec<tokio::task::JoinHandle<()>>,
}

impl Drop for Background {
    fn drop(&mut self) {
        for task in &self.tasks {
            task.abort();
        }
    }
}

/// Starts the background readers into `store`: the ESC error counters, the event counts
/// and the watched values.
pub fn start(core: &Core, store: &Store, watches: &[crate::watch::WatchSpec]) -> Background {
    let mut tasks = vec![store.esc.start(core.master()), store.events.start(core)];
    tasks.extend(crate::watch::start(core, watches, &store.watch));
    Background { tasks }
}

/// The text exposition format.
pub fn render(core: &Core, store: &Store) -> Result<String, String> {
    let mut out = Vec::new();
    TextEncoder::new()
        .encode(&gather(core, store), &mut out)
        .map_err(|err| err.to_string())?;
    String::from_utf8(out).map_err(|err| err.to_string())
}

fn build_info() -> Option<MetricFamily> {
    Family::new(
        "ecat_build_info",
        "ecatd's version; always 1.",
        prometheus::proto::MetricType::GAUGE,
    )
    .gauge(&[("version", env!("CARGO_PKG_VERSION"))], 1.0)
    .done()
}
