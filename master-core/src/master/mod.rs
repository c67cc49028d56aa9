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
//! Files: `config`, `error`, `address` (naming slaves), `info` (the snapshot type),
//! `event`, `access` (single-slave register access), `eeprom` (the SII interface), `al`
//! (state changes), `reset`, `layout` (process-data sources), `image` (process image and
//! cyclic task), `configure` (one slave), `scan` (all slaves), `watch` (topology changes),
//! `tools` (register/SII/alias access), `context` (shared state).

mod access;
mod address;
mod al;
mod bits;
mod coe_layout;
mod config;
mod configure;
mod context;
mod cycle_stats;
mod dc;
mod eeprom;
mod error;
mod event;
mod groups;
mod image;
mod info;
mod layout;
mod mailbox_status;
mod mailboxes;
mod pd_entry;
mod pdo_config;
mod reset;
mod scan;
mod tools;
mod watch;
mod wkc_blame;

use std::future::Future;
use std::io;
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use tokio::sync::{broadcast, oneshot};

use crate::bus::BusHandle;
use crate::mailbox::{MailboxEngine, SlaveMailbox};
use crate::wire::register::AlState;

pub use address::SlaveAddress;
pub use coe_layout::CoeLayout;
pub use config::MasterConfig;
pub use cycle_stats::{CycleStats, CycleTiming};
pub use dc::{DcSettings, DcSlave};
pub use error::MasterError;
pub use event::MasterEvent;
pub use groups::{GroupStats, SlaveGroup};
pub use info::{Identity, MailboxLayout, ProcessDataInfo, SlaveInfo};
pub use layout::{
    LayoutFuture, LayoutSource, PdSyncManager, PdoEntryInfo, PdoInfo, ProcessDataLayout, SiiLayout,
};
pub use pd_entry::{ImageSnapshot, PdEntry};
pub use pdo_config::{PdoAssignment, PdoMapping};
pub use scan::ScanReport;

use context::{Context, Slaves};
use cycle_stats::CycleCounters;
use image::{Image, ProcessCycle};

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
            image,
            layout_source: source,
            pdo_configs: Mutex::new(Vec::new()),
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

    /// Scans the segment and brings every slave to [`MasterConfig::target_state`]
    /// (everything the scan knew before is forgotten). Fails only if the segment cannot be
    /// counted, reset or identified; slaves that refuse a state are listed in
    /// [`ScanReport::failures`] while the others carry on.
    pub async fn scan(&self) -> Result<ScanReport, MasterError> {
        let ctx = Arc::clone(&self.ctx);
        self.run(scan::scan(ctx)).await
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
        self.ctx.resolve(address).map(|r| r.info)
    }

    /// The process-data SyncManagers of the slave at `address` (empty until a scan brought it
    /// to PREOP and made the layout).
    pub fn process_data_layout(
        &self,
        address: SlaveAddress,
    ) -> Result<ProcessDataLayout, MasterError> {
        self.ctx.resolve(address).map(|r| r.layout)
    }

    /// Configures the PDO assignment of the slave `address` names (by position, station
    /// or alias): from the next scan on, and whenever the slave goes from PREOP to SAFEOP
    /// after a power cycle, the master writes it through CoE in PREOP (clear 0x1C1n:00,
    /// rewrite the mappings that come with entries, write the PDOs, write the count) and
    /// lays the slave's process data out as the slave then reports it. An empty
    /// `assignments` removes the configuration (the slave's own assignment is kept from
    /// its next power cycle on).
    pub fn set_pdo_assignment(&self, address: SlaveAddress, assignments: Vec<PdoAssignment>) {
        let mut configs = self
            .ctx
            .pdo_configs
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        configs.retain(|c| c.address != address);
        if !assignments.is_empty() {
            configs.push(pdo_config::SlavePdoConfig {
                address,
                assignments,
            });
        }
    }

    /// The PDO assignment configured for `address` ([`Master::set_pdo_assignment`]).
    pub fn pdo_assignment(&self, address: SlaveAddress) -> Option<Vec<PdoAssignment>> {
        self.ctx
            .pdo_configs
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .iter()
            .find(|c| c.address == address)
            .map(|c| c.assignments.clone())
    }

    /// The SII image of the slave at `address` as the scan (or the watch) read it; see
    /// [`Master::read_sii`] for a fresh read.
    pub fn sii_image(&self, address: SlaveAddress) -> Result<Vec<u8>, MasterError> {
        self.ctx.resolve(address).map(|r| r.sii)
    }

    /// The mailbox of the slave at `address`, with every protocol client on it (CoE, SoE,
    /// FoE, VoE, EoE, raw messages). A slave's mailbox is served from PREOP on; in INIT, or
    /// for a slave without a mailbox, this fails with [`MasterError::NoMailbox`].
    pub fn mailbox(&self, address: SlaveAddress) -> Result<SlaveMailbox, MasterError> {
        let info = self.ctx.resolve(address)?.info;
        self.ctx
            .mailboxes
            .slave(info.station)
            .map_err(|_| MasterError::NoMailbox {
                position: info.position,
                state: info.al_state,
            })
    }

    /// The engine that owns every slave's mailbox (statistics, the mailbox-full hook).
    pub fn mailbox_engine(&self) -> &MailboxEngine {
        &self.ctx.mailboxes
    }

    /// The mailboxes of every slave that has one, for the mailbox engine.
    pub fn mailbox_layouts(&self) -> Vec<MailboxLayout> {
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

    /// Reads `len` bytes at register `ado` of the slave at `address`.
    pub async fn read_register(
        &self,
        address: SlaveAddress,
        ado: u16,
        len: usize,
    ) -> Result<Vec<u8>, MasterError> {
        let ctx = Arc::clone(&self.ctx);
        self.run(async move { tools::read_register(&ctx, address, ado, len).await })
            .await
    }

    /// Writes `data` at register `ado` of the slave at `address`.
    pub async fn write_register(
        &self,
        address: SlaveAddress,
        ado: u16,
        data: &[u8],
    ) -> Result<(), MasterError> {
        let ctx = Arc::clone(&self.ctx);
        let data = data.to_vec();
        self.run(async move { tools::write_register(&ctx, address, ado, data).await })
            .await
    }

    /// Reads the whole SII image of the slave at `address` (from the slave, not a cache).
    pub async fn read_sii(&self, address: SlaveAddress) -> Result<Vec<u8>, MasterError> {
        let ctx = Arc::clone(&self.ctx);
        self.run(async move { tools::read_sii(&ctx, address).await })
            .await
    }

    /// Writes SII words from word `start` on. The checksum (word 7) is not touched; use
    /// [`Master::set_alias`] for the alias.
    pub async fn write_sii(
        &self,
        address: SlaveAddress,
        start: u16,
        words: &[u16],
    ) -> Result<(), MasterError> {
        let ctx = Arc::clone(&self.ctx);
        let words = words.to_vec();
        self.run(async move { tools::write_sii(&ctx, address, start, &words).await })
            .await
    }

    /// Sets the station alias of the slave at `address` in its SII (word 4, checksum in
    /// word 7 kept valid) and in its alias register (EEPROM reload), so that it is
    /// reachable as [`SlaveAddress::Alias`] at once and after a power cycle. Returns the
    /// alias register read back.
    pub async fn set_alias(&self, address: SlaveAddress, alias: u16) -> Result<u16, MasterError> {
        let ctx = Arc::clone(&self.ctx);
        self.run(async move { tools::set_alias(&ctx, address, alias).await })
            .await
    }

    /// Writes `data` into the outputs of the slave at `address`, from byte `offset` of its
    /// outputs on; the next cycle sends them.
    pub fn write_outputs(
        &self,
        address: SlaveAddress,
        offset: usize,
        data: &[u8],
    ) -> Result<(), MasterError> {
        let pd = self.ctx.resolve(address)?.info.process_data;
        let end = offset.checked_add(data.len());
        if end.is_none_or(|end| end > usize::from(pd.outputs)) {
            return Err(MasterError::InvalidArgument(
                "outputs beyond the slave's process data",
            ));
        }
        let at = pd.outputs_offset as usize + offset;
        if self.ctx.image.write(at, data) {
            Ok(())
        } else {
            Err(MasterError::InvalidArgument(
                "outputs beyond the process image",
            ))
        }
    }

    /// The outputs of the slave at `address` as the master sends them.
    pub fn read_outputs(&self, address: SlaveAddress) -> Result<Vec<u8>, MasterError> {
        let pd = self.ctx.resolve(address)?.info.process_data;
        self.ctx
            .image
            .read(pd.outputs_offset as usize, usize::from(pd.outputs), true)
            .ok_or(MasterError::InvalidArgument(
                "outputs beyond the process image",
            ))
    }

    /// The inputs of the slave at `address` as the last cycle brought them.
    pub fn read_inputs(&self, address: SlaveAddress) -> Result<Vec<u8>, MasterError> {
        let pd = self.ctx.resolve(address)?.info.process_data;
        self.ctx
            .image
            .read(pd.inputs_offset as usize, usize::from(pd.inputs), false)
            .ok_or(MasterError::InvalidArgument(
                "inputs beyond the process image",
            ))
    }

    /// Cyclic working-counter errors per slave, by ring position (ETG.1510 0xAnnn:0E):
    /// the cycles since the last scan whose LRW or mailbox-status LRD came back with a
    /// wrong working counter that is put down to that slave. The frame has one LRW for all
    /// slaves, so the shortfall is explained by the slaves' shares: the shortest missing
    /// tail of the ring, else the one slave whose share it is, else every slave in the
    /// wrong datagram. Lost frames are not counted here ([`CycleStats::lost`]).
    pub fn wkc_errors(&self) -> Vec<u32> {
        self.ctx.image.wkc_errors()
    }

    /// Counters of the cyclic exchange.
    pub fn cycle_stats(&self) -> CycleStats {
        CycleStats {
            late: self.ctx.bus.stats().cycles_late,
            ..self.ctx.image.stats()
        }
    }

    /// Runs the cyclic exchange at `period` from now on (raised to the bus's
    /// [`MIN_PERIOD`](crate::bus::MIN_PERIOD)); the image and the counters carry on. A
    /// cyclic frame that is not back within the period counts as lost, so a period shorter
    /// than the segment's round trip loses every cycle.
    pub fn set_cycle_period(&self, period: Duration) {
        self.ctx.bus.set_cyclic(Some(Box::new(ProcessCycle::new(
            Arc::clone(&self.ctx.image),
            period.max(crate::bus::MIN_PERIOD),
            self.ctx.mailboxes.clone(),
        ))));
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

    /// Distributions of the cyclic exchange's timing: cycle time, jitter, start delay,
    /// round trip.
    pub fn cycle_timing(&self) -> CycleTiming {
        let c = &self.ctx.image.counters;
        CycleTiming {
            period: Duration::from_nanos(CycleCounters::count(&c.period_ns)),
            cycle_time: c.cycle_time.snapshot(),
            jitter: c.jitter.snapshot(),
            start_delay: self.ctx.bus.stats().cycle_start_delay,
            round_trip: c.round_trip.snapshot(),
        }
    }

    /// The mapped entries of the slave at `address` (gaps left out), outputs first, in
    /// image order, with their place in the image.
    pub fn entries(&self, address: SlaveAddress) -> Result<Vec<PdEntry>, MasterError> {
        self.ctx.resolve(address).map(|r| pd_entry::entries_of(&r))
    }

    /// The entry mapping `index:subindex` in the slave at `address`.
    pub fn entry(
        &self,
        address: SlaveAddress,
        index: u16,
        subindex: u8,
    ) -> Result<PdEntry, MasterError> {
        self.entries(address)?
            .into_iter()
            .find(|e| e.index == index && e.subindex == subindex)
            .ok_or(MasterError::InvalidArgument(
                "the slave maps no such object into its process data",
            ))
    }

    /// Writes `value` (little-endian, at least [`PdEntry::byte_len`] bytes) into the
    /// output `entry`; the next cycle sends it.
    pub fn write_entry(&self, entry: &PdEntry, value: &[u8]) -> Result<(), MasterError> {
        self.write_entries(&[(entry, value)])
    }

    /// Writes several outputs at once: the same cycle sends all of them. Nothing is
    /// written if one entry is not an output, lies outside the image or gets a value too
    /// short for it.
    pub fn write_entries(&self, values: &[(&PdEntry, &[u8])]) -> Result<(), MasterError> {
        if self.ctx.image.write_entries(values) {
            Ok(())
        } else {
            Err(MasterError::InvalidArgument(
                "not an output of the image, or a value shorter than the entry",
            ))
        }
    }

    /// The current value of `entry`: an input as the last cycle brought it, an output as
    /// it will be sent.
    pub fn read_entry(&self, entry: &PdEntry) -> Result<Vec<u8>, MasterError> {
        self.snapshot()
            .get(entry)
            .ok_or(MasterError::InvalidArgument(
                "entry outside the process image",
            ))
    }

    /// Groups of slaves with periods of their own, applied at the next scan; every slave
    /// not listed stays in the default group 0, exchanged every cycle. See
    /// [`SlaveGroup`]; an empty list goes back to one group of all slaves.
    pub fn set_groups(&self, groups: Vec<SlaveGroup>) {
        self.ctx.image.define(groups);
    }

    /// The groups asked for with [`Master::set_groups`].
    pub fn groups(&self) -> Vec<SlaveGroup> {
        self.ctx.image.definitions()
    }

    /// Each group's share of the image and its counters, group 0 (the default group) first,
    /// as laid out by the last scan.
    pub fn group_stats(&self) -> Vec<GroupStats> {
        self.ctx
            .image
            .groups()
            .into_iter()
            .enumerate()
            .map(|(group, g)| GroupStats {
                group,
                period: g.period,
                logical: g.logical,
                image_offset: g.start,
                image_len: g.len,
                sent: g.sent,
                completed: g.completed,
                last_wkc: g.last_wkc,
                expected_wkc: g.expected_wkc,
                wrong_wkc: g.wrong_wkc,
            })
            .collect()
    }

    /// The image with group `group`'s exchange count and working counters: its share is
    /// from one exchange of that group. `None` for a group the last scan did not lay out.
    pub fn group_snapshot(&self, group: usize) -> Option<ImageSnapshot> {
        let mut snapshot = ImageSnapshot::default();
        self.ctx
            .image
            .group_snapshot_into(group, &mut snapshot)
            .then_some(snapshot)
    }

    /// The whole image as the last completed cycle left it (inputs and outputs of one
    /// cycle together).
    pub fn snapshot(&self) -> ImageSnapshot {
        let mut snapshot = ImageSnapshot::default();
        self.ctx.image.snapshot_into(&mut snapshot);
        snapshot
    }

    /// [`Master::snapshot`] into an existing snapshot, reusing its buffers (no allocation
    /// once they are large enough).
    pub fn snapshot_into(&self, snapshot: &mut ImageSnapshot) {
        self.ctx.image.snapshot_into(snapshot);
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
