//! The frame builder: packs datagrams into one Ethernet frame in a caller-provided buffer.

use crate::command::{Command, DatagramAddress};
use crate::datagram::{Datagram, DatagramRepr, MAX_DATA_LEN, OVERHEAD};
use crate::error::{Result, WireError, room};
use crate::ethernet::{
    self, BROADCAST, ETHERTYPE_ETHERCAT, EthernetFrame, EthernetRepr, MAX_FRAME_LEN, MIN_FRAME_LEN,
};
use crate::frame::{self, Frame, FrameHeader, FrameType};

/// Zeros for [`FrameBuilder::push_zeroed`], so read requests need no buffer of their own.
static ZEROS: [u8; MAX_DATA_LEN] = [0; MAX_DATA_LEN];

/// Offset of the first datagram in an untagged Ethernet frame.
const FIRST_DATAGRAM: usize = ethernet::HEADER_LEN + frame::HEADER_LEN;

/// Packs datagrams into one Ethernet frame in a caller-provided buffer, without allocation.
///
/// [`push`](Self::push) appends a datagram and returns its offset in the frame (so the
/// returned frame's datagram can be found again, see
/// [`EthercatFrame::datagram_at`](crate::frame::EthercatFrame::datagram_at)); it sets
/// M on the previous datagram, so M is always set on all but the last.
/// [`finish`](Self::finish) writes the Ethernet and EtherCAT headers and zero padding to the
/// Ethernet minimum and returns the frame length. The frame never exceeds the 1500-byte MTU
/// (1514 bytes without FCS), whatever the buffer size.
#[derive(Debug)]
pub struct FrameBuilder<'b> {
    buffer: &'b mut [u8],
    capacity: usize,
    end: usize,
    last: Option<usize>,
    count: usize,
}

impl<'b> FrameBuilder<'b> {
    /// Starts a frame in `buffer`, which must hold at least [`MIN_FRAME_LEN`] (60) bytes.
    pub fn new(buffer: &'b mut [u8]) -> Result<Self> {
        room("EtherCAT frame", buffer, MIN_FRAME_LEN)?;
        let capacity = buffer.len().min(MAX_FRAME_LEN);
        Ok(FrameBuilder {
            buffer,
            capacity,
            end: FIRST_DATAGRAM,
            last: None,
            count: 0,
        })
    }

    /// Appends a datagram (its `more` flag is ignored: the builder manages M) and returns the
    /// datagram's offset from the start of the Ethernet frame.
    ///
    /// Errors: data above [`MAX_DATA_LEN`] ([`WireError::BadLength`]); not enough room left in
    /// the buffer or the MTU ([`WireError::BufferTooSmall`]). Nothing is written on error.
    pub fn push(&mut self, datagram: &DatagramRepr<'_>) -> Result<usize> {
        if datagram.data.len() > MAX_DATA_LEN {
            return Err(WireError::BadLength {
                what: "datagram length",
                declared: datagram.data.len(),
                available: MAX_DATA_LEN,
            });
        }
        let start = self.end;
        let end = start + datagram.buffer_len();
        if end > self.capacity {
            return Err(WireError::BufferTooSmall {
                what: "EtherCAT frame",
                need: end,
                have: self.capacity,
            });
        }
        let target = self.buffer.get_mut(start..end).unwrap_or_default();
        DatagramRepr {
            more: false,
            ..*datagram
        }
        .emit(&mut Datagram::new_unchecked(target))?;
        if let Some(previous) = self.last {
            let previous = self.buffer.get_mut(previous..start).unwrap_or_default();
            Datagram::new_unchecked(previous).set_more(true);
        }
        self.last = Some(start);
        self.end = end;
        self.count += 1;
        Ok(start)
    }

    /// Appends a datagram whose `len` data bytes are zero (reads), returning its offset.
    pub fn push_zeroed(
        &mut self,
        command: Command,
        index: u8,
        address: DatagramAddress,
        len: usize,
    ) -> Result<usize> {
        let data = ZEROS.get(..len).ok_or(WireError::BadLength {
            what: "datagram length",
            declared: len,
            available: MAX_DATA_LEN,
        })?;
        self.push(&DatagramRepr::request(command, index, address, data))
    }

    /// A mutable view of the datagram pushed at `offset`, to fill its data in place.
    pub fn datagram_mut(&mut self, offset: usize) -> Result<Datagram<&mut [u8]>> {
        if offset < FIRST_DATAGRAM {
            return Err(WireError::Invalid {
                what: "datagram offset",
                reason: "offset before the first datagram",
            });
        }
        let end = self.end;
        Datagram::new_checked(self.buffer.get_mut(offset..end).unwrap_or_default())
    }

    /// Number of datagrams pushed.
    pub const fn datagram_count(&self) -> usize {
        self.count
    }

    /// True if no datagram was pushed yet.
    pub const fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Frame length so far (Ethernet and EtherCAT headers and datagrams, no padding).
    pub const fn len(&self) -> usize {
        self.end
    }

    /// The largest data length one more datagram could have.
    pub fn remaining_data(&self) -> usize {
        self.capacity
            .saturating_sub(self.end + OVERHEAD)
            .min(MAX_DATA_LEN)
    }

    /// Writes the Ethernet header (broadcast destination, `source`, EtherType 0x88A4), the
    /// EtherCAT header (type 1, length = sum of datagram sizes) and zero padding up to 60
    /// bytes; returns the frame length (without FCS). A frame without datagrams is refused.
    pub fn finish(self, source: [u8; 6]) -> Result<usize> {
        if self.count == 0 {
            return Err(WireError::Invalid {
                what: "EtherCAT frame",
                reason: "no datagrams",
            });
        }
        let length =
            u16::try_from(self.end - FIRST_DATAGRAM).map_err(|_| WireError::BadLength {
                what: "EtherCAT length",
                declared: self.end - FIRST_DATAGRAM,
                available: usize::from(frame::MAX_LENGTH),
            })?;
        let header = FrameHeader {
            length,
            frame_type: FrameType::Datagrams,
        };
        // Check everything that can fail before writing anything.
        header.to_raw()?;
        let total = self.end + ethernet::padding_len(self.end);
        let buffer = self.buffer;
        let ethernet = EthernetRepr {
            destination: BROADCAST,
            source,
            vlan_tci: None,
            ethertype: ETHERTYPE_ETHERCAT,
        };
        ethernet.emit(&mut EthernetFrame::new_unchecked(&mut *buffer))?;
        let ecat = buffer.get_mut(ethernet::HEADER_LEN..).unwrap_or_default();
        header.emit(&mut Frame::new_unchecked(ecat))?;
        if let Some(padding) = buffer.get_mut(self.end..total) {
            padding.fill(0);
        }
        Ok(total)
    }
}
