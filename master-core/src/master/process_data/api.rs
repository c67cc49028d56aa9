//! The [`Master`] methods for process data: layouts and configured PDO assignments, the
//! slaves' inputs and outputs, named entries and snapshots, slave groups, and the cyclic
//! exchange's period and counters.

use std::sync::{Arc, PoisonError};
use std::time::Duration;

use crate::master::{
    CycleHook, CycleStats, CycleTiming, GroupStats, ImageSnapshot, Master, MasterError, PdEntry,
    PdoAssignment, ProcessDataLayout, SlaveAddress, SlaveGroup,
};

use super::cycle_stats::CycleCounters;
use super::image::ProcessCycle;
use super::{pd_entry, pdo_assignment};

impl Master {
    /// The process-data SyncManagers of the slave at `address` (empty until a scan brought it
    /// to PREOP and made the layout).
    pub fn process_data_layout(
        &self,
        address: SlaveAddress,
    ) -> Result<ProcessDataLayout, MasterError> {
        self.ctx.resolve_with(address, |r| r.layout.clone())
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
            configs.push(pdo_assignment::SlavePdoConfig {
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

    /// Writes `data` into the outputs of the slave at `address`, from byte `offset` of its
    /// outputs on; the next cycle sends them.
    pub fn write_outputs(
        &self,
        address: SlaveAddress,
        offset: usize,
        data: &[u8],
    ) -> Result<(), MasterError> {
        let pd = self.ctx.resolve_with(address, |r| r.info.process_data)?;
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
        let pd = self.ctx.resolve_with(address, |r| r.info.process_data)?;
        self.ctx
            .image
            .read(pd.outputs_offset as usize, usize::from(pd.outputs), true)
            .ok_or(MasterError::InvalidArgument(
                "outputs beyond the process image",
            ))
    }

    /// The inputs of the slave at `address` as the last cycle brought them.
    pub fn read_inputs(&self, address: SlaveAddress) -> Result<Vec<u8>, MasterError> {
        let pd = self.ctx.resolve_with(address, |r| r.info.process_data)?;
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
        self.ctx.resolve_with(address, pd_entry::entries_of)
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

    /// Installs `hook` to run on the bus thread around every cycle (`None` removes it): a
    /// control program's cycle in this process, or ecatd's shared image for programs in
    /// others. One hook at a time; a new one replaces the last from the next cycle on.
    pub fn set_cycle_hook(&self, hook: Option<Arc<dyn CycleHook>>) {
        self.ctx.image.set_hook(hook);
    }

    /// Counts the image's layouts: it changes whenever a scan lays the image out again
    /// (see [`OutgoingImage::layout`](crate::master::OutgoingImage::layout)).
    pub fn layout_count(&self) -> u64 {
        self.ctx.image.layout()
    }

    /// Whether a scan (or the watch's repair of a slave) is under way: the layout may be
    /// between two states until it ends.
    pub fn topology_busy(&self) -> bool {
        self.ctx.topology.try_lock().is_err()
    }

    /// [`Master::snapshot`] into an existing snapshot, reusing its buffers (no allocation
    /// once they are large enough).
    pub fn snapshot_into(&self, snapshot: &mut ImageSnapshot) {
        self.ctx.image.snapshot_into(snapshot);
    }
}
