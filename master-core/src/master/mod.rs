//! The master: bring-up of the segment, slave addressing, AL states, register and SII
//! access, the process image, the topology watch and its events.
//!
//! [`Master::start`] takes a [`BusHandle`] and spawns the master's own thread (named
//! `ecat-master`) running a small runtime: every timed step (polling AL status and the
//! EEPROM, timeouts, the watch) runs there, so the public `async fn`s can be awaited from
//! any executor (or driven by a plain `block_on`), and the caller needs no particular
//! runtime. It also installs the process-data exchange as the bus's cyclic task.
//!
//! [`Master::scan`] brings the segment up as the reference capture shows it (spec-notes §bringup):
//! count the slaves (BRD), reset their registers (spec-notes §esc.reset), give each its station address
//! (`station_base + position`), read its ESC information, alias and whole SII, DL status,
//! configure the mailbox SyncManagers from the SII, and move it INIT → PREOP → SAFEOP → OP,
//! with the process-data SyncManagers and FMMUs set from the layout a [`LayoutSource`]
//! gives (CoE through the mailbox by default, the SII for slaves without CoE) and the cyclic LRW running before OP. A
//! slave that refuses a state is reported with its AL status code, and the others go on.
//!
//! Modules, each with one job:
//! - `config`, `error`, `event`, `info`: the public types (settings, errors, events, the
//!   snapshot of one slave);
//! - `record`: what the master keeps of one slave (a leaf module);
//! - `context`: the state the handle, the scan and the watch share;
//! - `diagnostics`: ESC error counters and bus statistics for the server and the master's
//!   dictionary;
//! - `access/`: naming slaves (`address`), single-slave register datagrams (`datagram`),
//!   register/SII/alias access for tools (`tools`, `api`);
//! - `bringup/`: the scan of all slaves (`scan`), one slave's configuration (`configure`),
//!   register reset (`reset`), the SII interface (`eeprom`), AL state changes (`al`),
//!   distributed clocks (`dc`, `dc_settings`), the mailbox engine kept in step (`mailboxes`), the topology
//!   watch (`watch`), the per-slave configuration (`slave_config`: expected identity,
//!   start-up commands, DC; applied by `startup`), and their [`Master`] methods (`api`);
//! - `process_data/`: layouts (`layout`, `coe_layout`), PDO assignments (`pdo_assignment`,
//!   written by `pdo_config`), the
//!   image and cyclic task (`image`), groups (`groups`), named entries and snapshots
//!   (`pd_entry`), bit copying (`bits`), counters (`cycle_stats`), working-counter blame
//!   (`wkc_blame`), mailbox-full bits in the cyclic frame (`mailbox_status`), and their
//!   [`Master`] methods (`api`).
//!
//! This file holds the [`Master`] handle itself: its thread, and the slaves and mailboxes
//! it knows.

mod access;
mod bringup;
mod config;
mod context;
mod diagnostics;
mod error;
mod event;
mod event_log;
mod info;
mod process_data;
mod record;

use std::future::Future;
use std::io;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use tokio::sync::{broadcast, oneshot};

use crate::bus::BusHandle;
use crate::mailbox::{MailboxEngine, SlaveMailbox, SlaveMailboxConfig};

pub use access::address::SlaveAddress;
pub use bringup::dc_settings::{DcSettings, DcSlave};
pub use bringup::safe_state::SafeStateReport;
pub use bringup::scan::ScanReport;
pub use bringup::slave_config::{
    ExpectedIdentity, MismatchPolicy, RevisionMatch, SlaveConfig, SlaveConfigs, SlaveDc,
    StartupAction, StartupCommand, SyncSignal, TopologyProblem, Transition, Watchdog,
};
pub use config::MasterConfig;
pub use error::MasterError;
pub use event::MasterEvent;
pub use info::{Identity, ProcessDataInfo, SlaveInfo};
pub use process_data::coe_layout::CoeLayout;
pub use process_data::cycle_stats::{CycleStats, CycleTiming};
pub use process_data::groups::{GroupStats, SlaveGroup};
pub use process_data::hook::{CompletedCycle, CycleHook, OutgoingImage};
pub use process_data::layout::{
    LayoutFuture, LayoutSource, PdSyncManager, PdoEntryInfo, PdoInfo, ProcessDataLayout, SiiLayout,
};
pub use process_data::pd_entry::{ImageSnapshot, PdEntry};
pub use process_data::pdo_assignment::{PdoAssignment, PdoMapping};

use context::Context;
use process_data::image::{Image, ProcessCycle};
use record::Slaves;

/// An EtherCAT master over a running bus. See the [module documentation](self).
///
/// Dropping it stops its thread (and the watch) and removes its cyclic task from the bus;
/// the slaves stay in the state they are in.
pub struct Master {
    ctx: Arc<Context>,
    runtime: tokio::runtime::Handle,
    stop: Mutex<Option<oneshot::Sender<()>>>,
    thread: Option<JoinHandle<()>>,
    watch: Mutex<Option<tokio::task::AbortHandle>>,
}

impl Master {
    /// Starts a master on `bus` that reads process-data layouts through CoE
    /// ([`CoeLayout`]; the SII for slaves without CoE).
    ///
    /// Fails only if the master's thread or runtime cannot be created.
    pub fn start(bus: BusHandle, config: MasterConfig) -> io::Result<Master> {
        Master::with_layout_source(bus, config, Box::new(CoeLayout))
    }

    /// Starts a master whose process-data layouts come from `source` (e.g. [`SiiLayout`]
    /// to trust the SII even for CoE slaves).
    pub fn with_layout_source(
        bus: BusHandle,
        config: MasterConfig,
        source: Box<dyn LayoutSource>,
    ) -> io::Result<Master> {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .build()?;
        let handle = runtime.handle().clone();
        let image = Arc::new(Image::default());
        let mut mailbox_config = config.mailbox;
        if config.map_mailbox_status {
            // The cyclic frame says which mailboxes have something to read.
            mailbox_config.idle_poll = None;
        }
        let mailboxes = MailboxEngine::start(bus.clone(), mailbox_config)?;
        bus.set_cyclic(Some(Box::new(ProcessCycle::new(
            Arc::clone(&image),
            config.cycle_period,
            mailboxes.clone(),
        ))));
        let (events, _) = broadcast::channel(config.event_capacity.max(1));
        let ctx = Arc::new(Context {
            bus,
            config,
            slaves: Mutex::new(Slaves::default()),
            events,
            event_log: event_log::limit(),
            image,
            layout_source: source,
            pdo_configs: Mutex::new(Vec::new()),
            slave_configs: Mutex::new(Default::default()),
            dc: Mutex::new(Vec::new()),
            mailboxes,
            topology: tokio::sync::Mutex::new(()),
        });
        let (stop, stopped) = oneshot::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("ecat-master".into())
            .spawn(move || {
                // Ends when the master is dropped; dropping the runtime cancels the watch
                // and any request still running.
                runtime.block_on(async {
                    let _ = stopped.await;
                });
            })?;
        let master = Master {
            ctx,
            runtime: handle,
            stop: Mutex::new(Some(stop)),
            thread: Some(thread),
            watch: Mutex::new(None),
        };
        if let Some(interval) = config.watch_interval {
            master.start_watch(interval);
        }
        Ok(master)
    }

    /// Runs `work` on the master's runtime and waits for its result (from any executor).
    async fn run<T, F>(&self, work: F) -> Result<T, MasterError>
    where
        T: Send + 'static,
        F: Future<Output = Result<T, MasterError>> + Send + 'static,
    {
        let (tx, rx) = oneshot::channel();
        self.runtime.spawn(async move {
            let _ = tx.send(work.await);
        });
        rx.await.map_err(|_| MasterError::Stopped)?
    }

    /// Every slave of the last scan, by ring position.
    pub fn slaves(&self) -> Vec<SlaveInfo> {
        self.ctx
            .lock()
            .list
            .iter()
            .map(|r| r.info.clone())
            .collect()
    }

    /// The slave at `address`.
    pub fn slave(&self, address: SlaveAddress) -> Result<SlaveInfo, MasterError> {
        self.ctx.resolve_with(address, |r| r.info.clone())
    }

    /// The station address of the slave at `address` (cheaper than [`Master::slave`]: it
    /// copies nothing of the slave's record).
    pub fn station(&self, address: SlaveAddress) -> Result<u16, MasterError> {
        self.ctx.station(address)
    }

    /// The mailbox of the slave at `address`, with every protocol client on it (CoE, SoE,
    /// FoE, VoE, EoE, raw messages). A slave's mailbox is served from PREOP on; in INIT, or
    /// for a slave without a mailbox, this fails with [`MasterError::NoMailbox`]; for a
    /// slave that did not answer the last look, with [`MasterError::Absent`] (its mailbox
    /// was let go when it was lost, and its last state says nothing of now).
    pub fn mailbox(&self, address: SlaveAddress) -> Result<SlaveMailbox, MasterError> {
        let (present, position, station, al_state) = self.ctx.resolve_with(address, |r| {
            let i = &r.info;
            (i.present, i.position, i.station, i.al_state)
        })?;
        if !present {
            return Err(MasterError::Absent { position, station });
        }
        self.ctx
            .mailboxes
            .slave(station)
            .map_err(|_| MasterError::NoMailbox {
                position,
                state: al_state,
            })
    }

    /// The engine that owns every slave's mailbox (statistics, the mailbox-full hook).
    pub fn mailbox_engine(&self) -> &MailboxEngine {
        &self.ctx.mailboxes
    }

    /// The mailboxes of every slave that has one, for the mailbox engine.
    pub fn mailbox_layouts(&self) -> Vec<SlaveMailboxConfig> {
        self.ctx
            .lock()
            .list
            .iter()
            .filter_map(|r| r.info.mailbox)
            .collect()
    }

    /// A new subscription to the master's events, from now on.
    pub fn events(&self) -> broadcast::Receiver<MasterEvent> {
        self.ctx.events.subscribe()
    }

    /// The bus the master runs on.
    pub fn bus(&self) -> &BusHandle {
        &self.ctx.bus
    }

    /// The configuration.
    pub fn config(&self) -> &MasterConfig {
        &self.ctx.config
    }
}

impl Drop for Master {
    fn drop(&mut self) {
        if let Some(stop) = self.stop.lock().ok().and_then(|mut s| s.take()) {
            let _ = stop.send(());
        }
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
        self.ctx.bus.set_cyclic(None);
    }
}

impl std::fmt::Debug for Master {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Master")
            .field("config", &self.ctx.config)
            .field("slaves", &self.ctx.lock().list.len())
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::register::AlState;

    fn send_sync<T: Send + Sync>(_: &T) {}
    fn send<T: Send>(_: &T) {}

    #[test]
    fn the_master_and_its_futures_can_move_between_threads() {
        let (bus, _thread) = crate::bus::Bus::start(
            crate::link::MemoryLink::pair(1).0,
            crate::bus::BusConfig::default(),
        )
        .unwrap();
        let master = Master::start(bus, MasterConfig::default()).unwrap();
        send_sync(&master);
        send(&master.scan());
        send(&master.read_register(SlaveAddress::Position(0), 0, 1));
        send(&master.set_alias(SlaveAddress::Position(0), 1));
        send(&master.request_state(SlaveAddress::Position(0), AlState::Op));
        send(&master.events());
    }
}
