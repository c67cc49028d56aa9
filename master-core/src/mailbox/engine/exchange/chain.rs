//! Streams of messages through the mailbox in chains the bus thread runs itself
//! ([`BusHandle::submit_chain`](crate::bus::BusHandle::submit_chain); spec-notes
//! §mbx.chain): several writes into SM0, each as soon as the slave took the one before, and
//! several reads of SM1, each as soon as the one before found a message. A stream of EoE
//! fragments then moves at the frame round trip's pace instead of that pace plus two thread
//! hand-offs per fragment. Writes go in runs that later batches join while they are under
//! way ([`ChainFeed`]), so the owner's wake-up between two batches is not in the stream's
//! path either; counters of writes that never went in are taken back.
//!
//! Reads of SM1 in a chain follow each other (the next is sent only once the one before
//! came back with a message), so at most one is in flight: a lost one ends the chain and is
//! recovered before SM1 is read again (spec-notes §mbx.repeat).
//!
//! Only the slave's owner task runs chains (EoE and its idle reads), never a request a
//! caller may drop: a chain runs to its end on the bus thread whoever still waits for it,
//! and the owner goes away only when the slave's mailbox is let go.

use crate::bus::{
    BusError, ChainFeed, Chained, DatagramData, DatagramRequest, DatagramResult, Pending,
};
use crate::mailbox::error::{MailboxError, Result};
use crate::wire::WireError;
use crate::wire::mailbox::MailboxType;

use super::super::demux::Want;
use super::super::stats::inc;
use super::{Exchange, Read};

/// A chain of writes into SM0 under way, which more writes may join while it runs
/// ([`Exchange::start_chain`], [`Exchange::join_chain`]).
pub(crate) struct WriteRun {
    feed: ChainFeed,
    mailbox_type: MailboxType,
}

/// The writes of one part of a [`WriteRun`], in order, to be counted with
/// [`Exchange::finish_batch`].
pub(crate) struct WriteBatch {
    writes: Vec<Pending>,
    /// The request counter before the batch's first write.
    counter_before: u8,
}

impl WriteBatch {
    /// How many messages the batch writes.
    pub fn len(&self) -> usize {
        self.writes.len()
    }
}

impl Exchange {
    /// Starts writing `count` messages of `mailbox_type` into SM0 one after the other,
    /// message `i` made by `emit(i, buf)` as for [`Self::send`], with one read of SM1 sent
    /// beside them (settled as the read behind a [`Self::send`]). Messages that do not
    /// encode end the batch before them (the caller meets them again); an error is one for
    /// the first. More batches may join the run while it is under way
    /// ([`Self::join_chain`]); each is counted with [`Self::finish_batch`]. For messages
    /// that expect no answer (EoE fragments).
    pub async fn start_chain(
        &mut self,
        mailbox_type: MailboxType,
        count: usize,
        emit: impl FnMut(usize, &mut [u8]) -> core::result::Result<usize, WireError>,
    ) -> Result<(WriteRun, WriteBatch)> {
        self.chain_ready().await?;
        let counter_before = self.counters.last_tx();
        let steps = self.compose_writes(mailbox_type, count, emit)?;
        // The read goes with the first write, in its frame when there is room: what the
        // slave sends meanwhile (the other direction's frames) is read without a turn or a
        // frame of its own.
        let (writes, read, feed) = self.bus.submit_chain_fed(steps, self.read_request());
        *self
            .shared
            .run
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(feed.clone());
        self.ahead = Some((read, Some(Want::Reply(mailbox_type))));
        let writes = writes.into_iter().flatten().collect();
        let batch = WriteBatch {
            writes,
            counter_before,
        };
        Ok((WriteRun { feed, mailbox_type }, batch))
    }

    /// Adds `count` more messages behind those of `run` (as [`Self::start_chain`] makes
    /// them), to be written once the ones before went in, without a new submission. `None`
    /// if the run has ended by now, or the first does not encode: nothing of them is
    /// written.
    pub fn join_chain(
        &mut self,
        run: &WriteRun,
        count: usize,
        emit: impl FnMut(usize, &mut [u8]) -> core::result::Result<usize, WireError>,
    ) -> Option<WriteBatch> {
        if run.feed.is_closed() {
            return None;
        }
        let counter_before = self.counters.last_tx();
        let joined = self
            .compose_writes(run.mailbox_type, count, emit)
            .ok()
            .and_then(|steps| self.bus.feed_chain(&run.feed, steps));
        let Some(writes) = joined else {
            self.rewind_counter(counter_before);
            return None;
        };
        // A request that came meanwhile may have found the feed empty: it takes priority.
        if self.queued_requests() > 0 {
            run.feed.take_back();
        }
        Some(WriteBatch {
            writes: writes.into_iter().flatten().collect(),
            counter_before,
        })
    }

    /// Waits for the writes of `batch` and counts them. Returns how many went in, in order:
    /// fewer than its length when SM0 was still full for one (the slave had not yet taken
    /// the one before; then also `true`), or when the run stopped before the batch or a
    /// request took it back; the rest is then the caller's to send again (with
    /// [`Self::send`], which waits for room). An error is a write whose fate is unknown (no
    /// reply after the bus's retries), after the ones counted.
    pub async fn finish_batch(&mut self, batch: WriteBatch) -> (usize, bool, Result<()>) {
        let mut writes = batch.writes;
        let len = writes.len();
        let Some(last) = writes.pop() else {
            return (0, false, Ok(()));
        };
        // The steps complete in order and a stopped chain completes the rest at once, so the
        // last write is the one to wait for: the others are done by then.
        let last = last.await;
        let mut counted = 0;
        let mut full = false;
        let mut failure = None;
        for write in writes {
            let result = write.await;
            self.count_write(&result, &mut counted, &mut full, &mut failure);
        }
        self.count_write(&last, &mut counted, &mut full, &mut failure);
        // The slave took the writes counted, and perhaps the one that failed; the rest of
        // the batch and any batch composed behind it were never written.
        let taken = counted + usize::from(failure.is_some());
        if taken < len {
            let mut counters =
                super::super::counter::Counters::continuing_after(batch.counter_before);
            for _ in 0..taken {
                counters.next_tx();
            }
            self.rewind_counter(counters.last_tx());
        }
        (counted, full, failure.map_or(Ok(()), Err))
    }

    /// Between two batches of a run: the read sent ahead settled (it came back long
    /// since: it went out beside the batch before), and another sent for what the slave
    /// sent meanwhile, so the other direction's frames keep coming while the run goes on.
    pub async fn read_beside(&mut self, run: &WriteRun) -> Result<()> {
        self.chain_ready().await?;
        let read = self.submit_read(0);
        self.ahead = Some((read, Some(Want::Reply(run.mailbox_type))));
        Ok(())
    }

    /// Up to `count` messages composed as writes of SM0, one per step; stops before one
    /// that does not encode, and fails if the first does not.
    fn compose_writes(
        &mut self,
        mailbox_type: MailboxType,
        count: usize,
        mut emit: impl FnMut(usize, &mut [u8]) -> core::result::Result<usize, WireError>,
    ) -> Result<Vec<Vec<Chained>>> {
        let station = self.station();
        let start = self.shared.config.write.start;
        let mut steps = Vec::with_capacity(count);
        for i in 0..count {
            if let Err(err) = self.compose(mailbox_type, |buf| emit(i, buf)) {
                if steps.is_empty() {
                    return Err(err);
                }
                break;
            }
            let write = DatagramRequest::fpwr(station, start, DatagramData::from_slice(&self.tx));
            steps.push(vec![Chained::new(write)]);
        }
        Ok(steps)
    }

    /// Reads SM1 up to `count` times in a row while it holds messages, with nobody waiting
    /// for an answer, and routes what came. Returns how many messages came.
    pub(super) async fn drain(&mut self, count: usize) -> Result<usize> {
        self.recover().await?;
        let read = self.read_request();
        let steps = (0..count)
            .map(|_| vec![Chained::once(read.clone())])
            .collect();
        let mut reads: Vec<_> = self.bus.submit_chain(steps).into_iter().flatten().collect();
        // As for writes: the last read completes when the chain ends.
        let Some(last) = reads.pop() else {
            return Ok(0);
        };
        let last = last.await;
        let mut came = 0;
        for result in futures_util::future::join_all(reads)
            .await
            .into_iter()
            .chain([last])
        {
            // After a read that brought nothing (or was lost) the rest were not sent.
            if matches!(result, Err(BusError::Skipped)) {
                break;
            }
            match self.finish_read(result, None).await? {
                Read::Nothing => break,
                Read::Answer | Read::Routed => came += 1,
            }
        }
        Ok(came)
    }

    /// What [`Self::send`] does before its write: the read sent ahead settled, the mailbox
    /// still ours, a repeat owed carried out.
    async fn chain_ready(&mut self) -> Result<()> {
        if self.settle().await? == Read::Answer {
            self.keep_answer();
        }
        self.check_owned()?;
        self.recover().await
    }

    /// Counts one write of a chain: the ones that went in (a prefix), SM0 found full, or the
    /// first failure.
    fn count_write(
        &self,
        result: &DatagramResult,
        counted: &mut usize,
        full: &mut bool,
        failure: &mut Option<MailboxError>,
    ) {
        match result {
            Ok(response) if response.wkc == 1 => {
                inc(&self.shared.stats.writes);
                *counted += 1;
            }
            Ok(_) => {
                inc(&self.shared.stats.write_full);
                *full = true;
            }
            Err(BusError::Skipped) => {}
            Err(err) => {
                failure.get_or_insert_with(|| err.clone().into());
            }
        }
    }
}
