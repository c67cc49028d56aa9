//! The loop of the bus thread: the only code that touches the link.
//!
//! Each turn: take control requests (shutdown, cyclic task), give up or resend frames
//! whose deadline passed, start the cyclic frame if a cycle is due, pack waiting datagrams
//! into as few frames as the MTU, the free datagram indices and the frames-in-flight limit
//! allow, then wait for a returning frame (or, with nothing in flight, for a submission).
//!
//! Nothing here allocates after start-up: frames are built in one transmit buffer and
//! received into one receive buffer, frame records and the staging queue are reserved once,
//! and a reply's data is copied into the storage the caller allocated with its request.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::link::{self, Link, Wait};
use crate::wire::command::DatagramAddress;
use crate::wire::datagram::{DatagramRepr, OVERHEAD};
use crate::wire::frame::{EthercatFrame, FrameBuilder};

use super::Shared;
use super::config::{BusConfig, FRAME_HEADERS_LEN, WaitMode};
use super::cyclic::{CyclicFrame, CyclicReply, CyclicTask, MIN_PERIOD};
use super::error::BusError;
use super::guest::Guest;
use super::index::{INDICES, IndexTable};
use super::matching::{Match, match_frame};
use super::queue::{CyclicChange, Queued, Submissions};
use super::record::{FrameRecord, MAX_DATAGRAMS_PER_FRAME, RecordKind, SentDatagram};
use super::request::{DatagramResponse, WkcCheck};
use super::stamp::Stamp;
use super::stats::BusStats;

/// Indices acyclic frames may hold at once; the rest stay free for the cyclic frame, so
/// that a burst of acyclic traffic cannot hold up process data.
pub(crate) const ACYCLIC_INDEX_LIMIT: usize = INDICES - 16;

/// The longest the thread sleeps in the link's `recv` before it looks at control requests
/// and submissions again. The link cannot be woken from outside, so this bounds how late a
/// shutdown is noticed, and how long new datagrams wait for a free frame record, while a
/// frame is out for longer than usual (a lost frame waiting for its deadline). A returning
/// frame ends the wait at once, so on a healthy segment this never adds latency.
const RECV_SLICE: Duration = Duration::from_millis(1);

/// How many stale frames are read off an idle link before parking, at most.
const IDLE_DRAIN: usize = 16;

/// What one receive brought.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Received {
    Frame,
    Nothing,
    LinkError,
}

/// The installed cyclic task and its schedule.
struct Cyclic {
    task: Box<dyn CyclicTask>,
    period: Duration,
    next_due: Instant,
    /// How long before `next_due` the thread wakes to spin ([`BusConfig::cycle_spin`], at
    /// most half the period).
    spin: Duration,
}

/// Everything the bus thread owns.
pub(crate) struct Engine<L: Link> {
    link: L,
    shared: Arc<Shared>,
    config: BusConfig,
    tx: Box<[u8]>,
    rx: Box<[u8]>,
    /// Datagrams taken from the submission queue, not yet in a frame.
    staging: VecDeque<Queued>,
    indices: IndexTable,
    /// `config.frames_in_flight` acyclic records, then the cyclic one.
    records: Vec<FrameRecord>,
    cyclic: Option<Cyclic>,
    /// Recent round trip of acyclic frames (a moving average): how long one sent now
    /// keeps the wire, and on an in-process link the bus thread itself, busy.
    acyclic_cost: Duration,
    /// Acyclic frames wait for the next cycle (see [`Engine::acyclic_fits`]).
    held: bool,
    /// Runs after each wait, and is waited on beside the link ([`super::guest`]).
    guest: Option<Box<dyn Guest>>,
}

impl<L: Link> Engine<L> {
    pub fn new(link: L, shared: Arc<Shared>) -> Engine<L> {
        // Before any frame is stamped (`DatagramResponse::sent_at`).
        Stamp::start_clock();
        let config = shared.config;
        let now = Instant::now();
        let mut records: Vec<FrameRecord> = (0..config.frames_in_flight)
            .map(|_| FrameRecord::new(RecordKind::Acyclic, now))
            .collect();
        records.push(FrameRecord::new(RecordKind::Cyclic, now));
        Engine {
            link,
            config,
            tx: vec![0; config.max_frame_len].into_boxed_slice(),
            rx: vec![0; link::MAX_FRAME_LEN].into_boxed_slice(),
            staging: VecDeque::with_capacity(config.queue_capacity),
            indices: IndexTable::new(),
            records,
            cyclic: None,
            acyclic_cost: Duration::ZERO,
            held: false,
            guest: None,
            shared,
        }
    }

    /// Records whether the thread got real-time scheduling, and its time slice.
    pub fn set_scheduling(&self, realtime: bool, time_slice_ns: u64) {
        let stats = &self.shared.stats;
        stats
            .realtime
            .store(realtime, std::sync::atomic::Ordering::Relaxed);
        stats
            .time_slice_ns
            .store(time_slice_ns, std::sync::atomic::Ordering::Relaxed);
    }

    /// Runs until shutdown, then fails whatever is left and hands the link back.
    pub fn run(mut self) -> L {
        // Should anything below panic, callers must still hear that the bus is gone:
        // closing the queue refuses new submissions, and dropping the engine's datagrams
        // completes them with `Shutdown`.
        let _closer = CloseOnDrop(Arc::clone(&self.shared));
        loop {
            if let Some(control) = self.shared.queue.take_control() {
                if control.shutdown {
                    break;
                }
                if let Some(change) = control.cyclic {
                    self.change_cyclic(change);
                }
                if let Some(guest) = control.guest {
                    self.guest = guest;
                }
            }
            self.drain_before_expiry(Instant::now());
            self.expire(Instant::now());
            self.run_cycle_if_due();
            self.send_acyclic();
            let readable = self.wait_and_receive();
            let cycle = self
                .cyclic
                .as_ref()
                .map(|c| c.next_due.checked_sub(c.spin).unwrap_or(c.next_due));
            if let Some(guest) = self.guest.as_mut() {
                guest.turn(readable, cycle);
            }
        }
        self.fail_everything();
        let Engine { link, .. } = self;
        link
    }

    // --- sending ------------------------------------------------------------------------

    /// Sends the frame in `tx[..len]` for record `id`, starting its clock.
    fn transmit(&mut self, id: usize, len: usize, timeout: Duration) {
        let now = Instant::now();
        let record = &mut self.records[id];
        record.sent_at = now;
        record.deadline = now + timeout;
        record.attempts += 1;
        record.active = true;
        match self.link.send(&self.tx[..len]) {
            Ok(()) => {
                record.send_error = None;
                self.shared.stats.frames_sent.inc();
            }
            Err(err) => {
                // Treated like a frame lost on the wire: it times out and is sent again,
                // which rides out a full send queue; the error is reported if it persists.
                record.send_error = Some(err.kind());
                self.shared.stats.link_errors.inc();
            }
        }
        if record.kind == RecordKind::Acyclic {
            let count = record.datagrams.len() as u64;
            self.shared.stats.datagrams_sent.add(count);
        }
    }

    /// Packs waiting datagrams into frames and sends them while there is a free record.
    fn send_acyclic(&mut self) {
        self.held = false;
        loop {
            // Only take from the queue with a frame to fill, so that submissions beyond
            // what the frames in flight carry wait in the bounded queue (and a full queue
            // is reported to callers) rather than piling up here.
            let Some(id) = self.free_acyclic_record() else {
                return;
            };
            if self.staging.is_empty() && self.shared.queue.len() == 0 {
                return;
            }
            if !self.acyclic_fits(Instant::now()) {
                self.held = true;
                self.shared.stats.acyclic_held.inc();
                return;
            }
            if self.staging.is_empty() {
                self.shared.queue.take_into(&mut self.staging);
                if self.staging.is_empty() {
                    return;
                }
            }
            let len = pack(
                &mut self.tx,
                &self.config,
                &self.shared.queue,
                &mut self.staging,
                &mut self.indices,
                &mut self.records[id],
                id as u16,
            );
            let Some(len) = len else {
                // Not even the first group fits the indices acyclic traffic may use: wait
                // for replies to free some.
                return;
            };
            self.transmit(id, len, self.config.response_timeout);
        }
    }

    /// Whether an acyclic frame sent at `now` is back before the next cycle is due: on
    /// the wire a cyclic frame sent behind it queues behind it, and on an in-process link
    /// the bus thread is busy carrying it. The guard is the recent acyclic round trip, at
    /// most a quarter of the period, so that acyclic traffic always keeps most of each
    /// period (a slow link does not starve it). A cycle already due is sent first by the
    /// loop; one whose previous frame is still out cannot start anyway, so holding back
    /// only delays acyclic traffic while a cycle is about to go out.
    fn acyclic_fits(&self, now: Instant) -> bool {
        let Some(cyclic) = &self.cyclic else {
            return true;
        };
        if self.records[self.cyclic_record()].active {
            return true;
        }
        let guard = self.acyclic_cost.min(cyclic.period / 4);
        now + guard < cyclic.next_due
    }

    /// Folds one acyclic round trip into the moving average (weight 1/8).
    fn learn_acyclic_cost(&mut self, round_trip: Duration) {
        self.acyclic_cost = if self.acyclic_cost.is_zero() {
            round_trip
        } else {
            (self.acyclic_cost * 7 + round_trip) / 8
        };
    }

    fn free_acyclic_record(&self) -> Option<usize> {
        self.records
            .iter()
            .position(|r| r.kind == RecordKind::Acyclic && !r.active)
    }

    fn cyclic_record(&self) -> usize {
        self.records.len() - 1
    }

    // --- deadlines ----------------------------------------------------------------------

    /// When a deadline has passed, first takes what already arrived: on a loaded machine
    /// the bus thread can be scheduled late, and a reply waiting in the link must not be
    /// counted lost (and its frame sent again) just because nobody read it yet.
    fn drain_before_expiry(&mut self, now: Instant) {
        let due = self.records.iter().any(|r| r.active && r.deadline <= now);
        if !due {
            return;
        }
        for _ in 0..IDLE_DRAIN {
            if self.receive_one(Wait::NoWait) != Received::Frame {
                break;
            }
        }
    }

    /// Resends or gives up every frame whose deadline has passed.
    fn expire(&mut self, now: Instant) {
        for id in 0..self.records.len() {
            let record = &self.records[id];
            if !record.active || record.deadline > now {
                continue;
            }
            self.shared.stats.frames_lost.inc();
            match record.kind {
                RecordKind::Cyclic => {
                    self.release_record(id);
                    self.shared.stats.cycles_lost.inc();
                    if let Some(cyclic) = &mut self.cyclic {
                        cyclic.task.lost();
                    }
                }
                RecordKind::Acyclic if record.attempts <= self.config.retries => {
                    self.fail_send_once(id);
                    if self.records[id].entries.is_empty() {
                        self.release_record(id);
                    } else {
                        self.shared.stats.retries.inc();
                        self.resend(id);
                    }
                }
                RecordKind::Acyclic => {
                    let error = match record.send_error {
                        Some(kind) => BusError::Link(kind),
                        None => BusError::Timeout {
                            attempts: record.attempts,
                        },
                    };
                    let failed = record.entries.len() as u64;
                    for entry in self.records[id].entries.drain(..) {
                        entry.completer.complete(Err(error.clone()));
                    }
                    self.shared.stats.datagrams_failed.add(failed);
                    self.release_record(id);
                }
            }
        }
    }

    /// Fails the datagrams of lost frame `id` that must not be sent twice
    /// ([`BusHandle::submit_once`](super::BusHandle::submit_once)), and takes them out of
    /// the record so that only the others are sent again.
    fn fail_send_once(&mut self, id: usize) {
        let record = &mut self.records[id];
        if !record.entries.iter().any(|entry| entry.once) {
            return;
        }
        let error = BusError::Timeout {
            attempts: record.attempts,
        };
        let mut kept = 0;
        for i in 0..record.entries.len() {
            if record.entries[i].once {
                self.indices.release(record.datagrams[i].index);
            } else {
                record.entries.swap(kept, i);
                record.datagrams.swap(kept, i);
                kept += 1;
            }
        }
        let mut failed = 0;
        for entry in record.entries.drain(kept..) {
            entry.completer.complete(Err(error.clone()));
            failed += 1;
        }
        record.datagrams.truncate(kept);
        self.shared.stats.datagrams_failed.add(failed);
    }

    /// Sends the datagrams of a lost acyclic frame again, together, under the same indices,
    /// as SOEM does: the request is byte for byte the one already sent, so a late reply to
    /// any attempt is a true answer to it and completes the frame. With new indices per
    /// attempt a segment that answers just slower than the timeout (a loaded simulator, a
    /// slave's slow firmware) would have every reply discarded as stale, each one arriving
    /// just after the next attempt went out, until the retries ran out.
    fn resend(&mut self, id: usize) {
        let record = &mut self.records[id];
        let mut builder = new_builder(&mut self.tx);
        for (sent, entry) in record.datagrams.iter_mut().zip(&record.entries) {
            let request = &entry.request;
            // The same datagrams fitted this buffer before, so the offsets come out equal.
            if let Ok(offset) = builder.push(&DatagramRepr::request(
                request.command,
                sent.index,
                request.address,
                &request.data,
            )) {
                sent.offset = offset;
            }
        }
        match builder.finish(self.config.source_mac) {
            Ok(len) => self.transmit(id, len, self.config.response_timeout),
            // Unreachable: the record holds at least one datagram.
            Err(_) => self.release_record(id),
        }
    }

    /// Frees a record and its indices.
    fn release_record(&mut self, id: usize) {
        let record = &mut self.records[id];
        for sent in &record.datagrams {
            self.indices.release(sent.index);
        }
        record.clear();
    }

    // --- cyclic -------------------------------------------------------------------------

    fn change_cyclic(&mut self, change: CyclicChange) {
        // A frame of the old task still out is forgotten; its reply will count as stale.
        let id = self.cyclic_record();
        if self.records[id].active {
            self.release_record(id);
        }
        let spin = self.config.cycle_spin;
        self.cyclic = change.map(|task| {
            let period = task.period().max(MIN_PERIOD);
            Cyclic {
                period,
                task,
                next_due: Instant::now(),
                spin: spin.min(period / 2),
            }
        });
    }

    /// Starts the cyclic frame if a cycle is due and the last one is back.
    fn run_cycle_if_due(&mut self) {
        let id = self.cyclic_record();
        let Some(cyclic) = &mut self.cyclic else {
            return;
        };
        if self.records[id].active {
            return;
        }
        let mut now = Instant::now();
        if now < cyclic.next_due {
            // Woken `cycle_spin` early (`next_wake`): spin the rest, so that the kernel's
            // wake-up latency is spent before the cycle is due, not after.
            if cyclic.next_due - now > cyclic.spin {
                return;
            }
            while now < cyclic.next_due {
                std::hint::spin_loop();
                now = Instant::now();
            }
        }
        let stats = &self.shared.stats;
        let late_by = now - cyclic.next_due;
        stats.cycle_start_delay.record(late_by);
        let missed = late_by.as_nanos() / cyclic.period.as_nanos();
        if missed > 0 {
            stats.cycles_late.inc();
        }
        // `missed` fits: it is at most the time since start-up in periods of 10 µs or more.
        let skip = u32::try_from(missed + 1).unwrap_or(u32::MAX);
        cyclic.next_due += cyclic.period.saturating_mul(skip);
        stats.cycles_run.inc();

        let record = &mut self.records[id];
        let mut frame = CyclicFrame {
            builder: new_builder(&mut self.tx),
            indices: &mut self.indices,
            record: id as u16,
            sent: &mut record.datagrams,
        };
        cyclic.task.build(&mut frame);
        let CyclicFrame { builder, .. } = frame;
        if builder.is_empty() {
            return;
        }
        let timeout = self.config.response_timeout.min(cyclic.period);
        match builder.finish(self.config.source_mac) {
            Ok(len) => self.transmit(id, len, timeout),
            Err(_) => self.release_record(id),
        }
    }

    // --- receiving ----------------------------------------------------------------------

    /// The earliest moment the loop must look up again: a frame deadline or a cycle.
    fn next_wake(&self) -> Option<Instant> {
        let deadlines = self.records.iter().filter(|r| r.active).map(|r| r.deadline);
        let cycle = self
            .cyclic
            .as_ref()
            .filter(|_| !self.records[self.cyclic_record()].active)
            .map(|c| c.next_due.checked_sub(c.spin).unwrap_or(c.next_due));
        deadlines.chain(cycle).min()
    }

    fn in_flight(&self) -> bool {
        self.records.iter().any(|r| r.active)
    }

    /// Waits as the wait mode says and handles what arrives; says whether the guest's
    /// descriptor was seen readable (always, in [`WaitMode::BusyPoll`], which waits on
    /// nothing).
    fn wait_and_receive(&mut self) -> bool {
        let wake = self.next_wake();
        let mut guest_readable = false;
        // A guest's task woken on this thread (a frame's completion, an expiry) runs before
        // the bus sleeps again.
        let guest_busy = self.guest.as_ref().is_some_and(|guest| guest.has_work());
        match self.config.wait_mode {
            WaitMode::Poll if self.in_flight() => {
                let slice_end = Instant::now() + RECV_SLICE;
                let until = wake.map_or(slice_end, |wake| wake.min(slice_end));
                let until = if guest_busy { Instant::now() } else { until };
                let wait = match (&self.guest, self.link.wait_fd()) {
                    (Some(guest), Some(link)) => {
                        // The link's frame or the guest's work, whichever comes first.
                        let timeout = until.saturating_duration_since(Instant::now());
                        let fds = [link, guest.wait_fd()];
                        let [frame, guest] =
                            link::which_readable(&fds, timeout).unwrap_or([true, true]);
                        guest_readable = guest;
                        frame.then_some(Wait::NoWait)
                    }
                    _ => Some(Wait::Until(until)),
                };
                if let Some(wait) = wait
                    && self.receive_one(wait) == Received::LinkError
                {
                    self.back_off(wake);
                }
            }
            WaitMode::Poll => {
                // Idle: read off late frames (so they are counted, and do not pile up in the
                // link), then sleep until a submission or the next cycle.
                for _ in 0..IDLE_DRAIN {
                    if self.receive_one(Wait::NoWait) != Received::Frame {
                        break;
                    }
                }
                // Held-back frames wait for the cycle: sleep until it is due, not woken by
                // more submissions, which could not go either.
                let ready = !self.staging.is_empty() && self.free_acyclic_record().is_some();
                let queue = &self.shared.queue;
                match &self.guest {
                    Some(_) if guest_busy => {}
                    Some(guest) if self.held => {
                        guest_readable = queue.park_beside(wake, false, guest.wait_fd());
                    }
                    Some(guest) if !ready => {
                        guest_readable = queue.park_beside(wake, true, guest.wait_fd());
                    }
                    None if self.held => queue.park(wake, false),
                    None if !ready => queue.park(wake, true),
                    _ => {}
                }
            }
            WaitMode::BusyPoll => match self.receive_one(Wait::NoWait) {
                Received::Frame => {}
                Received::Nothing if self.in_flight() => std::hint::spin_loop(),
                // Idle, still spinning for the next submission, but letting any other
                // runnable thread go first: on a machine without a core to spare, the
                // callers just completed would otherwise wait for the scheduler's tick.
                Received::Nothing => std::thread::yield_now(),
                Received::LinkError => self.back_off(wake),
            },
        }
        guest_readable || self.config.wait_mode == WaitMode::BusyPoll
    }

    /// After a link error: a link that keeps failing (a dead interface, a dropped peer)
    /// must not make the loop spin, so sleep until the next deadline, waking early only
    /// for control requests, or for a submission if nothing is due at all.
    fn back_off(&self, wake: Option<Instant>) {
        self.shared.queue.park(wake, wake.is_none());
    }

    /// Receives at most one frame and handles it.
    fn receive_one(&mut self, wait: Wait) -> Received {
        match self.link.recv(&mut self.rx, wait) {
            Ok(Some(len)) => {
                self.handle_frame(len.min(self.rx.len()));
                Received::Frame
            }
            Ok(None) => Received::Nothing,
            Err(_) => {
                self.shared.stats.link_errors.inc();
                Received::LinkError
            }
        }
    }

    /// Matches a received frame and completes what it answers.
    fn handle_frame(&mut self, len: usize) {
        let received_at = Instant::now();
        let stats = &self.shared.stats;
        let Ok(frame) = EthercatFrame::parse(&self.rx[..len]) else {
            stats.frames_foreign.inc();
            return;
        };
        let id = match match_frame(&frame, &self.indices, &self.records) {
            Match::Foreign => {
                stats.frames_foreign.inc();
                return;
            }
            Match::Stale => {
                stats.frames_stale.inc();
                return;
            }
            Match::Reply(id) => usize::from(id),
        };
        stats.frames_received.inc();
        let record = &mut self.records[id];
        let round_trip = received_at.saturating_duration_since(record.sent_at);
        // Only a frame sent once times the segment (Karn's rule): the reply to a frame sent
        // again may answer any of its attempts, and timing it from the last would understate.
        let timed = record.attempts == 1;
        if timed {
            stats.round_trip.record(round_trip);
        }
        let kind = record.kind;
        match kind {
            RecordKind::Acyclic => {
                let returned = frame.datagrams().into_iter().flatten().flatten();
                for (datagram, mut entry) in returned.zip(record.entries.drain(..)) {
                    if datagram.wkc == 0 && entry.again > 0 {
                        // A poll that found nothing: again in the next frame, without
                        // waking its caller (`BusHandle::submit_once_polling`).
                        entry.again -= 1;
                        entry.first_sent.get_or_insert(record.sent_at);
                        stats.datagrams_polled_again.inc();
                        self.staging.push_back(entry);
                        continue;
                    }
                    // The next step of a chain goes in the next frame out; after a datagram
                    // that did not count, the rest is skipped (dropped). Either happens
                    // before the caller hears of this one: by then a chain's feed has been
                    // taken or closed.
                    let next = entry
                        .then
                        .take()
                        .filter(|_| datagram.wkc > 0)
                        .map(|rest| rest.next_step());
                    complete(entry, &datagram, record.sent_at, stats);
                    if let Some(step) = next.filter(|step| !step.is_empty()) {
                        stats.datagrams_chained.inc();
                        self.staging.extend(step);
                    }
                }
            }
            RecordKind::Cyclic => {
                if let Some(cyclic) = &mut self.cyclic {
                    let reply = CyclicReply {
                        frame: &frame,
                        count: record.datagrams.len(),
                        round_trip,
                    };
                    cyclic.task.complete(&reply);
                }
            }
        }
        self.release_record(id);
        if kind == RecordKind::Acyclic && timed {
            self.learn_acyclic_cost(round_trip);
        }
    }

    // --- stopping -----------------------------------------------------------------------

    /// Fails every datagram still queued, staged or in flight with `Shutdown`.
    fn fail_everything(&mut self) {
        let queued = self.shared.queue.close();
        let in_flight = self.records.iter_mut().flat_map(|r| r.entries.drain(..));
        let mut failed = 0;
        for entry in queued
            .into_iter()
            .chain(self.staging.drain(..))
            .chain(in_flight)
        {
            entry.completer.complete(Err(BusError::Shutdown));
            failed += 1;
        }
        self.shared.stats.datagrams_failed.add(failed);
        self.cyclic = None;
    }
}

/// Completes one caller's datagram with its reply.
fn complete(mut entry: Queued, returned: &DatagramRepr<'_>, sent_at: Instant, stats: &BusStats) {
    let request = &mut entry.request;
    // The matcher checked that the lengths agree.
    if request.data.len() == returned.data.len() {
        request.data.copy_from_slice(returned.data);
    }
    let address =
        DatagramAddress::decode(returned.command, returned.address).unwrap_or(request.address);
    let response = DatagramResponse {
        data: std::mem::take(&mut request.data),
        wkc: returned.wkc,
        address,
        irq: returned.irq,
        sent_at: Stamp::from_instant(sent_at),
        polled_us: entry.first_sent.map_or(0, |first| {
            let polled = sent_at.saturating_duration_since(first).as_micros();
            u16::try_from(polled).unwrap_or(u16::MAX)
        }),
    };
    stats.datagrams_completed.inc();
    let result = if request.wkc.accepts(returned.wkc) {
        Ok(response)
    } else {
        stats.wkc_mismatches.inc();
        Err(BusError::WorkingCounter {
            expected: match request.wkc {
                WkcCheck::Exact(expected) => expected,
                WkcCheck::Ignore => returned.wkc,
            },
            got: returned.wkc,
            response,
        })
    };
    entry.completer.complete(result);
}

fn new_builder(tx: &mut [u8]) -> FrameBuilder<'_> {
    // The configuration check guarantees at least the 60 bytes a builder needs; a shorter
    // buffer would only make every push fail.
    FrameBuilder::new(tx).unwrap_or_else(|_| unreachable_builder())
}

#[cold]
fn unreachable_builder() -> ! {
    unreachable!("BusConfig::check guarantees a transmit buffer of at least 60 bytes")
}

/// Packs whole groups from the front of `staging` (refilled from `queue` when it runs
/// dry) into a frame in `tx` under record `id`. Returns the frame length, or `None` if not
/// even the first group fits the datagram indices left for acyclic traffic.
fn pack(
    tx: &mut [u8],
    config: &BusConfig,
    queue: &Submissions,
    staging: &mut VecDeque<Queued>,
    indices: &mut IndexTable,
    record: &mut FrameRecord,
    id: u16,
) -> Option<usize> {
    let room = config.datagram_room();
    let mut builder = new_builder(tx);
    loop {
        if staging.is_empty() {
            queue.take_into(staging);
        }
        let Some(front) = staging.front() else {
            break;
        };
        // Groups are queued whole, so all of one is in `staging` together.
        let group = usize::from(front.group_left.max(1)).min(staging.len());
        let bytes: usize = staging
            .range(..group)
            .map(|q| q.request.data.len() + OVERHEAD)
            .sum();
        if bytes > room || group > MAX_DATAGRAMS_PER_FRAME.min(ACYCLIC_INDEX_LIMIT) {
            // Unreachable: submissions are checked against these limits. Failing the group
            // keeps the loop from waiting forever for room that never comes.
            for entry in staging.drain(..group) {
                entry.completer.complete(Err(BusError::TooLarge {
                    what: "datagram group",
                    need: bytes,
                    room,
                }));
            }
            continue;
        }
        let used = builder.len() - FRAME_HEADERS_LEN;
        let fits = used + bytes <= room
            && indices.in_use() + group <= ACYCLIC_INDEX_LIMIT
            && record.datagrams.len() + group <= MAX_DATAGRAMS_PER_FRAME;
        if !fits {
            break;
        }
        for entry in staging.drain(..group) {
            let Some(index) = indices.take(id) else {
                // Unreachable: checked against the limit above.
                entry
                    .completer
                    .complete(Err(BusError::InvalidRequest("no datagram index free")));
                continue;
            };
            let request = &entry.request;
            let pushed = builder.push(&DatagramRepr::request(
                request.command,
                index,
                request.address,
                &request.data,
            ));
            match pushed {
                Ok(offset) => {
                    record.datagrams.push(SentDatagram {
                        index,
                        command: request.command,
                        address: request.address.to_raw(),
                        len: request.data.len() as u16,
                        offset,
                    });
                    record.entries.push(entry);
                }
                Err(_) => {
                    // Unreachable: requests are checked when submitted and room above.
                    indices.release(index);
                    entry.completer.complete(Err(BusError::InvalidRequest(
                        "the datagram could not be encoded",
                    )));
                }
            }
        }
    }
    if builder.is_empty() {
        return None;
    }
    match builder.finish(config.source_mac) {
        Ok(len) => Some(len),
        Err(_) => {
            // Unreachable: the frame holds at least one datagram. Should it happen, the
            // callers hear of it and the record is left clean for the next frame.
            for sent in &record.datagrams {
                indices.release(sent.index);
            }
            for entry in record.entries.drain(..) {
                entry.completer.complete(Err(BusError::InvalidRequest(
                    "the frame could not be finished",
                )));
            }
            record.clear();
            None
        }
    }
}

/// Closes the submission queue when the bus thread ends, however it ends.
struct CloseOnDrop(Arc<Shared>);

impl Drop for CloseOnDrop {
    fn drop(&mut self) {
        // Dropping the queued datagrams completes each with `Shutdown`.
        drop(self.0.queue.close());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::cyclic::{CyclicFrame, CyclicReply};
    use crate::link::MemoryLink;
    use crate::wire::command::Command;

    struct Idle(Duration);

    impl CyclicTask for Idle {
        fn period(&self) -> Duration {
            self.0
        }
        fn build(&mut self, _frame: &mut CyclicFrame<'_>) {}
        fn complete(&mut self, _reply: &CyclicReply<'_>) {}
    }

    /// A cyclic task of one BRD, so that each cycle sends a frame.
    struct OneRead(Duration);

    impl CyclicTask for OneRead {
        fn period(&self) -> Duration {
            self.0
        }
        fn build(&mut self, frame: &mut CyclicFrame<'_>) {
            let brd = DatagramAddress::broadcast(0x0130);
            frame.push_zeroed(Command::Brd, brd, 2).unwrap();
        }
        fn complete(&mut self, _reply: &CyclicReply<'_>) {}
    }

    fn engine() -> Engine<MemoryLink> {
        engine_with(BusConfig::default()).0
    }

    /// An engine on `config`, and the far end of its link.
    fn engine_with(config: BusConfig) -> (Engine<MemoryLink>, MemoryLink) {
        let (link, far) = MemoryLink::pair(4);
        let shared = Arc::new(Shared {
            queue: Submissions::new(config.queue_capacity),
            stats: BusStats::default(),
            config,
            ring: None,
            waitable: false,
        });
        (Engine::new(link, shared), far)
    }

    #[test]
    fn a_cycle_spin_wakes_the_thread_early_and_the_cycle_goes_when_due_never_before() {
        let spin = Duration::from_micros(200);
        let config = BusConfig {
            cycle_spin: spin,
            ..BusConfig::default()
        };
        let (mut engine, mut far) = engine_with(config);
        engine.change_cyclic(Some(Box::new(OneRead(Duration::from_millis(1)))));
        let id = engine.cyclic_record();
        let set_due = |engine: &mut Engine<MemoryLink>, after: Duration| {
            let due = Instant::now() + after;
            engine.cyclic.as_mut().unwrap().next_due = due;
            due
        };
        // The wake-up is asked for `spin` before the cycle (far off: the test's own
        // scheduling never brings it into the spin).
        let due = set_due(&mut engine, Duration::from_secs(10));
        assert_eq!(engine.next_wake(), Some(due - spin));
        // Woken before that (a submission, a frame): nothing is sent, nothing spun.
        engine.run_cycle_if_due();
        assert!(!engine.records[id].active);
        assert!(Instant::now() < due);
        // Inside the spin: the thread spins until the cycle is due, then sends it.
        let due = set_due(&mut engine, spin / 2);
        engine.run_cycle_if_due();
        assert!(engine.records[id].active, "the cycle went");
        assert!(Instant::now() >= due, "not before it was due");
        let mut rx = [0u8; 64];
        assert!(far.recv(&mut rx, Wait::NoWait).unwrap().is_some());
        // A spin of more than half the period is cut to half.
        let (mut engine, _far) = engine_with(BusConfig {
            cycle_spin: Duration::from_millis(2),
            ..BusConfig::default()
        });
        engine.change_cyclic(Some(Box::new(OneRead(Duration::from_millis(1)))));
        assert_eq!(
            engine.cyclic.as_ref().unwrap().spin,
            Duration::from_micros(500)
        );
        // Without a spin, the wake-up is the cycle's due time itself.
        let mut plain = self::engine();
        plain.change_cyclic(Some(Box::new(OneRead(Duration::from_millis(1)))));
        let due = set_due(&mut plain, Duration::from_secs(10));
        assert_eq!(plain.next_wake(), Some(due));
    }

    #[test]
    fn acyclic_frames_wait_when_the_cycle_is_due_before_they_could_be_back() {
        let mut engine = engine();
        let now = Instant::now();
        assert!(
            engine.acyclic_fits(now),
            "no cyclic task: nothing to protect"
        );
        engine.change_cyclic(Some(Box::new(Idle(Duration::from_millis(1)))));
        let due = |engine: &mut Engine<MemoryLink>, after: u64| {
            if let Some(cyclic) = engine.cyclic.as_mut() {
                cyclic.next_due = now + Duration::from_micros(after);
            }
        };
        // Nothing measured yet: nothing held.
        due(&mut engine, 100);
        assert!(engine.acyclic_fits(now));
        // Acyclic frames take 150 µs: one sent 100 µs before the cycle would delay it.
        engine.learn_acyclic_cost(Duration::from_micros(150));
        assert!(!engine.acyclic_fits(now));
        due(&mut engine, 200);
        assert!(engine.acyclic_fits(now));
        // The average moves by an eighth of each new round trip.
        engine.learn_acyclic_cost(Duration::from_micros(950));
        assert_eq!(engine.acyclic_cost, Duration::from_micros(250));
        // A slow link guards a quarter of the period at most, not its whole round trip.
        engine.acyclic_cost = Duration::from_millis(5);
        due(&mut engine, 300);
        assert!(engine.acyclic_fits(now));
        due(&mut engine, 200);
        assert!(!engine.acyclic_fits(now));
        // While the cyclic frame is out the next cycle cannot start: nothing held.
        let id = engine.cyclic_record();
        engine.records[id].active = true;
        assert!(engine.acyclic_fits(now));
    }
}
