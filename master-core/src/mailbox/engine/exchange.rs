//! One slave's mailbox as the protocol code sees it: write a message into SM0, wait for the
//! answer in SM1. Everything else read from SM1 on the way is routed to where it belongs.
//!
//! An `Exchange` is only reached through a turn ([`super::turn`]), so there is exactly one
//! reader of the slave's send mailbox and one transaction at a time.
//!
//! Guards against a bus that may deliver a retried write twice and lose a read:
//! - every request carries the next counter 1..7, and a write the bus retried carries the
//!   same one, so the slave discards the second copy (ETG.1000.4, spec-notes §mbx.counter);
//! - SM1 is read with [`BusHandle::submit_once`]: a lost read is never blindly repeated
//!   (which could swallow the next message) but recovered with the repeat procedure, and a
//!   message re-posted by it that the master already has is recognised by the slave's
//!   counter and dropped (ETG.1000.4, spec-notes §mbx.repeat); a repeat that fails stays
//!   owing and is carried out before SM1 is read again (`Exchange::recover`).
//!
//! The first read of an answer is sent right behind the write (usually in the same frame),
//! so a slave that answers at once is read one round trip earlier; it is always settled —
//! routed like any other read — before the next write or read, so no message it brings is
//! lost.
//!
//! How often SM1 is read while an answer is awaited: a slave's application answers after
//! its own delay, which the master cannot know (the mailbox is a handshake: the slave
//! fills SM1 when it is ready; ETG.1000.4, spec-notes §mbx.handshake). So a few reads go
//! back to back ([`MailboxConfig::eager_polls`]: fast slaves are answered within a round
//! trip or two; the bus thread repeats an empty read itself, so no thread wakes between
//! them), then the pauses between reads grow from [`FIRST_PAUSE`] by half each time
//! up to [`MailboxConfig::poll_interval`] ([`next_pause`]), so that a slow slave costs a
//! few frames per exchange and is read at most about half its delay late. A slave that
//! keeps answering late is read when its answer is due instead: the first read after the
//! write's own waits for the least of its last answer times, each timed from the write's
//! frame to the frame of the read that found the answer ([`super::answer_time`]), and the
//! eager reads go from there. A "mailbox full"
//! notice (SM1 status 0x080D bit 3 mapped into the cyclic frame; ETG.1000.4, spec-notes
//! §esc.sm) ends a pause at once. The pauses run on the engine's own timer thread
//! ([`super::timer`]): tokio's timer would round each up to 1-2 ms.

use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::bus::{BusError, BusHandle, DatagramData, DatagramRequest, DatagramResult, Pending};
use crate::mailbox::config::MailboxConfig;
use crate::mailbox::error::{MailboxError, Result};
use crate::wire::WireError;
use crate::wire::mailbox::{
    ErrorReply, ErrorReplyRepr, HEADER_LEN, Mailbox, MailboxHeader, MailboxType,
};

use super::answer_time::AnswerTimes;
use super::counter::Counters;
use super::demux::{Route, Want, route};
use super::events::{EoeFrame, SoeNotification};
use super::hook::{Pushed, Reassembly};
use super::repeat::request_repeat;
use super::report;
use super::slave::SlaveShared;
use super::stats::inc;

mod chain;
pub(crate) use chain::WriteBatch;

/// Answers read while a request waited for room in SM0, kept for it.
const STASH_LEN: usize = 8;
/// Messages an idle read takes from SM1 in a row at most.
const IDLE_DRAIN: usize = 16;
/// The first pause between two reads of SM1 once the eager reads found nothing. Each
/// further pause is half as long again, up to [`MailboxConfig::poll_interval`].
pub(crate) const FIRST_PAUSE: Duration = Duration::from_micros(50);

/// The pause after `last` (zero before the first): [`FIRST_PAUSE`], then half as long
/// again each time, at most `longest`. A slave whose application answers after a delay
/// *d* is read at most about *d* / 2 late, after some log₁.₅(*d* / 50 µs) reads, instead of
/// a read per frame round trip (or a pause of a whole poll interval at once).
pub(crate) fn next_pause(last: Duration, longest: Duration) -> Duration {
    if last.is_zero() {
        FIRST_PAUSE.min(longest)
    } else {
        (last + last / 2).min(longest)
    }
}

/// What one read of SM1 brought.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Read {
    /// Nothing (empty, lost and recovered, or dropped).
    Nothing,
    /// A message, routed elsewhere.
    Routed,
    /// The waiting request's answer, now in `rx`.
    Answer,
}

/// An answer to a request: a message of the type asked for, or a mailbox error reply.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Reply<'a> {
    /// Station address of the slave that answered.
    pub station: u16,
    /// The header.
    pub header: MailboxHeader,
    /// The whole message (header and data).
    pub message: &'a [u8],
    /// The mailbox data.
    pub data: &'a [u8],
}

impl<'a> Reply<'a> {
    /// The mailbox data, or the mailbox error the slave answered with.
    pub fn data(&self) -> Result<&'a [u8]> {
        if self.header.mailbox_type != MailboxType::Error {
            return Ok(self.data);
        }
        match ErrorReply::new_checked(self.data).and_then(|r| ErrorReplyRepr::parse(&r)) {
            Ok(reply) => Err(MailboxError::Mailbox(reply.detail)),
            Err(_) => Err(MailboxError::Protocol {
                station: self.station,
                reason: "a mailbox error reply that cannot be parsed",
            }),
        }
    }
}

/// Access to one slave's mailbox, held by one turn at a time.
pub(crate) struct Exchange {
    shared: Arc<SlaveShared>,
    bus: BusHandle,
    counters: Counters,
    tx: Vec<u8>,
    rx: Vec<u8>,
    stash: VecDeque<Vec<u8>>,
    /// The receiver of EoE fragments (the side traffic's, spec-notes §mbx.demux).
    eoe_rx: Box<dyn Reassembly>,
    deadline: Instant,
    /// With progress deadlines: the window each exchange gets and the request's cap.
    progress: Option<(Duration, Instant)>,
    cancelled: Option<Arc<AtomicBool>>,
    /// A read of SM1 sent right behind the last write, with what it was sent for; it must
    /// be settled before anything else is read or written.
    ahead: Option<(Pending, Option<Want>)>,
    /// A read of SM1 was lost and the repeat procedure has not been carried out yet: it
    /// must be before SM1 is read again (see `Self::recover`).
    repeat_owed: bool,
    /// The last turn was dropped in the middle of its work (see [`super::turn`]).
    was_interrupted: bool,
    /// When the frame of the message now awaiting its answer left.
    written_at: Option<Instant>,
    /// When the frame of the last read that brought an answer left.
    found_sent: Option<Instant>,
    /// When the last read of SM1 first left (`None` while it is out, or if it was lost).
    read_left: Option<Instant>,
    /// How long this slave took to answer lately.
    answer_times: AnswerTimes,
}

impl Exchange {
    pub fn new(shared: Arc<SlaveShared>, bus: BusHandle, eoe_rx: Box<dyn Reassembly>) -> Exchange {
        let write = usize::from(shared.config.write.len);
        let read = usize::from(shared.config.read.len);
        let counters =
            Counters::continuing_after(shared.last_tx.load(std::sync::atomic::Ordering::Relaxed));
        Exchange {
            shared,
            bus,
            counters,
            tx: vec![0; write],
            rx: Vec::with_capacity(read),
            stash: VecDeque::with_capacity(STASH_LEN),
            eoe_rx,
            deadline: Instant::now(),
            progress: None,
            cancelled: None,
            ahead: None,
            repeat_owed: false,
            was_interrupted: false,
            written_at: None,
            found_sent: None,
            read_left: None,
            answer_times: AnswerTimes::default(),
        }
    }

    /// The next request counter, also left where a replacing owner finds it.
    fn next_counter(&mut self) -> u8 {
        let counter = self.counters.next_tx();
        self.shared
            .last_tx
            .store(counter, std::sync::atomic::Ordering::Relaxed);
        counter
    }

    /// Takes back the counters given to messages composed after `last` and never written
    /// ([`Counters::rewind_to`]).
    fn rewind_counter(&mut self, last: u8) {
        self.counters.rewind_to(last);
        self.shared.last_tx.store(
            self.counters.last_tx(),
            std::sync::atomic::Ordering::Relaxed,
        );
    }

    /// The slave's station address.
    pub fn station(&self) -> u16 {
        self.shared.config.station
    }

    /// The engine's settings.
    pub fn config(&self) -> &MailboxConfig {
        &self.shared.engine
    }

    /// Requests waiting for their turn at this mailbox.
    pub fn queued_requests(&self) -> usize {
        self.shared
            .waiting
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// SM0 length: what a message to the slave may occupy, header included.
    pub fn write_size(&self) -> usize {
        self.tx.len()
    }

    /// SM1 length: what a message from the slave may occupy, header included.
    pub fn read_size(&self) -> usize {
        usize::from(self.shared.config.read.len)
    }

    /// Starts a transaction that must end by `deadline`, or with `progress` (window, cap)
    /// within a window of its last progress and by the cap; `cancelled` is the caller's flag.
    pub fn begin(
        &mut self,
        deadline: Instant,
        progress: Option<(Duration, Instant)>,
        cancelled: Option<Arc<AtomicBool>>,
    ) {
        self.deadline = deadline;
        self.progress = progress;
        self.cancelled = cancelled;
    }

    /// The transfer moved on (an answer that advances it): with progress deadlines the
    /// next exchange gets a whole window again, never beyond the request's cap. Without
    /// them the request's single deadline stays.
    pub fn progressed(&mut self) {
        if let Some((window, cap)) = self.progress {
            self.deadline = (Instant::now() + window).min(cap);
        }
    }

    /// Ends the transaction: the read sent ahead is settled (a bus error there is seen
    /// again by the next read); answers nobody took are counted as unexpected.
    pub async fn end(&mut self) {
        if let Ok(Read::Answer) = self.settle().await {
            let message = std::mem::take(&mut self.rx);
            self.drop_unclaimed(&message);
            self.rx = message;
        }
        self.cancelled = None;
        self.progress = None;
        while let Some(message) = self.stash.pop_front() {
            self.drop_unclaimed(&message);
        }
    }

    /// Counts and logs a whole message read for a request that did not take it.
    fn drop_unclaimed(&self, message: &[u8]) {
        inc(&self.shared.stats.unexpected);
        let mailbox_type = Mailbox::new_checked(message)
            .and_then(|m| MailboxHeader::parse(&m))
            .map_or(MailboxType::Error, |h| h.mailbox_type);
        let shared = &*self.shared;
        let why = "the request it came during did not take it";
        report::unexpected(&shared.log_limit, shared.config.station, mailbox_type, why);
    }

    /// The turn holding the exchange was dropped in the middle of its work: whatever it
    /// had under way is unknown (a read of SM1 may have emptied it without the message
    /// arriving here).
    pub fn interrupted(&mut self) {
        self.was_interrupted = true;
    }

    /// Starts a turn after an interrupted one: the read sent ahead is forgotten, answers
    /// kept for it are dropped (counted as unexpected), and, since a read of SM1 may have
    /// been lost on the way, the repeat procedure is owed before SM1 is read again, as
    /// after a lost read (ETG.1000.4, spec-notes §mbx.repeat).
    pub async fn recover_interrupted(&mut self) {
        if !std::mem::take(&mut self.was_interrupted) {
            return;
        }
        self.ahead = None;
        self.repeat_owed = true;
        self.end().await;
    }

    /// Waits `pause` on the engine's timer (it works from any executor, to the
    /// microsecond).
    pub async fn sleep(&self, pause: Duration) {
        self.shared.timer.sleep(pause).await;
    }

    /// Whether the caller went away.
    pub fn cancelled(&self) -> bool {
        self.cancelled
            .as_ref()
            .is_some_and(|flag| flag.load(Ordering::Relaxed))
    }

    /// Whether the transaction's deadline has passed.
    pub fn expired(&self) -> bool {
        Instant::now() >= self.deadline
    }

    /// Fails once the slave's mailbox was let go (the slave was lost, power-cycled or
    /// scanned again): a new owner may have it by now, and a read of SM1 from here would
    /// take that owner's answers (one owner per mailbox; spec-notes §mbx.handshake).
    fn check_owned(&self) -> Result<()> {
        if self.shared.stopped() {
            return Err(MailboxError::Shutdown);
        }
        Ok(())
    }

    /// A timeout error for this slave.
    pub fn timeout(&self, waiting_for: &'static str) -> MailboxError {
        MailboxError::Timeout {
            station: self.station(),
            waiting_for,
        }
    }

    /// A protocol violation by this slave.
    pub fn violation(&self, reason: &'static str) -> MailboxError {
        MailboxError::Protocol {
            station: self.station(),
            reason,
        }
    }

    /// The slave's counters.
    pub(crate) fn stats(&self) -> &super::stats::Stats {
        &self.shared.stats
    }

    /// An answer of the right type that belongs to no request (a late answer to one that
    /// timed out): dropped and counted.
    pub(crate) fn count_unexpected(&self, protocol: MailboxType) {
        inc(&self.shared.stats.unexpected);
        let shared = &*self.shared;
        report::unexpected(
            &shared.log_limit,
            shared.config.station,
            protocol,
            "it does not answer the request",
        );
    }

    /// Leaves the log line of a failed request.
    pub(crate) fn report_failure(
        &self,
        protocol: Option<MailboxType>,
        subject: &report::Subject,
        err: &MailboxError,
    ) {
        let shared = &*self.shared;
        report::failure(
            &shared.log_limit,
            shared.config.station,
            protocol,
            subject,
            err,
        );
    }

    pub(crate) fn count_failed(&self) {
        inc(&self.shared.stats.failed);
    }

    pub(crate) fn count_cancelled(&self) {
        inc(&self.shared.stats.cancelled);
    }

    /// The bytes of mailbox data one message to the slave can carry (SM0 length − 6).
    pub(crate) fn data_capacity(&self) -> usize {
        self.tx.len().saturating_sub(HEADER_LEN)
    }

    /// Writes one message of `mailbox_type` into SM0. `emit` writes the mailbox data into
    /// the buffer it is given (SM0 length − 6 bytes) and returns its length; the header
    /// (length, counter, type) is added here. A full SM0 is written again until the
    /// deadline, reading SM1 in between (a slave may hold SM0 until its answers are read).
    pub async fn send(
        &mut self,
        mailbox_type: MailboxType,
        emit: impl FnOnce(&mut [u8]) -> core::result::Result<usize, WireError>,
    ) -> Result<()> {
        self.compose(mailbox_type, emit)?;
        let station = self.station();
        let start = self.shared.config.write.start;
        let want = Some(Want::Reply(mailbox_type));
        if self.settle().await? == Read::Answer {
            self.keep_answer();
        }
        loop {
            self.check_owned()?;
            self.recover().await?;
            // The first read of the answer goes right behind the write, in the same frame
            // when it has room: a slave that answers at once (as the simulator does) is read
            // one round trip earlier, and one that does not just returns an empty read.
            let (write, read) = self.bus.submit_then_poll(
                DatagramRequest::fpwr(station, start, DatagramData::from_slice(&self.tx)),
                self.read_request(),
                0,
            );
            let written = write.await;
            if let Ok(response) = &written
                && response.wkc == 1
            {
                inc(&self.shared.stats.writes);
                self.ahead = Some((read, want));
                self.written_at = Some(response.sent_at.instant());
                return Ok(());
            }
            // Never drop a read that may have emptied SM1: route what it brought first.
            if self.finish_read(read.await, want).await? == Read::Answer {
                self.keep_answer();
            }
            written?;
            inc(&self.shared.stats.write_full);
            if self.expired() {
                return Err(self.timeout("room in the receive mailbox"));
            }
            self.sleep(self.shared.engine.full_retry_interval).await;
        }
    }

    /// Puts one message of `mailbox_type` in `tx`, under the next counter: the header, and
    /// the data `emit` writes.
    fn compose(
        &mut self,
        mailbox_type: MailboxType,
        emit: impl FnOnce(&mut [u8]) -> core::result::Result<usize, WireError>,
    ) -> Result<()> {
        if self.tx.len() <= HEADER_LEN {
            return Err(self.violation("the receive mailbox is too small"));
        }
        self.tx.fill(0);
        // Taken even if the body does not encode: a skipped counter is harmless, the slave
        // only discards a repeat of the last one.
        let counter = self.next_counter();
        let (head, body) = self.tx.split_at_mut(HEADER_LEN);
        let length = emit(body).map_err(MailboxError::Invalid)?;
        let header = MailboxHeader {
            // At most the SM0 length − 6: `emit` wrote no more than `body` holds.
            length: u16::try_from(length).unwrap_or(u16::MAX),
            address: 0,
            channel: 0,
            priority: 0,
            mailbox_type,
            counter,
        };
        header
            .emit(&mut Mailbox::new_unchecked(head))
            .map_err(MailboxError::Invalid)
    }

    /// Keeps the answer just read (in `rx`) for the next [`Self::receive`].
    fn keep_answer(&mut self) {
        if self.stash.len() >= STASH_LEN {
            inc(&self.shared.stats.unexpected);
        } else {
            self.stash.push_back(self.rx.clone());
        }
    }

    /// Finishes the read sent ahead, if any.
    async fn settle(&mut self) -> Result<Read> {
        match self.ahead.take() {
            Some((read, want)) => self.finish_read(read.await, want).await,
            None => Ok(Read::Nothing),
        }
    }

    /// Waits for the answer of `mailbox_type` (or a mailbox error reply) to the message
    /// just sent, routing everything else read meanwhile.
    pub async fn receive(&mut self, mailbox_type: MailboxType) -> Result<Reply<'_>> {
        let want = Want::Reply(mailbox_type);
        let mut reads = 0u32;
        let mut pause = Duration::ZERO;
        // Only the first answer after a write is timed, and only it may be planned for.
        let written_at = self.written_at.take();
        self.found_sent = None;
        let mut planned = written_at
            .zip(self.answer_times.planned())
            .map(|(at, after)| at + after);
        // A notice kept from before this message was written is about an older one.
        std::pin::pin!(self.shared.answer.notified()).enable();
        loop {
            // Checked first as well: a slave answering with a stream of messages the
            // caller skips must not keep the request beyond its deadline.
            if self.expired() && self.stash.is_empty() {
                return Err(self.timeout(want.describe()));
            }
            if let Some(message) = self.stash.pop_front() {
                self.rx = message;
                break;
            }
            self.check_owned()?;
            if self.settle().await? == Read::Answer {
                break;
            }
            // A slave that has taken long to answer lately is read when its answer is due
            // (the eager reads then go from there), not from the write on.
            let mut paused_for = None;
            if let Some(at) = planned.take() {
                let now = Instant::now();
                if at > now {
                    self.pause(at - now).await;
                    paused_for = Some(at);
                }
            }
            // The eager reads go as one poll the bus thread repeats while SM1 is empty, so
            // they follow each other at the wire's pace, without waking this task between
            // them; the later ones go one by one, after the pauses.
            let eager = self.shared.engine.eager_polls;
            let again = if reads == 0 {
                u16::try_from(eager.saturating_sub(1)).unwrap_or(u16::MAX)
            } else {
                0
            };
            let read = self.read_one(Some(want), again).await?;
            // How late the planned read left: the pause's timer, this task and the bus
            // thread woken, all of which the next plan asks for earlier.
            if let (Some(at), Some(left)) = (paused_for, self.read_left) {
                self.answer_times
                    .left_late(left.saturating_duration_since(at));
            }
            if read == Read::Answer {
                break;
            }
            if self.expired() {
                return Err(self.timeout(want.describe()));
            }
            reads += 1 + u32::from(again);
            if reads >= eager {
                pause = next_pause(pause, self.shared.engine.poll_interval);
                self.pause(pause).await;
            }
        }
        if let (Some(written), Some(found)) = (written_at, self.found_sent) {
            self.answer_times
                .record(found.saturating_duration_since(written));
        }
        let header = Mailbox::new_checked(&self.rx[..])
            .and_then(|m| MailboxHeader::parse(&m))
            .map_err(|_| self.violation("an answer without a valid header"))?;
        let end = HEADER_LEN + usize::from(header.length);
        Ok(Reply {
            station: self.shared.config.station,
            header,
            message: &self.rx[..end],
            data: &self.rx[HEADER_LEN..end],
        })
    }

    /// Waits `pause` (or for a "mailbox full" notification), not beyond the deadline.
    async fn pause(&self, pause: Duration) {
        let wait = pause.min(self.deadline.saturating_duration_since(Instant::now()));
        tokio::select! {
            () = self.sleep(wait) => {}
            () = self.shared.answer.notified() => {}
        }
    }

    /// Reads SM1 while it holds messages, with nobody waiting for an answer. Returns
    /// whether anything was there: a slave that just sent something (an EoE frame, say)
    /// often has more on the way, so the owner reads again at once instead of at the next
    /// poll. The reads go as one chain the bus thread runs (`drain`).
    pub async fn poll_idle(&mut self) -> Result<bool> {
        self.deadline = Instant::now() + self.shared.engine.timeout;
        if self.eoe_rx.expire(Instant::now(), None) {
            inc(&self.shared.stats.eoe_reassembly_errors);
        }
        let mut found = false;
        match self.settle().await? {
            Read::Answer => {
                let message = std::mem::take(&mut self.rx);
                self.drop_unclaimed(&message);
                self.rx = message;
                found = true;
            }
            Read::Routed => found = true,
            Read::Nothing => {}
        }
        Ok(self.drain(IDLE_DRAIN).await? > 0 || found)
    }

    /// Sends one read of the whole SM1, never to be resent by the bus after a lost frame;
    /// while it finds SM1 empty the bus reads again, `again` more times at most.
    fn submit_read(&self, again: u16) -> Pending {
        self.bus.submit_once_polling(self.read_request(), again)
    }

    /// A read of the whole SM1.
    fn read_request(&self) -> DatagramRequest {
        let area = self.shared.config.read;
        DatagramRequest::fprd(self.station(), area.start, usize::from(area.len))
    }

    /// Reads SM1 (up to `1 + again` times while it is empty) and routes what it held.
    async fn read_one(&mut self, want: Option<Want>, again: u16) -> Result<Read> {
        self.recover().await?;
        self.read_left = None;
        let read = self.submit_read(again);
        self.finish_read(read.await, want).await
    }

    /// Carries out the repeat procedure a lost read left owing, if any.
    ///
    /// The slave re-posts the message the lost read took only as long as the master has not
    /// read SM1 again: its copy is of the last message read (ETG.1000.4 §6.7, spec-notes
    /// §mbx.repeat), and the next read replaces it. So when the procedure fails (its register
    /// accesses got no answer within the bus's retries, as when the frames of a slow or
    /// briefly unreachable slave come back too late), SM1 is not read until it has been
    /// carried out: every read of SM1 comes here first, and the message arrives late instead
    /// of never.
    async fn recover(&mut self) -> Result<()> {
        if !self.repeat_owed {
            return Ok(());
        }
        let deadline = self
            .deadline
            .max(Instant::now() + self.shared.engine.timeout);
        let interval = self.shared.engine.poll_interval;
        request_repeat(
            &self.bus,
            self.station(),
            deadline,
            interval,
            &self.shared.timer,
        )
        .await?;
        self.repeat_owed = false;
        inc(&self.shared.stats.repeats);
        Ok(())
    }

    /// Routes what a read of SM1 brought; a lost read is recovered with a repeat request.
    async fn finish_read(&mut self, result: DatagramResult, want: Option<Want>) -> Result<Read> {
        let station = self.station();
        let response = match result {
            Ok(response) => response,
            Err(BusError::Timeout { .. }) => {
                inc(&self.shared.stats.lost_reads);
                self.repeat_owed = true;
                self.recover().await?;
                return Ok(Read::Nothing);
            }
            Err(err) => return Err(err.into()),
        };
        self.read_left = Some(response.first_sent_at());
        if response.wkc != 1 {
            return Ok(Read::Nothing);
        }
        inc(&self.shared.stats.reads);
        let bytes = response.data.as_slice();
        let Ok(header) = Mailbox::new_checked(bytes).and_then(|m| MailboxHeader::parse(&m)) else {
            inc(&self.shared.stats.malformed);
            return Ok(Read::Routed);
        };
        if !self.counters.accept_rx(header.counter) {
            inc(&self.shared.stats.duplicates);
            return Ok(Read::Routed);
        }
        let end = HEADER_LEN + usize::from(header.length);
        // `new_checked` guaranteed that the declared length fits the buffer.
        let data = bytes.get(HEADER_LEN..end).unwrap_or_default();
        let shared = &*self.shared;
        match route(header.mailbox_type, data, want) {
            Route::Request => {
                self.found_sent = Some(response.sent_at.instant());
                self.rx.clear();
                self.rx
                    .extend_from_slice(bytes.get(..end).unwrap_or_default());
                return Ok(Read::Answer);
            }
            Route::Emergency(repr) => shared.events.emergency(station, &repr, &shared.stats),
            Route::EoeFrame => {
                let now = Instant::now();
                if self.eoe_rx.expire(now, Some(data)) {
                    inc(&shared.stats.eoe_reassembly_errors);
                }
                match self.eoe_rx.push(data, now) {
                    Pushed::Frame(frame) => {
                        shared
                            .events
                            .eoe_frame(EoeFrame { station, frame }, &shared.stats);
                    }
                    Pushed::Dropped => inc(&shared.stats.eoe_reassembly_errors),
                    Pushed::Partial | Pushed::Orphan | Pushed::Ignored => {}
                }
            }
            Route::SoeNotification => shared.events.soe_notification(
                SoeNotification {
                    station,
                    message: data.to_vec(),
                },
                &shared.stats,
            ),
            Route::Unexpected => {
                inc(&shared.stats.unexpected);
                let why = "nobody waits for it";
                report::unexpected(&shared.log_limit, station, header.mailbox_type, why);
            }
            Route::Malformed => inc(&shared.stats.malformed),
        }
        Ok(Read::Routed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pauses_start_at_50_us_and_grow_by_half_up_to_the_poll_interval() {
        let longest = Duration::from_millis(1);
        let mut pause = Duration::ZERO;
        let mut seen = Vec::new();
        for _ in 0..9 {
            pause = next_pause(pause, longest);
            seen.push(pause.as_micros());
        }
        assert_eq!(seen, [50, 75, 112, 168, 253, 379, 569, 854, 1000]);
        // A poll interval shorter than the first pause is kept to.
        let short = Duration::from_micros(20);
        assert_eq!(next_pause(Duration::ZERO, short), short);
    }
}
