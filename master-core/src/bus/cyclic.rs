//! The cyclic slot: process data exchanged by the bus thread itself at a fixed period.
//!
//! A [`CyclicTask`] runs on the bus thread. When a cycle is due, the bus asks it to fill a
//! frame ([`CyclicTask::build`]), sends that frame before any waiting acyclic traffic, and
//! hands the returned frame back ([`CyclicTask::complete`]) or reports it lost
//! ([`CyclicTask::lost`]). Acyclic frames travel in the gaps between cycles.
//!
//! Cyclic frames are never retried: by the time a retry could go out, the next cycle
//! carries newer outputs. A cycle that would start while the previous cyclic frame is
//! still out waits for it (or for its deadline: the period or the response timeout,
//! whichever is shorter). A cycle that starts a whole period late counts as late, and the
//! missed periods are skipped rather than made up in a burst.
//!
//! The callbacks run on the thread that owns the link, between frames: they must be quick
//! and must not block (no locks that callers hold for long, no waiting on the bus itself,
//! which would deadlock). A panic in a task stops the bus (every caller then gets
//! [`BusError::Shutdown`]).

use std::time::Duration;

use crate::wire::command::{Command, DatagramAddress};
use crate::wire::datagram::{self, DatagramRepr};
use crate::wire::error::WireError;
use crate::wire::frame::{EthercatFrame, FrameBuilder};

use super::error::BusError;
use super::index::IndexTable;
use super::record::SentDatagram;

/// The default cycle period: 1 ms.
pub const DEFAULT_PERIOD: Duration = Duration::from_millis(1);

/// The shortest period the bus accepts; shorter ones are raised to it.
pub const MIN_PERIOD: Duration = Duration::from_micros(10);

/// Work the bus thread does once per period: typically the process-data exchange (LRW) and
/// the distributed-clock reference time (FRMW).
pub trait CyclicTask: Send {
    /// The cycle period, read once when the task is installed. Default: 1 ms.
    fn period(&self) -> Duration {
        DEFAULT_PERIOD
    }

    /// Fills the frame of one cycle. Datagrams pushed here travel together in one frame,
    /// in the order pushed; pushing none skips the cycle's frame.
    fn build(&mut self, frame: &mut CyclicFrame<'_>);

    /// The frame of the last cycle came back: its datagrams in the order they were
    /// pushed.
    fn complete(&mut self, reply: &CyclicReply<'_>);

    /// The frame of the last cycle did not come back in time.
    fn lost(&mut self) {}
}

/// The frame of one cycle, being filled by [`CyclicTask::build`].
#[derive(Debug)]
pub struct CyclicFrame<'a> {
    pub(crate) builder: FrameBuilder<'a>,
    pub(crate) indices: &'a mut IndexTable,
    pub(crate) record: u16,
    pub(crate) sent: &'a mut Vec<SentDatagram>,
}

impl CyclicFrame<'_> {
    /// Appends a datagram sending `data`; returns its position in the frame (0 for the
    /// first), the same position [`CyclicReply::datagram`] takes.
    ///
    /// Errors: the address's mode is not the command's ([`BusError::InvalidRequest`]), no
    /// room left in the frame ([`BusError::TooLarge`]), all datagram indices in flight
    /// ([`BusError::IndicesExhausted`]). Nothing is added on error.
    pub fn push(
        &mut self,
        command: Command,
        address: DatagramAddress,
        data: &[u8],
    ) -> Result<usize, BusError> {
        let raw = address.encode(command).map_err(|_| {
            BusError::InvalidRequest("the address's addressing mode is not the command's")
        })?;
        let len = u16::try_from(data.len()).map_err(|_| self.too_large(data.len()))?;
        if data.len() > self.builder.remaining_data() {
            return Err(self.too_large(data.len()));
        }
        let index = self
            .indices
            .take(self.record)
            .ok_or(BusError::IndicesExhausted)?;
        match self
            .builder
            .push(&DatagramRepr::request(command, index, address, data))
        {
            Ok(offset) => {
                self.sent.push(SentDatagram {
                    index,
                    command,
                    address: raw,
                    len,
                    offset,
                });
                Ok(self.sent.len() - 1)
            }
            Err(err) => {
                self.indices.release(index);
                Err(match err {
                    WireError::BufferTooSmall { .. } | WireError::BadLength { .. } => {
                        self.too_large(data.len())
                    }
                    _ => BusError::InvalidRequest("the datagram could not be encoded"),
                })
            }
        }
    }

    /// Appends a datagram of `len` zero bytes (a read); returns its position.
    pub fn push_zeroed(
        &mut self,
        command: Command,
        address: DatagramAddress,
        len: usize,
    ) -> Result<usize, BusError> {
        const ZEROS: [u8; datagram::MAX_DATA_LEN] = [0; datagram::MAX_DATA_LEN];
        let data = ZEROS.get(..len).ok_or_else(|| self.too_large(len))?;
        self.push(command, address, data)
    }

    /// The data of the datagram at `position`, to fill in place (outputs written straight
    /// into the frame, without a copy of their own).
    pub fn data_mut(&mut self, position: usize) -> Option<&mut [u8]> {
        let sent = *self.sent.get(position)?;
        let view = self.builder.datagram_mut(sent.offset).ok()?;
        let data = view.into_inner();
        data.get_mut(datagram::HEADER_LEN..datagram::HEADER_LEN + usize::from(sent.len))
    }

    /// Datagrams pushed so far.
    pub fn len(&self) -> usize {
        self.sent.len()
    }

    /// True if no datagram was pushed yet.
    pub fn is_empty(&self) -> bool {
        self.sent.is_empty()
    }

    /// The longest data one more datagram could carry.
    pub fn remaining_data(&self) -> usize {
        self.builder.remaining_data()
    }

    fn too_large(&self, need: usize) -> BusError {
        BusError::TooLarge {
            what: "cyclic datagram",
            need,
            room: self.builder.remaining_data(),
        }
    }
}

/// A cyclic frame that came back, as handed to [`CyclicTask::complete`].
#[derive(Debug)]
pub struct CyclicReply<'a> {
    pub(crate) frame: &'a EthercatFrame<'a>,
    pub(crate) count: usize,
    pub(crate) round_trip: Duration,
}

impl<'a> CyclicReply<'a> {
    /// Number of datagrams (as many as were pushed).
    pub fn len(&self) -> usize {
        self.count
    }

    /// True if the frame carried no datagram (never the case for a reply the bus hands out).
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The returned datagram at `position` (as returned by [`CyclicFrame::push`]): data,
    /// working counter, IRQ.
    pub fn datagram(&self, position: usize) -> Option<DatagramRepr<'a>> {
        self.datagrams().nth(position)
    }

    /// The returned datagrams in order.
    pub fn datagrams(&self) -> impl Iterator<Item = DatagramRepr<'a>> + 'a {
        // The bus checked the whole chain before handing the reply out.
        self.frame.datagrams().into_iter().flatten().flatten()
    }

    /// The whole returned frame.
    pub fn frame(&self) -> &EthercatFrame<'a> {
        self.frame
    }

    /// Time from sending the frame to receiving it.
    pub fn round_trip(&self) -> Duration {
        self.round_trip
    }
}
