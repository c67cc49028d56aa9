//! Streams of messages through the mailbox in chains the bus thread runs itself
//! ([`BusHandle::submit_chain`](crate::bus::BusHandle::submit_chain); spec-notes
//! §mbx.chain): several writes into SM0, each as soon as the slave took the one before, and
//! several reads of SM1, each as soon as the one before found a message. A stream of EoE
//! fragments then moves at the frame round trip's pace instead of that pace plus two thread
//! hand-offs per fragment.
//!
//! Reads of SM1 in a chain follow each other (the next is sent only once the one before
//! came back with a message), so at most one is in flight: a lost one ends the chain and is
//! recovered before SM1 is read again (spec-notes §mbx.repeat).
//!
//! Only the slave's owner task runs chains (EoE and its idle reads), never a request a
//! caller may drop: a chain runs to its end on the bus thread whoever still waits for it,
//! and the owner goes away only when the slave's mailbox is let go.

use crate::bus::{BusError, Chained, DatagramData, DatagramRequest, DatagramResult};
use crate::mailbox::error::{MailboxError, Result};
use crate::wire::WireError;
use crate::wire::mailbox::MailboxType;

use super::super::demux::Want;
use super::super::stats::inc;
use super::{Exchange, Read};

impl Exchange {
    /// Writes `count` messages of `mailbox_type` into SM0 one after the other, message `i`
    /// made by `emit(i, buf)` as for [`Self::send`], with one read of SM1 sent beside
    /// them (settled as the read behind a [`Self::send`]). Returns how many went in, in order: fewer than `count` when SM0
    /// was still full for one (the slave had not yet taken the one before), and the rest is
    /// then the caller's to send again (with [`Self::send`], which waits for room). An
    /// error is a write whose fate is unknown (no reply after the bus's retries), after the
    /// ones counted. For messages that expect no answer (EoE fragments).
    pub async fn send_chain(
        &mut self,
        mailbox_type: MailboxType,
        count: usize,
        mut emit: impl FnMut(usize, &mut [u8]) -> core::result::Result<usize, WireError>,
    ) -> (usize, Result<()>) {
        if count == 0 {
            return (0, Ok(()));
        }
        if let Err(err) = self.chain_ready().await {
            return (0, Err(err));
        }
        let station = self.station();
        let start = self.shared.config.write.start;
        let mut steps = Vec::with_capacity(count);
        for i in 0..count {
            if let Err(err) = self.compose(mailbox_type, |buf| emit(i, buf)) {
                if steps.is_empty() {
                    return (0, Err(err));
                }
                // Sent up to the message that does not encode; the caller meets it again.
                break;
            }
            let write = DatagramRequest::fpwr(station, start, DatagramData::from_slice(&self.tx));
            steps.push(vec![Chained::new(write)]);
        }
        // The read goes with the first write, in its frame when there is room: what the
        // slave sends meanwhile (the other direction's frames) is read without a turn or a
        // frame of its own.
        let (writes, read) = self
            .bus
            .submit_chain_then_poll(steps, self.read_request(), 0);
        let mut writes: Vec<_> = writes.into_iter().flatten().collect();
        self.ahead = Some((read, Some(Want::Reply(mailbox_type))));
        let Some(last) = writes.pop() else {
            return (0, Ok(()));
        };
        // The steps complete in order and a stopped chain completes the rest at once, so the
        // last write is the one to wait for: the others are done by then.
        let last = last.await;
        let mut counted = 0;
        let mut failure = None;
        for write in writes {
            let result = write.await;
            self.count_write(&result, &mut counted, &mut failure);
        }
        self.count_write(&last, &mut counted, &mut failure);
        (counted, failure.map_or(Ok(()), Err))
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
        failure: &mut Option<MailboxError>,
    ) {
        match result {
            Ok(response) if response.wkc == 1 => {
                inc(&self.shared.stats.writes);
                *counted += 1;
            }
            Ok(_) => inc(&self.shared.stats.write_full),
            Err(BusError::Skipped) => {}
            Err(err) => {
                failure.get_or_insert_with(|| err.clone().into());
            }
        }
    }
}
