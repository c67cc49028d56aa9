//! The [`Master`] methods that bring slaves up and keep them up: the scan, AL state
//! requests, the topology watch, and what the scan measured of distributed clocks.

use std::sync::{Arc, PoisonError};
use std::time::Duration;

use crate::master::{DcSlave, Master, MasterError, ScanReport, SlaveAddress};
use crate::wire::register::AlState;

use super::{configure, scan, watch};

impl Master {
    /// Starts the topology watch with `interval` between looks, replacing a running one.
    /// It does nothing until a scan has found slaves.
    pub fn start_watch(&self, interval: Duration) {
        let task = self
            .runtime
            .spawn(watch::watch(Arc::clone(&self.ctx), interval));
        let old = self
            .watch
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .replace(task.abort_handle());
        if let Some(old) = old {
            old.abort();
        }
    }

    /// Stops the topology watch (a look in progress ends at its next await).
    pub fn stop_watch(&self) {
        let old = self
            .watch
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .take();
        if let Some(old) = old {
            old.abort();
        }
    }

    /// Whether the topology watch is running.
    pub fn watching(&self) -> bool {
        self.watch
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .as_ref()
            .is_some_and(|task| !task.is_finished())
    }

    /// Scans the segment and brings every slave to [`MasterConfig::target_state`](crate::master::MasterConfig::target_state)
    /// (everything the scan knew before is forgotten). Fails only if the segment cannot be
    /// counted, reset or identified; slaves that refuse a state are listed in
    /// [`ScanReport::failures`] while the others carry on.
    pub async fn scan(&self) -> Result<ScanReport, MasterError> {
        let ctx = Arc::clone(&self.ctx);
        self.run(scan::scan(ctx)).await
    }

    /// [`Master::scan`] that stops at its next await when the returned future is dropped
    /// (a shutdown during the start-up scan): the segment is then left half configured, to
    /// be brought down with [`Master::all_to_safe`].
    pub async fn scan_cancellable(&self) -> Result<ScanReport, MasterError> {
        struct AbortOnDrop(tokio::task::AbortHandle);
        impl Drop for AbortOnDrop {
            fn drop(&mut self) {
                self.0.abort();
            }
        }
        let task = self.runtime.spawn(scan::scan(Arc::clone(&self.ctx)));
        let _abort = AbortOnDrop(task.abort_handle());
        task.await.map_err(|_| MasterError::Stopped)?
    }

    /// Moves the slave at `address` to `state` (through the states in between) and keeps it
    /// there: the watch restores this state after a power cycle.
    pub async fn request_state(
        &self,
        address: SlaveAddress,
        state: AlState,
    ) -> Result<(), MasterError> {
        if matches!(state, AlState::Unknown(_)) {
            return Err(MasterError::InvalidState(state));
        }
        let ctx = Arc::clone(&self.ctx);
        self.run(async move {
            let _topology = ctx.topology.lock().await;
            let mut record = ctx.resolve(address)?;
            ctx.update(record.info.position, |r| r.info.requested_state = state);
            record.info.requested_state = state;
            configure::bring_to(&ctx, &record, state).await
        })
        .await
    }

    /// Looks at the segment once, as the watch does at every tick (for callers that run
    /// without a watch, or want a look now).
    pub async fn check_topology(&self) -> Result<(), MasterError> {
        let ctx = Arc::clone(&self.ctx);
        self.run(async move { watch::look(&ctx).await }).await
    }

    /// Sets the per-slave configuration (expected identities, start-up commands, DC) the
    /// master applies from the next scan on and at every bring-up after it (a power cycle,
    /// a hot-plug): see [`SlaveConfigs`](crate::master::SlaveConfigs).
    pub fn set_slave_configs(&self, configs: crate::master::SlaveConfigs) {
        *self
            .ctx
            .slave_configs
            .lock()
            .unwrap_or_else(PoisonError::into_inner) = configs;
    }

    /// The per-slave configuration in force ([`Master::set_slave_configs`]).
    pub fn slave_configs(&self) -> crate::master::SlaveConfigs {
        self.ctx
            .slave_configs
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// The DC slaves of the last scan with their measured delays and offsets, the
    /// reference clock first (empty without DC).
    pub fn dc_slaves(&self) -> Vec<DcSlave> {
        self.ctx
            .dc
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// The reference clock's system time (ns since 2000) as the last cycle read it.
    pub fn dc_reference_time(&self) -> Option<u64> {
        self.ctx.image.dc_time()
    }
}
