//! Chains: steps of datagrams the bus thread sends one after the other, each once the step
//! before came back counted, without waking the caller in between
//! ([`BusHandle::submit_chain`](super::BusHandle::submit_chain)).
//!
//! A caller that has several messages for one slave's receive mailbox (SM0) can write only
//! one at a time: the mailbox takes the next once the slave has taken the one before, and a
//! write to a full mailbox is not counted and changes nothing (ETG.1000.4, spec-notes
//! §mbx.chain). Woken after each write to send the next, the caller adds two thread
//! hand-offs per message to the frame's round trip; a chain leaves the next write to the bus
//! thread, which sends it in the next frame out as soon as the write before it counted.
//!
//! A chain may be *fed* while it runs ([`ChainFeed`]): steps given to its feed follow its
//! own, so a caller with a stream of messages keeps the bus thread writing while it is
//! woken for the steps before, instead of adding its wake-up and a new submission between
//! two chains. A chain that ran out of steps, or stopped, closes its feed: steps given
//! after that come back to the caller, and steps waiting in it when the chain stopped are
//! skipped with the chain's own.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use super::error::BusError;
use super::queue::Queued;
use super::request::DatagramRequest;

/// One datagram of a chain's step.
#[derive(Debug)]
pub struct Chained {
    /// The datagram.
    pub request: DatagramRequest,
    /// Never sent again after a lost frame, as with
    /// [`BusHandle::submit_once`](super::BusHandle::submit_once) (a read of a send mailbox).
    pub once: bool,
}

impl Chained {
    /// A datagram the bus sends again after a lost frame, as usual.
    pub fn new(request: DatagramRequest) -> Chained {
        Chained {
            request,
            once: false,
        }
    }

    /// A datagram never sent again after a lost frame.
    pub fn once(request: DatagramRequest) -> Chained {
        Chained {
            request,
            once: true,
        }
    }
}

/// The steps of a chain still to be sent, carried by the first datagram of the step on its
/// way. Dropped unsent (the step before did not count, failed, or the bus stopped), its
/// datagrams complete with [`BusError::Skipped`].
#[derive(Debug)]
pub(crate) struct Chain {
    steps: VecDeque<Vec<Queued>>,
    feed: Option<ChainFeed>,
}

impl Chain {
    /// The steps after the first, and the feed that may add more; `None` if there are
    /// neither.
    pub fn new(steps: VecDeque<Vec<Queued>>, feed: Option<ChainFeed>) -> Option<Box<Chain>> {
        (!steps.is_empty() || feed.is_some()).then(|| Box::new(Chain { steps, feed }))
    }

    /// The next step to stage, its first datagram carrying the rest; empty when the chain
    /// has ended (its feed is then closed).
    pub fn next_step(mut self: Box<Self>) -> Vec<Queued> {
        if self.steps.is_empty()
            && let Some(feed) = &self.feed
        {
            // Under the feed's lock: a step given now either is taken or comes back.
            self.steps.append(&mut feed.lock().steps);
        }
        let mut step = self.steps.pop_front().unwrap_or_default();
        if (!self.steps.is_empty() || self.feed.is_some())
            && let Some(first) = step.first_mut()
        {
            first.then = Some(self);
        }
        step
    }

    /// Completes every datagram of the rest, and of its feed, with `err`.
    pub fn fail(mut self, err: &BusError) {
        self.complete_rest(err);
    }

    /// Closes the feed and completes what is left, its own steps and the fed ones, with
    /// `err`.
    fn complete_rest(&mut self, err: &BusError) {
        let fed = self
            .feed
            .take()
            .map(|feed| feed.close())
            .unwrap_or_default();
        for entry in self.steps.drain(..).chain(fed).flatten() {
            entry.completer.complete(Err(err.clone()));
        }
    }
}

impl Drop for Chain {
    fn drop(&mut self) {
        self.complete_rest(&BusError::Skipped);
    }
}

/// Steps that join a running chain behind its own
/// ([`BusHandle::submit_chain_fed`](super::BusHandle::submit_chain_fed),
/// [`BusHandle::feed_chain`](super::BusHandle::feed_chain)). Shared by the caller and the
/// chain on the bus thread; each takes its lock only for a move of the steps.
#[derive(Debug, Clone, Default)]
pub struct ChainFeed(Arc<Mutex<Feed>>);

#[derive(Debug, Default)]
pub(crate) struct Feed {
    steps: VecDeque<Vec<Queued>>,
    closed: bool,
}

impl ChainFeed {
    fn lock(&self) -> MutexGuard<'_, Feed> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Adds `steps` behind the chain's, unless it has ended: then they come back.
    pub(crate) fn extend(&self, steps: VecDeque<Vec<Queued>>) -> Result<(), VecDeque<Vec<Queued>>> {
        let mut feed = self.lock();
        if feed.closed {
            return Err(steps);
        }
        feed.steps.extend(steps);
        Ok(())
    }

    /// Takes back the steps that wait in the feed (the chain has not started them): they
    /// complete with [`BusError::Skipped`], and the chain goes on with what it has.
    pub fn take_back(&self) {
        let steps = std::mem::take(&mut self.lock().steps);
        for entry in steps.into_iter().flatten() {
            entry.completer.complete(Err(BusError::Skipped));
        }
    }

    /// Whether the chain has ended (ran out of steps, stopped or failed).
    pub fn is_closed(&self) -> bool {
        self.lock().closed
    }

    /// The chain ended: no step joins any more; returns the ones that waited.
    pub(crate) fn close(&self) -> VecDeque<Vec<Queued>> {
        let mut feed = self.lock();
        feed.closed = true;
        std::mem::take(&mut feed.steps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::completion::pair;

    fn step(n: usize) -> (Vec<Queued>, Vec<crate::bus::Pending>) {
        (0..n)
            .map(|i| {
                let (pending, completer) = pair();
                let queued = Queued {
                    request: DatagramRequest::brd(0, 2),
                    completer,
                    group_left: (n - i) as u16,
                    once: false,
                    again: 0,
                    first_sent: None,
                    then: None,
                };
                (queued, pending)
            })
            .unzip()
    }

    #[test]
    fn each_step_carries_the_rest_and_an_unsent_rest_is_skipped() {
        let (second, _) = step(2);
        let (third, third_pending) = step(1);
        let chain = Chain::new([second, third].into_iter().collect(), None).unwrap();
        let mut staged = chain.next_step();
        assert_eq!(staged.len(), 2);
        assert!(staged[1].then.is_none());
        let rest = staged[0]
            .then
            .take()
            .expect("the third step rides on the second");
        drop(rest);
        for pending in third_pending {
            assert!(matches!(pending.wait(), Err(BusError::Skipped)));
        }
        assert!(Chain::new(VecDeque::new(), None).is_none());
    }

    #[test]
    fn a_fed_step_follows_the_chains_own_and_a_feed_closes_when_the_chain_ends() {
        let feed = ChainFeed::default();
        let (second, _) = step(1);
        let chain = Chain::new([second].into_iter().collect(), Some(feed.clone())).unwrap();
        let mut staged = chain.next_step();
        let rest = staged[0]
            .then
            .take()
            .expect("the feed rides on the last own step");
        let (fed, fed_pending) = step(1);
        assert!(feed.extend([fed].into_iter().collect()).is_ok());
        let mut staged = rest.next_step();
        assert_eq!(staged.len(), 1, "the fed step is next");
        let rest = staged[0].then.take().expect("the feed still rides on it");
        assert!(!feed.is_closed());
        assert!(
            rest.next_step().is_empty(),
            "nothing more fed: the chain ends"
        );
        assert!(feed.is_closed());
        let (late, late_pending) = step(1);
        let back = feed.extend([late].into_iter().collect());
        assert_eq!(
            back.map_err(|steps| steps.len()),
            Err(1),
            "a late step comes back"
        );
        drop(staged);
        drop(late_pending);
        drop(fed_pending);
    }

    #[test]
    fn steps_taken_back_are_skipped_and_the_chain_goes_on_with_its_own() {
        let feed = ChainFeed::default();
        let (second, _) = step(1);
        let chain = Chain::new([second].into_iter().collect(), Some(feed.clone())).unwrap();
        let (fed, fed_pending) = step(1);
        assert!(feed.extend([fed].into_iter().collect()).is_ok());
        feed.take_back();
        for pending in fed_pending {
            assert!(matches!(pending.wait(), Err(BusError::Skipped)));
        }
        assert!(!feed.is_closed(), "the chain still runs");
        let mut staged = chain.next_step();
        assert_eq!(staged.len(), 1, "its own step");
        let rest = staged[0].then.take().expect("the feed rides on it");
        assert!(rest.next_step().is_empty(), "and nothing after it");
        assert!(feed.is_closed());
    }

    #[test]
    fn steps_waiting_in_the_feed_of_a_stopped_chain_are_skipped() {
        let feed = ChainFeed::default();
        let chain = Chain::new(VecDeque::new(), Some(feed.clone())).unwrap();
        let (fed, fed_pending) = step(2);
        assert!(feed.extend([fed].into_iter().collect()).is_ok());
        // The step carrying the chain did not count: the chain is dropped.
        drop(chain);
        assert!(feed.is_closed());
        for pending in fed_pending {
            assert!(matches!(pending.wait(), Err(BusError::Skipped)));
        }
    }
}
