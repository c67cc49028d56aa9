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

use std::collections::VecDeque;

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
}

impl Chain {
    /// The steps after the first, or `None` if there are none.
    pub fn new(steps: VecDeque<Vec<Queued>>) -> Option<Box<Chain>> {
        (!steps.is_empty()).then(|| Box::new(Chain { steps }))
    }

    /// The next step to stage, its first datagram carrying the rest.
    pub fn next_step(mut self: Box<Self>) -> Vec<Queued> {
        let mut step = self.steps.pop_front().unwrap_or_default();
        if !self.steps.is_empty()
            && let Some(first) = step.first_mut()
        {
            first.then = Some(self);
        }
        step
    }

    /// Completes every datagram of the rest with `err`.
    pub fn fail(mut self, err: &BusError) {
        for entry in self.steps.drain(..).flatten() {
            entry.completer.complete(Err(err.clone()));
        }
    }
}

impl Drop for Chain {
    fn drop(&mut self) {
        for entry in self.steps.drain(..).flatten() {
            entry.completer.complete(Err(BusError::Skipped));
        }
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
        let chain = Chain::new([second, third].into_iter().collect()).unwrap();
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
        assert!(Chain::new(VecDeque::new()).is_none());
    }
}
