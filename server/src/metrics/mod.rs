//! Prometheus metrics, read from the master at scrape time (`/metrics`). The names are
//! documented in `docs/metrics.md`.
//!
//! Files: `family` (building families), `bus` (link and cycle), `slaves` (AL states and
//! codes), `mailbox` (per-slave mailbox and EoE counters), `gateway` (the mailbox gateway's
//! statistics), `calls` (ecatd's own mailbox requests per slave and protocol), `esc` (the
//! ESC error counters, read in the background).

mod bus;
pub mod calls;
pub mod esc;
pub(crate) mod family;
mod gateway;
mod mailbox;
mod slaves;

use std::sync::Arc;

use prometheus::proto::MetricFamily;
use prometheus::{Encoder, TextEncoder};

use crate::service::Core;
use family::Family;

/// Every family, in a stable order.
pub fn gather(core: &Core) -> Vec<MetricFamily> {
    let mut families: Vec<Option<MetricFamily>> = vec![build_info()];
    families.extend(bus::collect(core));
    families.extend(slaves::collect(core));
    families.extend(mailbox::collect(core));
    families.extend(core.metrics().calls.collect());
    families.extend(core.metrics().esc.collect());
    families.extend(core.metrics().watch.collect());
    families.extend(gateway::collect(core));
    families.into_iter().flatten().collect()
}

/// What ecatd records for the metrics itself (the rest is read from the master at scrape
/// time).
#[derive(Debug, Default)]
pub struct Store {
    /// Mailbox requests per slave and protocol.
    pub calls: calls::MailboxCalls,
    /// The ESC error counters last read.
    pub esc: Arc<esc::EscCounters>,
    /// The watched values (`[[watch]]`).
    pub watch: Arc<crate::watch::WatchValues>,
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

/// Starts the background readers: the ESC error counters and the watched values.
pub fn start(core: &Core, watches: &[crate::watch::WatchSpec]) -> Background {
    let mut tasks = vec![core.metrics().esc.start(core.master())];
    tasks.extend(crate::watch::start(core, watches, &core.metrics().watch));
    Background { tasks }
}

/// The text exposition format.
pub fn render(core: &Core) -> Result<String, String> {
    let mut out = Vec::new();
    TextEncoder::new()
        .encode(&gather(core), &mut out)
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
