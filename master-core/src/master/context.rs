//! What the master's public handle, its scan and its watch share.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use tokio::sync::broadcast;

use crate::bus::BusHandle;
use crate::mailbox::MailboxEngine;

use crate::log_limit::LogLimit;
use crate::master::access::address::{self, SlaveAddress};
use crate::master::bringup::dc_settings::DcSlave;
use crate::master::bringup::slave_config::{SlaveConfig, SlaveConfigs};
use crate::master::config::MasterConfig;
use crate::master::error::MasterError;
use crate::master::event::MasterEvent;
use crate::master::event_log;
use crate::master::info::SlaveInfo;
use crate::master::process_data::image::Image;
use crate::master::process_data::layout::LayoutSource;
use crate::master::process_data::pdo_assignment::{PdoAssignment, SlavePdoConfig};

use crate::master::record::{SlaveRecord, Slaves};

/// Shared by everything in the master. The lock is never held across an `.await`.
pub(crate) struct Context {
    pub bus: BusHandle,
    pub config: MasterConfig,
    pub slaves: Mutex<Slaves>,
    pub events: broadcast::Sender<MasterEvent>,
    /// The bucket of the events' log lines (`event_log`).
    pub event_log: LogLimit,
    pub image: Arc<Image>,
    pub layout_source: Box<dyn LayoutSource>,
    /// What the last scan measured and set on DC slaves.
    pub dc: Mutex<Vec<DcSlave>>,
    /// PDO assignments to write in PREOP, by slave.
    pub pdo_configs: Mutex<Vec<SlavePdoConfig>>,
    /// Expected identities, start-up commands and DC settings, by slave.
    pub slave_configs: Mutex<SlaveConfigs>,
    /// Owns the mailbox of every slave in PREOP or above (see `mailboxes`).
    pub mailboxes: MailboxEngine,
    /// Serialises scans and the watch's repairs, so they never configure the same slave at
    /// once (a tokio mutex: it is held across the awaits of a whole scan).
    pub topology: tokio::sync::Mutex<()>,
}

impl Context {
    pub fn lock(&self) -> MutexGuard<'_, Slaves> {
        self.slaves.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Reports `event`; nobody listening is fine.
    pub fn emit(&self, event: MasterEvent) {
        event_log::log(&self.event_log, &event);
        let _ = self.events.send(event);
    }

    /// The record of the slave at `address`.
    pub fn resolve(&self, address: SlaveAddress) -> Result<SlaveRecord, MasterError> {
        self.resolve_with(address, SlaveRecord::clone)
    }

    /// What `read` takes from the record of the slave at `address`, under the lock: a
    /// request that needs a station address or a few fields does not copy the whole record
    /// (its SII image and PDO layout are dozens of allocations, per request on the
    /// gateway's path).
    pub fn resolve_with<R>(
        &self,
        address: SlaveAddress,
        read: impl FnOnce(&SlaveRecord) -> R,
    ) -> Result<R, MasterError> {
        let slaves = self.lock();
        address::resolve(
            address,
            slaves.list.iter().map(|s| {
                let i = &s.info;
                (s, i.position, i.station, i.alias)
            }),
        )
        .map(read)
        .ok_or(MasterError::UnknownSlave(address))
    }

    /// The station address of the slave at `address`.
    pub fn station(&self, address: SlaveAddress) -> Result<u16, MasterError> {
        self.resolve_with(address, |r| r.info.station)
    }

    /// Changes the record at `position` (if there is one).
    pub fn update(&self, position: u16, change: impl FnOnce(&mut SlaveRecord)) {
        if let Some(record) = self.lock().list.get_mut(usize::from(position)) {
            change(record);
        }
    }

    /// The configured PDO assignment of the slave of `info`, if any.
    pub fn pdo_config_for(&self, info: &SlaveInfo) -> Option<Vec<PdoAssignment>> {
        self.pdo_configs
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .iter()
            .find(|c| c.names(info))
            .map(|c| c.assignments.clone())
    }

    /// The configuration entry of the slave of `info`, if any.
    pub fn slave_config_for(&self, info: &SlaveInfo) -> Option<SlaveConfig> {
        self.slave_configs
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .for_slave(info)
            .cloned()
    }

    /// The record at `position`.
    pub fn record(&self, position: u16) -> Option<SlaveRecord> {
        self.lock().list.get(usize::from(position)).cloned()
    }
}
