//! What the segment's configuration found at bring-up, counted from the master's events:
//! `ecat_slave_config_mismatch_total{station,problem}` (slaves not the ones configured, missing,
//! or extra) and `ecat_slave_startup_failures_total{station}` (start-up commands that
//! failed). Subscribed before the start-up scan, so its findings are counted too.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, PoisonError};

use prometheus::proto::{MetricFamily, MetricType};
use tokio::sync::broadcast::error::RecvError;

use master_core::master::{Master, MasterEvent, TopologyProblem};

use super::family::Family;

/// The counts, by station and problem.
#[derive(Debug, Default)]
pub struct ConfigFindings {
    mismatches: Mutex<BTreeMap<(u16, &'static str), u64>>,
    startup_failures: Mutex<BTreeMap<u16, u64>>,
}

impl ConfigFindings {
    /// Counts the configuration events of `master` from now on, until the master stops.
    pub fn follow(self: &Arc<Self>, master: &Master) -> tokio::task::JoinHandle<()> {
        let mut events = master.events();
        let findings = Arc::clone(self);
        tokio::spawn(async move {
            loop {
                match events.recv().await {
                    Ok(event) => findings.count(&event),
                    Err(RecvError::Lagged(_)) => continue,
                    Err(RecvError::Closed) => break,
                }
            }
        })
    }

    fn count(&self, event: &MasterEvent) {
        match event {
            MasterEvent::TopologyMismatch {
                station, problem, ..
            } => {
                let kind = match problem {
                    TopologyProblem::Mismatch { .. } => "identity",
                    TopologyProblem::Missing { .. } => "missing",
                    TopologyProblem::Extra { .. } => "extra",
                };
                *self
                    .mismatches
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .entry((*station, kind))
                    .or_default() += 1;
            }
            MasterEvent::StartupFailed { station, .. } => {
                *self
                    .startup_failures
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .entry(*station)
                    .or_default() += 1;
            }
            _ => {}
        }
    }

    /// The families.
    pub fn collect(&self) -> Vec<Option<MetricFamily>> {
        let mut mismatch = Family::new(
            "ecat_slave_config_mismatch_total",
            "Times a slave was found not to be the one configured (identity), a configured \
             slave was missing, or a slave was not configured (extra).",
            MetricType::COUNTER,
        );
        for ((station, problem), n) in self
            .mismatches
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .iter()
        {
            mismatch = mismatch.counter(
                &[("station", &station.to_string()), ("problem", problem)],
                *n as f64,
            );
        }
        let mut failures = Family::new(
            "ecat_slave_startup_failures_total",
            "Start-up commands that failed, by slave.",
            MetricType::COUNTER,
        );
        for (station, n) in self
            .startup_failures
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .iter()
        {
            failures = failures.counter(&[("station", &station.to_string())], *n as f64);
        }
        vec![mismatch.done(), failures.done()]
    }
}
