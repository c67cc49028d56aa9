//! The callers' side of the bus: submitting datagrams from any thread or task.

use std::fmt;
use std::sync::Arc;

use crate::wire::datagram::OVERHEAD;

use super::Shared;
use super::chain::{Chain, ChainFeed, Chained};
use super::completion::{self, Pending};
use super::config::BusConfig;
use super::cyclic::CyclicTask;
use super::data::DatagramData;
use super::engine::ACYCLIC_INDEX_LIMIT;
use super::error::BusError;
use super::queue::Queued;
use super::record::MAX_DATAGRAMS_PER_FRAME;
use super::request::DatagramRequest;
use super::stats::BusStatsSnapshot;

/// A handle on a running bus: submit datagrams, install the cyclic task, read statistics.
///
/// Cheap to clone, and usable from any thread and any async task. Submitting never blocks:
/// it queues the datagram and returns a [`Pending`] to `.await` or
/// [`wait`](Pending::wait) for. When the last handle is dropped the bus shuts down.
#[derive(Clone)]
pub struct BusHandle {
    inner: Arc<Inner>,
}

/// Dropped with the last handle, which stops the bus.
struct Inner {
    shared: Arc<Shared>,
}

impl Drop for Inner {
    fn drop(&mut self) {
        self.shared.queue.request_shutdown();
    }
}

/// A chain's `Pending`s by step, its queue entries by step, and whether every step passed
/// the checks.
type ChainEntries = (
    Vec<Vec<Pending>>,
    std::collections::VecDeque<Vec<Queued>>,
    Result<(), BusError>,
);

/// One datagram on its own (not part of a group), and its caller's end.
fn queued(request: DatagramRequest, once: bool, again: u16) -> (Queued, Pending) {
    let (pending, completer) = completion::pair();
    let queued = Queued {
        request,
        completer,
        group_left: 1,
        once,
        again,
        first_sent: None,
        then: None,
    };
    (queued, pending)
}

impl BusHandle {
    pub(crate) fn new(shared: Arc<Shared>) -> BusHandle {
        BusHandle {
            inner: Arc::new(Inner { shared }),
        }
    }

    fn shared(&self) -> &Shared {
        &self.inner.shared
    }

    /// What the ring link knows of the ring, when the bus runs on one
    /// ([`Bus::start_ring`](super::Bus::start_ring)); `None` on a single port.
    pub fn ring(&self) -> Option<&super::redundancy::RingWatch> {
        self.shared().ring.as_ref()
    }

    /// Queues one datagram. Requests that cannot be sent (an address of another
    /// addressing mode than the command's, data too long for a frame) and submissions to
    /// a full queue or a stopped bus complete at once with the error.
    pub fn submit(&self, request: DatagramRequest) -> Pending {
        self.submit_single(request, false, 0)
    }

    /// Queues one datagram that is **never sent again**: if its frame is lost, it fails
    /// with [`BusError::Timeout`] after [`BusConfig::response_timeout`] instead of being
    /// retried (the other datagrams of that frame are retried as usual).
    ///
    /// For reads with a side effect, where a blind retry would do harm: reading a slave's
    /// send mailbox (SM1) empties it, so a retried read of a lost frame could return the
    /// *next* message and the lost one would be gone without a trace. The mailbox layer
    /// reads SM1 with this and recovers a lost read with the repeat procedure instead
    /// (ETG.1000.4, spec-notes §mbx.repeat).
    pub fn submit_once(&self, request: DatagramRequest) -> Pending {
        self.submit_single(request, true, 0)
    }

    /// [`Self::submit_once`] for polling: while the datagram comes back with working
    /// counter 0 the bus thread sends it again at once, in the next frame out, up to `again`
    /// more times, and completes it with the first reply that counted or the last empty
    /// one. The caller is woken once, not at every try.
    ///
    /// The mailbox layer polls SM1 this way while it waits for an answer: a read of an empty
    /// send mailbox is not counted by the slave and takes nothing, so sending it again is
    /// harmless, and the tries follow each other at the wire's pace instead of the pace of
    /// two thread wake-ups per try. A lost frame ends the polling with [`BusError::Timeout`]
    /// as with `submit_once`.
    pub fn submit_once_polling(&self, request: DatagramRequest, again: u16) -> Pending {
        self.submit_single(request, true, again)
    }

    /// Queues `first` as [`Self::submit`] does and `poll` as [`Self::submit_once_polling`]
    /// does, in one submission: the bus thread takes both at once, so they travel in the same
    /// frame, `first` ahead, whenever it has room for both, and a sleeping bus thread is woken
    /// once. They are not a group: each is retried, polled and completed on its own.
    ///
    /// The mailbox layer writes SM0 and reads SM1 this way. Submitted one after the other,
    /// the first submission woke the bus thread, which on a warm CPU could send the write
    /// alone before the read was queued: a frame and a wake-up more for an answer the slave
    /// had ready in the write's own pass.
    pub fn submit_then_poll(
        &self,
        first: DatagramRequest,
        poll: DatagramRequest,
        again: u16,
    ) -> (Pending, Pending) {
        if let Err(err) = self.check(&first) {
            return (
                Pending::ready(Err(err)),
                self.submit_once_polling(poll, again),
            );
        }
        if let Err(err) = self.check(&poll) {
            return (self.submit(first), Pending::ready(Err(err)));
        }
        let (first, first_pending) = queued(first, false, 0);
        let (poll, poll_pending) = queued(poll, true, again);
        self.push([first, poll]);
        (first_pending, poll_pending)
    }

    fn submit_single(&self, request: DatagramRequest, once: bool, again: u16) -> Pending {
        if let Err(err) = self.check(&request) {
            return Pending::ready(Err(err));
        }
        let (queued, pending) = queued(request, once, again);
        self.push([queued]);
        pending
    }

    /// Queues independent datagrams in one submission; all are refused together if the
    /// queue has no room for them (or the bus stopped).
    fn push<const N: usize>(&self, batch: [Queued; N]) {
        match self.shared().queue.push(batch.into_iter()) {
            Ok(woke) => self.count_wakeup(woke),
            Err((err, refused)) => {
                for entry in refused {
                    entry.completer.complete(Err(err.clone()));
                }
            }
        }
    }

    fn count_wakeup(&self, woke: bool) {
        if woke {
            self.shared().stats.wakeups.inc();
        }
    }

    /// Queues datagrams that must travel in the same frame, in this order (the cyclic
    /// exchange, a DC time distribution next to the read that latches it). Returns one
    /// `Pending` per datagram, in the same order.
    ///
    /// The group is refused as a whole (every `Pending` completes with the error) if any
    /// request is invalid, if together they do not fit one frame, or if the queue has no
    /// room for all of them. A lost frame is sent again whole, so the group stays together.
    pub fn submit_group(
        &self,
        requests: impl IntoIterator<Item = DatagramRequest>,
    ) -> Vec<Pending> {
        let requests: Vec<DatagramRequest> = requests.into_iter().collect();
        let mut pendings = Vec::with_capacity(requests.len());
        let mut completers = Vec::with_capacity(requests.len());
        for _ in 0..requests.len() {
            let (pending, completer) = completion::pair();
            pendings.push(pending);
            completers.push(completer);
        }
        let checked = self.check_group(&requests);
        let count = requests.len();
        let batch =
            requests
                .into_iter()
                .zip(completers)
                .enumerate()
                .map(|(i, (request, completer))| Queued {
                    request,
                    completer,
                    // Checked: a group has at most `MAX_DATAGRAMS_PER_FRAME` members.
                    group_left: (count - i) as u16,
                    once: false,
                    again: 0,
                    first_sent: None,
                    then: None,
                });
        let refused = match checked {
            Ok(()) => match self.shared().queue.push(batch) {
                Ok(woke) => {
                    self.count_wakeup(woke);
                    None
                }
                Err(refused) => Some(refused),
            },
            Err(err) => Some((err, batch.collect())),
        };
        if let Some((err, refused)) = refused {
            for entry in refused {
                entry.completer.complete(Err(err.clone()));
            }
        }
        pendings
    }

    /// Queues `steps`, each a group of datagrams that share a frame, to be sent one step
    /// after the other: the bus thread sends a step in the next frame out once the step
    /// before came back with its **first** datagram counted (working counter above 0),
    /// without waking the caller in between. After a first datagram that did not count or
    /// failed, the steps behind it are not sent and complete with [`BusError::Skipped`].
    /// Returns one `Pending` per datagram, by step.
    ///
    /// For messages to a slave's receive mailbox, one write per step: the next is written
    /// as soon as the one before was taken, at the frame round trip's pace (see
    /// `chain`'s module documentation). Every step is checked as [`Self::submit_group`]
    /// checks a group; if one is refused, every `Pending` completes with the error.
    pub fn submit_chain(&self, steps: Vec<Vec<Chained>>) -> Vec<Vec<Pending>> {
        self.chain_beside(steps, None, None)
    }

    /// [`Self::submit_chain`], and `poll` queued as [`Self::submit_once_polling`] does in the
    /// same submission as the chain's first step: it travels in that step's frame when
    /// there is room, on its own otherwise, and is completed on its own either way.
    ///
    /// The mailbox layer writes EoE fragments this way with the read of SM1 that picks up
    /// the other direction's fragments: a frame fewer per chain than a read submitted
    /// after it, which the bus thread could send on its own.
    pub fn submit_chain_then_poll(
        &self,
        steps: Vec<Vec<Chained>>,
        poll: DatagramRequest,
        again: u16,
    ) -> (Vec<Vec<Pending>>, Pending) {
        if let Err(err) = self.check(&poll) {
            return (self.submit_chain(steps), Pending::ready(Err(err)));
        }
        let (poll, pending) = queued(poll, true, again);
        (self.chain_beside(steps, Some(poll), None), pending)
    }

    /// [`Self::submit_chain_then_poll`] for a chain that more steps may join while it runs
    /// ([`Self::feed_chain`] with the feed returned): the chain ends when its steps run out
    /// with none fed, or at the first step that does not count, as any chain.
    pub fn submit_chain_fed(
        &self,
        steps: Vec<Vec<Chained>>,
        poll: DatagramRequest,
    ) -> (Vec<Vec<Pending>>, Pending, ChainFeed) {
        let feed = ChainFeed::default();
        if let Err(err) = self.check(&poll) {
            return (self.submit_chain(steps), Pending::ready(Err(err)), feed);
        }
        let (poll, pending) = queued(poll, true, 0);
        let pendings = self.chain_beside(steps, Some(poll), Some(feed.clone()));
        (pendings, pending, feed)
    }

    /// Adds `steps` behind a chain submitted with [`Self::submit_chain_fed`], checked as
    /// [`Self::submit_chain`] checks them: the first is sent in the next frame out once the
    /// chain's last step before it counted, without a wake-up of the bus thread. `None` if
    /// the chain has ended by now (nothing is sent: submit them as a chain of their own);
    /// refused steps complete with the error.
    pub fn feed_chain(
        &self,
        feed: &ChainFeed,
        steps: Vec<Vec<Chained>>,
    ) -> Option<Vec<Vec<Pending>>> {
        let (pendings, queued, checked) = self.chain_entries(steps);
        if let Err(err) = checked {
            for entry in queued.into_iter().flatten() {
                entry.completer.complete(Err(err.clone()));
            }
            return Some(pendings);
        }
        match feed.extend(queued) {
            Ok(()) => Some(pendings),
            Err(back) => {
                // Never sent: their completions are dropped unused along with them.
                for entry in back.into_iter().flatten() {
                    entry.completer.complete(Err(BusError::Skipped));
                }
                None
            }
        }
    }

    /// The entries of a chain's steps, their `Pending`s, and whether every step passes the
    /// checks.
    fn chain_entries(&self, steps: Vec<Vec<Chained>>) -> ChainEntries {
        let checked = steps.iter().try_for_each(|step| {
            if step.is_empty() {
                return Err(BusError::InvalidRequest("an empty step of a chain"));
            }
            let requests: Vec<&DatagramRequest> = step.iter().map(|c| &c.request).collect();
            self.check_requests(&requests)
        });
        let mut pendings = Vec::with_capacity(steps.len());
        let mut queued = std::collections::VecDeque::with_capacity(steps.len());
        for step in steps {
            let count = step.len();
            let mut step_pendings = Vec::with_capacity(count);
            let mut entries = Vec::with_capacity(count);
            for (i, chained) in step.into_iter().enumerate() {
                let (pending, completer) = completion::pair();
                step_pendings.push(pending);
                entries.push(Queued {
                    request: chained.request,
                    completer,
                    // Checked: a step has at most `MAX_DATAGRAMS_PER_FRAME` members.
                    group_left: (count - i) as u16,
                    once: chained.once,
                    again: 0,
                    first_sent: None,
                    then: None,
                });
            }
            pendings.push(step_pendings);
            queued.push_back(entries);
        }
        (pendings, queued, checked)
    }

    /// Queues a chain (fed by `feed`, if any), and `beside` (a lone datagram) in the same
    /// submission.
    fn chain_beside(
        &self,
        steps: Vec<Vec<Chained>>,
        beside: Option<Queued>,
        feed: Option<ChainFeed>,
    ) -> Vec<Vec<Pending>> {
        let (pendings, mut queued, checked) = self.chain_entries(steps);
        if let Err(err) = checked {
            // Nothing runs: a feed closes at once, so nothing joins it.
            let fed = feed.map(|feed| feed.close()).unwrap_or_default();
            for entry in queued.into_iter().chain(fed).flatten().chain(beside) {
                entry.completer.complete(Err(err.clone()));
            }
            return pendings;
        }
        let Some(mut first) = queued.pop_front() else {
            if let Some(feed) = feed {
                drop(Chain::new(queued, Some(feed)));
            }
            if let Some(beside) = beside {
                self.push([beside]);
            }
            return pendings;
        };
        if let Some(head) = first.first_mut() {
            head.then = Chain::new(queued, feed);
        }
        first.extend(beside);
        match self.shared().queue.push(first.into_iter()) {
            Ok(woke) => self.count_wakeup(woke),
            Err((err, refused)) => {
                for mut entry in refused {
                    if let Some(rest) = entry.then.take() {
                        (*rest).fail(&err);
                    }
                    entry.completer.complete(Err(err.clone()));
                }
            }
        }
        pendings
    }

    fn check(&self, request: &DatagramRequest) -> Result<(), BusError> {
        request.address.encode(request.command).map_err(|_| {
            BusError::InvalidRequest("the address's addressing mode is not the command's")
        })?;
        let max = self.shared().config.max_data_len();
        if request.data.len() > max {
            return Err(BusError::TooLarge {
                what: "datagram data",
                need: request.data.len(),
                room: max,
            });
        }
        Ok(())
    }

    fn check_group(&self, requests: &[DatagramRequest]) -> Result<(), BusError> {
        let requests: Vec<&DatagramRequest> = requests.iter().collect();
        self.check_requests(&requests)
    }

    fn check_requests(&self, requests: &[&DatagramRequest]) -> Result<(), BusError> {
        for request in requests {
            self.check(request)?;
        }
        let config = &self.shared().config;
        let limit = MAX_DATAGRAMS_PER_FRAME
            .min(ACYCLIC_INDEX_LIMIT)
            .min(config.queue_capacity);
        if requests.len() > limit {
            return Err(BusError::TooLarge {
                what: "datagram group (datagrams)",
                need: requests.len(),
                room: limit,
            });
        }
        let bytes: usize = requests.iter().map(|r| r.data.len() + OVERHEAD).sum();
        if bytes > config.datagram_room() {
            return Err(BusError::TooLarge {
                what: "datagram group (bytes)",
                need: bytes,
                room: config.datagram_room(),
            });
        }
        Ok(())
    }

    /// APRD: reads `len` bytes at `ado` of the slave at ring `position`.
    pub fn aprd(&self, position: u16, ado: u16, len: usize) -> Pending {
        self.submit(DatagramRequest::aprd(position, ado, len))
    }

    /// APWR: writes `data` at `ado` of the slave at ring `position`.
    pub fn apwr(&self, position: u16, ado: u16, data: impl Into<DatagramData>) -> Pending {
        self.submit(DatagramRequest::apwr(position, ado, data))
    }

    /// APRW: exchanges `data` with the memory at `ado` of the slave at ring `position`.
    pub fn aprw(&self, position: u16, ado: u16, data: impl Into<DatagramData>) -> Pending {
        self.submit(DatagramRequest::aprw(position, ado, data))
    }

    /// FPRD: reads `len` bytes at `ado` of the slave with station address `station`.
    pub fn fprd(&self, station: u16, ado: u16, len: usize) -> Pending {
        self.submit(DatagramRequest::fprd(station, ado, len))
    }

    /// FPWR: writes `data` at `ado` of the slave with station address `station`.
    pub fn fpwr(&self, station: u16, ado: u16, data: impl Into<DatagramData>) -> Pending {
        self.submit(DatagramRequest::fpwr(station, ado, data))
    }

    /// FPRW: exchanges `data` with the memory at `ado` of the slave `station`.
    pub fn fprw(&self, station: u16, ado: u16, data: impl Into<DatagramData>) -> Pending {
        self.submit(DatagramRequest::fprw(station, ado, data))
    }

    /// BRD: ORs `len` bytes at `ado` of every slave; the working counter counts them.
    pub fn brd(&self, ado: u16, len: usize) -> Pending {
        self.submit(DatagramRequest::brd(ado, len))
    }

    /// BWR: writes `data` at `ado` of every slave.
    pub fn bwr(&self, ado: u16, data: impl Into<DatagramData>) -> Pending {
        self.submit(DatagramRequest::bwr(ado, data))
    }

    /// BRW: broadcast read-write at `ado`.
    pub fn brw(&self, ado: u16, data: impl Into<DatagramData>) -> Pending {
        self.submit(DatagramRequest::brw(ado, data))
    }

    /// LRD: reads `len` bytes of logical memory at `address`.
    pub fn lrd(&self, address: u32, len: usize) -> Pending {
        self.submit(DatagramRequest::lrd(address, len))
    }

    /// LWR: writes `data` to logical memory at `address`.
    pub fn lwr(&self, address: u32, data: impl Into<DatagramData>) -> Pending {
        self.submit(DatagramRequest::lwr(address, data))
    }

    /// LRW: writes `data` to and reads inputs from logical memory at `address`.
    pub fn lrw(&self, address: u32, data: impl Into<DatagramData>) -> Pending {
        self.submit(DatagramRequest::lrw(address, data))
    }

    /// ARMW: the slave at `position` reads `len` bytes at `ado`, all others write them.
    pub fn armw(&self, position: u16, ado: u16, len: usize) -> Pending {
        self.submit(DatagramRequest::armw(position, ado, len))
    }

    /// FRMW: the slave `station` reads `len` bytes at `ado`, all others write them.
    pub fn frmw(&self, station: u16, ado: u16, len: usize) -> Pending {
        self.submit(DatagramRequest::frmw(station, ado, len))
    }

    /// Installs `task` as the cyclic task (replacing and dropping any earlier one), or with
    /// `None` stops cyclic exchange. Takes effect on the bus thread's next turn.
    ///
    /// A task must not own a `BusHandle`: the bus owns the task, so the last handle would
    /// never be dropped and the bus would only stop through [`BusHandle::shutdown`].
    pub fn set_cyclic(&self, task: Option<Box<dyn CyclicTask>>) {
        self.shared().queue.request_cyclic(task);
    }

    /// Whether [`Self::set_guest`] can install a guest: the link has a file descriptor to
    /// wait on, and the bus sleeps (not [`WaitMode::BusyPoll`](super::WaitMode::BusyPoll),
    /// which would run the guest's turn on every spin).
    pub fn can_host_guest(&self) -> bool {
        self.shared().waitable && self.config().wait_mode == super::WaitMode::Poll
    }

    /// Installs `guest` on the bus thread (replacing and dropping any earlier one there),
    /// or with `None` removes it. Takes effect on the bus thread's next turn. Refused (the
    /// guest handed back) when the link cannot be waited on with a file descriptor.
    pub fn set_guest(
        &self,
        guest: Option<Box<dyn super::Guest>>,
    ) -> Result<(), Option<Box<dyn super::Guest>>> {
        if guest.is_some() && !self.can_host_guest() {
            return Err(guest);
        }
        self.shared().queue.request_guest(guest);
        Ok(())
    }

    /// The bus's counters now.
    pub fn stats(&self) -> BusStatsSnapshot {
        self.shared().stats.snapshot()
    }

    /// The configuration the bus runs with.
    pub fn config(&self) -> &BusConfig {
        &self.shared().config
    }

    /// Datagrams waiting in the submission queue (not yet taken by the bus thread).
    pub fn queued(&self) -> usize {
        self.shared().queue.len()
    }

    /// Stops the bus thread: datagrams queued or in flight complete with
    /// [`BusError::Shutdown`], and later submissions fail with it. Other handles stay valid
    /// but every submission through them fails. Returns at once; join the thread returned
    /// by [`Bus::start`](super::Bus::start) to wait for it.
    pub fn shutdown(&self) {
        self.shared().queue.request_shutdown();
    }
}

impl fmt::Debug for BusHandle {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("BusHandle")
            .field("config", self.config())
            .field("queued", &self.queued())
            .finish()
    }
}
