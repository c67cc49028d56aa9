//! The process image and the cyclic task that exchanges it, one frame per cycle:
//!
//! 1. an LRW per [group](crate::master::SlaveGroup) of slaves whose period is due, of that
//!    group's share of the image at its own logical address ([`LOGICAL_BASE`] +
//!    [`GROUP_STRIDE`] × group): every slave's outputs, then its inputs, in ring order. The
//!    default group 0 (every slave not given to another group) goes every cycle; a group
//!    of period *T* every round(*T* / cycle period) cycles, counted in cycles, so its frames
//!    keep their ratio to the base cycle whatever the timing;
//! 0. with distributed clocks, first an FRMW of the reference clock's system time
//!    (0x0910, 8 bytes), which every other DC slave compares with its own (see `dc`);
//! 2. an LRD of the mailbox-status bits at logical [`STATUS_BASE`] (0x40000 as in
//!    spec-notes §capture): bit *p* is bit 3 ("mailbox full") of SM1's status byte 0x080D of the slave
//!    at position *p*, mapped by an FMMU of that slave (see `mailbox_status`). A set bit is
//!    handed to the mailbox engine ([`MailboxEngine::notify_mailbox_full`]), which then
//!    reads that slave's mailbox; the engine does not poll idle mailboxes.
//!
//! A datagram whose working counter is not the expected one counts the cycle in
//! [`CycleStats::wrong_wkc`], and in the per-slave counts of the slaves that explain the
//! shortfall (see `wkc_blame`). The task runs on the bus thread; callers read and write the image through the master.
//! The lock is held only to copy bytes, and a reader sees the inputs of one whole cycle.

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use crate::bus::{CyclicFrame, CyclicReply, CyclicTask};
use crate::mailbox::MailboxEngine;
use crate::wire::command::{Command, DatagramAddress};
use crate::wire::register::address::DC_SYSTEM_TIME;
use crate::wire::register::dc::read_time;

use super::bits::copy_bits;
use super::cycle_stats::{CycleCounters, CycleStats};
use super::hook::{CompletedCycle, CycleHook, OutgoingImage};
use super::pd_entry::{ImageSnapshot, PdEntry};
use super::wkc_blame::blame;

/// Logical address of the first image byte.
pub(crate) const LOGICAL_BASE: u32 = 0;

/// Logical address space of each group: group *g*'s image starts at
/// `LOGICAL_BASE + g * GROUP_STRIDE` (a group's image is at most one datagram, < 1.5 KiB).
pub(crate) const GROUP_STRIDE: u32 = 0x1000;

/// Groups at most (their logical ranges stay below [`STATUS_BASE`]).
pub(crate) const MAX_GROUPS: usize = (STATUS_BASE / GROUP_STRIDE) as usize;

/// Logical address of the mailbox-status bits (bit *p* for ring position *p*).
pub(crate) const STATUS_BASE: u32 = 0x0004_0000;

/// One group's share of the image and of the cyclic frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct GroupSlot {
    /// Its bytes in the image buffers.
    pub start: usize,
    pub len: usize,
    /// Logical address of its first byte.
    pub logical: u32,
    /// Its period; `None`: every cycle.
    pub period: Option<Duration>,
    pub expected_wkc: u16,
    pub last_wkc: u16,
    /// Its exchanges that came back.
    pub completed: u64,
    /// Its exchanges with a working counter other than expected.
    pub wrong_wkc: u64,
    /// Its exchanges sent.
    pub sent: u64,
}

impl GroupSlot {
    /// A group of `len` bytes from `start`, at logical address `logical`.
    pub fn new(
        start: usize,
        len: usize,
        logical: u32,
        period: Option<Duration>,
        expected_wkc: u16,
    ) -> GroupSlot {
        GroupSlot {
            start,
            len,
            logical,
            period,
            expected_wkc,
            last_wkc: 0,
            completed: 0,
            wrong_wkc: 0,
            sent: 0,
        }
    }

    /// Every how many cycles of `base` it goes (at least 1).
    fn every(&self, base: Duration) -> u64 {
        let Some(period) = self.period else {
            return 1;
        };
        let base = base.as_nanos().max(1);
        let ratio = (period.as_nanos() + base / 2) / base;
        u64::try_from(ratio).unwrap_or(u64::MAX).max(1)
    }
}

#[derive(Default)]
struct Buffers {
    /// What is sent: the outputs (input ranges are sent as whatever they hold).
    outputs: Vec<u8>,
    /// What came back last.
    inputs: Vec<u8>,
    expected_wkc: u16,
    last_wkc: u16,
    /// Completed cycles; the inputs are from the last of them.
    cycle: u64,
    /// Station address behind each mailbox-status bit (`None`: bit not mapped).
    status_stations: Vec<Option<u16>>,
    /// Bytes of the status area (a bit per slave position).
    status_len: usize,
    /// The DC reference clock's station and the number of DC slaves (the working counter
    /// of the reference-time datagram).
    dc: Option<(u16, u16)>,
    /// The reference clock's system time as the last cycle read it.
    dc_time: Option<u64>,
    /// Each position's share of its group's LRW working counter.
    lrw_shares: Vec<u16>,
    /// Each position's group (index into `groups`).
    lrw_group: Vec<u8>,
    /// This cycle's shares: `lrw_shares` of the groups whose LRW the frame carried, else 0
    /// (kept here so that the cycle allocates nothing).
    cycle_shares: Vec<u16>,
    /// Wrong-WKC cycles put down to each position.
    wkc_errors: Vec<u32>,
    /// The groups' shares, in image order.
    groups: Vec<GroupSlot>,
    /// The groups asked for (applied at the next scan).
    definitions: Vec<super::groups::SlaveGroup>,
    /// Layouts made so far (see [`OutgoingImage::layout`]).
    layout: u64,
    /// Runs at every cycle beside the image (a control program's).
    hook: Option<Arc<dyn CycleHook>>,
}

impl std::fmt::Debug for Buffers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Buffers")
            .field("image_len", &self.outputs.len())
            .field("cycle", &self.cycle)
            .field("layout", &self.layout)
            .field("groups", &self.groups)
            .field("hook", &self.hook.is_some())
            .finish_non_exhaustive()
    }
}

impl Buffers {
    fn status_wkc(&self) -> u16 {
        let mapped = self.status_stations.iter().flatten().count();
        u16::try_from(mapped).unwrap_or(u16::MAX)
    }
}

/// The image shared by the cyclic task and the master.
#[derive(Debug, Default)]
pub(crate) struct Image {
    buffers: Mutex<Buffers>,
    pub counters: CycleCounters,
}

impl Image {
    fn lock(&self) -> MutexGuard<'_, Buffers> {
        self.buffers.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Lays the image out as `groups` (in image order, back to back); keeps the bytes
    /// that fit.
    pub fn set_groups(&self, groups: Vec<GroupSlot>) {
        let mut b = self.lock();
        let len = groups.last().map_or(0, |g| g.start + g.len);
        b.outputs.resize(len, 0);
        b.inputs.resize(len, 0);
        b.expected_wkc = groups
            .iter()
            .fold(0u16, |sum, g| sum.saturating_add(g.expected_wkc));
        b.last_wkc = 0;
        b.groups = groups;
        b.layout += 1;
    }

    /// Installs (or, with `None`, removes) the hook run at every cycle.
    pub fn set_hook(&self, hook: Option<Arc<dyn CycleHook>>) {
        self.lock().hook = hook;
    }

    /// Layouts made so far.
    pub fn layout(&self) -> u64 {
        self.lock().layout
    }

    /// The groups' shares as laid out at the last scan.
    pub fn groups(&self) -> Vec<GroupSlot> {
        self.lock().groups.clone()
    }

    /// The logical address of image byte `offset` (its group's base plus its place in
    /// the group); the offset itself if no group holds it.
    pub fn logical_of(&self, offset: u32) -> u32 {
        let b = self.lock();
        let at = offset as usize;
        b.groups
            .iter()
            .find(|g| g.start <= at && at < g.start + g.len)
            .map_or(offset, |g| g.logical + (offset - g.start as u32))
    }

    /// The groups to lay out at the next scan.
    pub fn definitions(&self) -> Vec<super::groups::SlaveGroup> {
        self.lock().definitions.clone()
    }

    /// Asks for `groups` at the next scan.
    pub fn define(&self, groups: Vec<super::groups::SlaveGroup>) {
        self.lock().definitions = groups;
    }

    /// Copies the image with the cycle count and working counters of group `group` (its
    /// share is from one exchange; the other groups' may be older or newer).
    pub fn group_snapshot_into(&self, group: usize, snapshot: &mut ImageSnapshot) -> bool {
        let b = self.lock();
        let Some(slot) = b.groups.get(group) else {
            return false;
        };
        snapshot.cycle = slot.completed;
        snapshot.wkc = slot.last_wkc;
        snapshot.expected_wkc = slot.expected_wkc;
        snapshot.inputs.clear();
        snapshot.inputs.extend_from_slice(&b.inputs);
        snapshot.outputs.clear();
        snapshot.outputs.extend_from_slice(&b.outputs);
        true
    }

    /// Sizes the mailbox-status area for `slaves` positions, none mapped yet.
    pub fn reset_status(&self, slaves: u16) {
        let mut b = self.lock();
        b.status_stations.clear();
        b.status_stations.resize(usize::from(slaves), None);
        b.status_len = usize::from(slaves).div_ceil(8);
        b.lrw_shares.clear();
        b.lrw_shares.resize(usize::from(slaves), 0);
        b.lrw_group.clear();
        b.lrw_group.resize(usize::from(slaves), 0);
        b.cycle_shares.clear();
        b.cycle_shares.resize(usize::from(slaves), 0);
        b.wkc_errors.clear();
        b.wkc_errors.resize(usize::from(slaves), 0);
    }

    /// The share of the slave at `position` in the LRW working counter of `group`.
    pub fn set_lrw_share(&self, position: u16, group: usize, share: u16) {
        let mut b = self.lock();
        let at = usize::from(position);
        if let (Some(slot), Some(member)) = (b.lrw_shares.get_mut(at), u8::try_from(group).ok()) {
            *slot = share;
            if let Some(g) = b.lrw_group.get_mut(at) {
                *g = member;
            }
        }
    }

    /// Wrong-WKC cycles put down to each position.
    pub fn wkc_errors(&self) -> Vec<u32> {
        self.lock().wkc_errors.clone()
    }

    /// Zeroes the per-slave wrong-WKC counts.
    pub fn clear_wkc_errors(&self) {
        self.lock().wkc_errors.fill(0);
    }

    /// Bit `position` of the status area now reads `station`'s "mailbox full" bit (`None`:
    /// no longer mapped).
    pub fn map_status(&self, position: u16, station: Option<u16>) {
        if let Some(slot) = self.lock().status_stations.get_mut(usize::from(position)) {
            *slot = station;
        }
    }

    /// The reference clock whose system time every cycle distributes (FRMW 0x0910) and
    /// the number of DC slaves; `None`: no DC.
    pub fn set_dc_reference(&self, reference: Option<(u16, u16)>) {
        let mut b = self.lock();
        b.dc = reference;
        b.dc_time = None;
    }

    /// The reference clock's system time as the last cycle read it.
    pub fn dc_time(&self) -> Option<u64> {
        self.lock().dc_time
    }

    /// Writes `data` into the image at `offset`; false if it does not fit.
    pub fn write(&self, offset: usize, data: &[u8]) -> bool {
        let mut b = self.lock();
        let range = offset..offset.saturating_add(data.len());
        match b.outputs.get_mut(range) {
            Some(target) => {
                target.copy_from_slice(data);
                true
            }
            None => false,
        }
    }

    /// Writes each value into its entry's bits, all under one lock (so one cycle sends all
    /// or none of them); false, and nothing written, if one does not fit.
    pub fn write_entries(&self, values: &[(&PdEntry, &[u8])]) -> bool {
        let mut b = self.lock();
        let fits = values.iter().all(|(e, v)| {
            let end = e.bit_offset as usize + usize::from(e.bit_length);
            e.output && v.len() * 8 >= usize::from(e.bit_length) && end <= b.outputs.len() * 8
        });
        if !fits {
            return false;
        }
        for (e, v) in values {
            copy_bits(
                v,
                0,
                &mut b.outputs,
                e.bit_offset as usize,
                usize::from(e.bit_length),
            );
        }
        true
    }

    /// `len` bytes at `offset` of what was sent (`outputs`) or received last.
    pub fn read(&self, offset: usize, len: usize, outputs: bool) -> Option<Vec<u8>> {
        let b = self.lock();
        let source = if outputs { &b.outputs } else { &b.inputs };
        source
            .get(offset..offset.saturating_add(len))
            .map(<[u8]>::to_vec)
    }

    /// Copies the image as the last cycle left it into `snapshot` (reusing its buffers).
    pub fn snapshot_into(&self, snapshot: &mut ImageSnapshot) {
        let b = self.lock();
        snapshot.cycle = b.cycle;
        snapshot.wkc = b.last_wkc;
        snapshot.expected_wkc = b.expected_wkc;
        snapshot.inputs.clear();
        snapshot.inputs.extend_from_slice(&b.inputs);
        snapshot.outputs.clear();
        snapshot.outputs.extend_from_slice(&b.outputs);
    }

    pub fn stats(&self) -> CycleStats {
        let b = self.lock();
        let c = &self.counters;
        CycleStats {
            completed: b.cycle,
            lost: CycleCounters::count(&c.lost),
            last_wkc: b.last_wkc,
            expected_wkc: b.expected_wkc,
            wrong_wkc: CycleCounters::count(&c.wrong_wkc),
            late: 0,
            missed: CycleCounters::count(&c.missed),
            image_len: b.outputs.len(),
            mailbox_status_slaves: b.status_wkc(),
            mailbox_notices: CycleCounters::count(&c.mailbox_notices),
        }
    }

    /// Exchanges of the process data of the slave at `position` completed so far: its
    /// group's; the cycles when its group carries no process data (and so no datagram).
    pub fn completed_for(&self, position: u16) -> u64 {
        let b = self.lock();
        b.lrw_group
            .get(usize::from(position))
            .and_then(|&g| b.groups.get(usize::from(g)))
            .filter(|g| g.len > 0)
            .map_or(b.cycle, |g| g.completed)
    }
}

/// The bus's cyclic task; see the [module documentation](self).
pub(crate) struct ProcessCycle {
    pub image: Arc<Image>,
    pub period: Duration,
    pub mailboxes: MailboxEngine,
    /// Frame positions of this cycle's reference-time, process-data (group, position)
    /// and status datagrams.
    dc_at: Option<usize>,
    pd_at: Vec<(usize, usize)>,
    status_at: Option<usize>,
    /// Cycles built: which groups are due.
    tick: u64,
    last_start: Option<Instant>,
    /// Stations whose bit was set in the last status read (kept to avoid allocating).
    full: Vec<u16>,
}

impl ProcessCycle {
    pub fn new(image: Arc<Image>, period: Duration, mailboxes: MailboxEngine) -> ProcessCycle {
        let period_ns = u64::try_from(period.as_nanos()).unwrap_or(u64::MAX);
        image.counters.period_ns.store(period_ns, Ordering::Relaxed);
        ProcessCycle {
            image,
            period,
            mailboxes,
            dc_at: None,
            pd_at: Vec::with_capacity(MAX_GROUPS),
            status_at: None,
            tick: 0,
            last_start: None,
            full: Vec::new(),
        }
    }
}

impl CyclicTask for ProcessCycle {
    fn period(&self) -> Duration {
        self.period
    }

    fn build(&mut self, frame: &mut CyclicFrame<'_>) {
        self.dc_at = None;
        self.pd_at.clear();
        self.status_at = None;
        let tick = self.tick;
        self.tick = self.tick.wrapping_add(1);
        let mut b = self.image.lock();
        // The reference time first, as SOEM and IgH put it: the slaves behind the
        // reference compare it with their own as the frame passes.
        if let Some((station, _)) = b.dc {
            self.dc_at = frame
                .push_zeroed(
                    Command::Frmw,
                    DatagramAddress::Node {
                        station,
                        ado: DC_SYSTEM_TIME,
                    },
                    8,
                )
                .ok();
        }
        // A failure leaves the datagram out: the image size was checked against the frame
        // when the layout was made.
        let b = &mut *b;
        if let Some(hook) = &b.hook {
            hook.before_send(&mut OutgoingImage {
                layout: b.layout,
                cycle: b.cycle,
                outputs: &mut b.outputs,
            });
        }
        for (index, group) in b.groups.iter_mut().enumerate() {
            if group.len == 0 || !tick.is_multiple_of(group.every(self.period)) {
                continue;
            }
            let Some(outputs) = b.outputs.get(group.start..group.start + group.len) else {
                continue;
            };
            let pushed = frame.push(
                Command::Lrw,
                DatagramAddress::Logical(group.logical),
                outputs,
            );
            if let Ok(position) = pushed {
                group.sent += 1;
                self.pd_at.push((index, position));
            }
        }
        if b.status_len > 0 && b.status_wkc() > 0 {
            self.status_at = frame
                .push_zeroed(
                    Command::Lrd,
                    DatagramAddress::Logical(STATUS_BASE),
                    b.status_len,
                )
                .ok();
        }
        if !self.pd_at.is_empty() || self.status_at.is_some() || self.dc_at.is_some() {
            let now = Instant::now();
            self.image
                .counters
                .started(now, self.last_start.replace(now), self.period);
        }
    }

    fn complete(&mut self, reply: &CyclicReply<'_>) {
        self.full.clear();
        let mut wrong = false;
        let mut deficit = (0i64, 0i64);
        // The groups whose LRW this frame carried (a bit per group; at most 64 groups).
        let mut carried = 0u64;
        {
            let mut b = self.image.lock();
            if let Some(datagram) = self.dc_at.and_then(|at| reply.datagram(at)) {
                let expected = b.dc.map_or(0, |(_, count)| count);
                wrong |= datagram.wkc != expected;
                b.dc_time = read_time(datagram.data).ok();
            }
            let b = &mut *b;
            for &(index, at) in &self.pd_at {
                let (Some(datagram), Some(group)) = (reply.datagram(at), b.groups.get_mut(index))
                else {
                    continue;
                };
                let range = group.start..group.start + group.len;
                if let Some(inputs) = b.inputs.get_mut(range)
                    && inputs.len() == datagram.data.len()
                {
                    inputs.copy_from_slice(datagram.data);
                }
                group.last_wkc = datagram.wkc;
                group.completed += 1;
                deficit.0 += i64::from(group.expected_wkc) - i64::from(datagram.wkc);
                if let Some(bit) = 1u64.checked_shl(u32::try_from(index).unwrap_or(u32::MAX)) {
                    carried |= bit;
                }
                if datagram.wkc != group.expected_wkc {
                    group.wrong_wkc += 1;
                    wrong = true;
                }
            }
            if !self.pd_at.is_empty() {
                b.last_wkc = b
                    .groups
                    .iter()
                    .fold(0u16, |sum, g| sum.saturating_add(g.last_wkc));
            }
            if let Some(datagram) = self.status_at.and_then(|at| reply.datagram(at)) {
                wrong |= datagram.wkc != b.status_wkc();
                deficit.1 = i64::from(b.status_wkc()) - i64::from(datagram.wkc);
                for (position, station) in b.status_stations.iter().enumerate() {
                    let set = datagram
                        .data
                        .get(position / 8)
                        .is_some_and(|byte| byte & (1 << (position % 8)) != 0);
                    if let (true, Some(station)) = (set, station) {
                        self.full.push(*station);
                    }
                }
            }
            let Buffers {
                lrw_shares,
                lrw_group,
                cycle_shares,
                status_stations,
                wkc_errors,
                ..
            } = &mut *b;
            // Only the slaves of the groups in this frame had a share in its working counters.
            for ((cycle, share), group) in cycle_shares
                .iter_mut()
                .zip(lrw_shares.iter())
                .zip(lrw_group.iter())
            {
                let in_frame = 1u64
                    .checked_shl(u32::from(*group))
                    .is_some_and(|bit| carried & bit != 0);
                *cycle = if in_frame { *share } else { 0 };
            }
            blame(cycle_shares, status_stations, deficit, wkc_errors);
            b.cycle += 1;
            if let Some(hook) = &b.hook
                && !self.pd_at.is_empty()
            {
                hook.after_receive(&CompletedCycle {
                    layout: b.layout,
                    cycle: b.cycle,
                    inputs: &b.inputs,
                    outputs: &b.outputs,
                    wkc: b.last_wkc,
                    expected_wkc: b.expected_wkc,
                });
            }
        }
        let counters = &self.image.counters;
        counters.round_trip.record(reply.round_trip());
        if wrong {
            CycleCounters::bump(&counters.wrong_wkc, 1);
        }
        for &station in &self.full {
            self.mailboxes.notify_mailbox_full(station);
        }
        CycleCounters::bump(&counters.mailbox_notices, self.full.len() as u64);
    }

    fn lost(&mut self) {
        CycleCounters::bump(&self.image.counters.lost, 1);
    }
}
