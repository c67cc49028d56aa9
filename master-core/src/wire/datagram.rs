//! Datagrams (EtherCAT PDUs), the datagram chain of a frame, and the frame builder
//! (ETG.1000.4 EtherCAT DLPDU, spec-notes §datagram, §frame).
//!
//! ```text
//! offset 0       u8      command (see `command::Command`)
//! offset 1       u8      index (chosen by the master, echoed unchanged)
//! offset 2       u32 LE  address: ADP u16 at 2 + ADO u16 at 4, or one logical u32
//! offset 6       u16 LE  bits 0-10 data length, bits 11-13 reserved,
//!                        bit 14 C (circulating), bit 15 M (more datagrams follow)
//! offset 8       u16 LE  IRQ
//! offset 10      [len]   data
//! offset 10+len  u16 LE  working counter
//! ```
//!
//! A frame's payload is a chain of datagrams, each `len + 12` bytes, with M set on all but
//! the last; whatever follows the datagram with M = 0 is padding.

use core::fmt;

use crate::wire::command::{Command, DatagramAddress};
use crate::wire::error::{Result, WireError, need, room};
use crate::wire::ethernet::{
    self, BROADCAST, ETHERTYPE_ETHERCAT, EthernetFrame, EthernetRepr, MAX_FRAME_LEN, MIN_FRAME_LEN,
};
use crate::wire::field::{self, Field, Rest};
use crate::wire::frame::{self, Frame, FrameHeader, FrameType};

mod fields {
    use super::{Field, Rest};
    pub const COMMAND: usize = 0;
    pub const INDEX: usize = 1;
    pub const ADDRESS: Field = 2..6;
    pub const ADP: Field = 2..4;
    pub const ADO: Field = 4..6;
    pub const LEN_FLAGS: Field = 6..8;
    pub const IRQ: Field = 8..10;
    pub const DATA: Rest = 10..;

    pub const LENGTH_MASK: u16 = 0x07FF;
    pub const RESERVED_MASK: u16 = 0x3800;
    pub const CIRCULATING: u16 = 0x4000;
    pub const MORE: u16 = 0x8000;
}

/// Size of the datagram header (before the data).
pub const HEADER_LEN: usize = fields::DATA.start;
/// Size of the working counter after the data.
pub const WKC_LEN: usize = 2;
/// Bytes a datagram adds to its data: header + working counter.
pub const OVERHEAD: usize = HEADER_LEN + WKC_LEN;
/// Largest data length of one datagram: 1500 − 2 − 10 − 2 (ETG.1000.4, spec-notes §datagram, IgH
/// `EC_MAX_DATA_SIZE`). The 11-bit field could say 2047, but such frames exceed the MTU.
pub const MAX_DATA_LEN: usize = frame::MAX_PAYLOAD_LEN - OVERHEAD;

/// A read/write view of one datagram.
#[derive(Debug, Clone)]
pub struct Datagram<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Datagram<T> {
    /// Wraps a buffer without checking it; accessors may panic until [`Self::check_len`] passed.
    pub const fn new_unchecked(buffer: T) -> Self {
        Datagram { buffer }
    }

    /// Wraps a buffer and checks that header, declared data and working counter are present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let datagram = Self::new_unchecked(buffer);
        datagram.check_len()?;
        Ok(datagram)
    }

    /// Checks that the 10-byte header, `length` data bytes and the 2-byte WKC are present.
    ///
    /// Bytes after the WKC are allowed (following datagrams, padding).
    pub fn check_len(&self) -> Result<()> {
        let buf = self.buffer.as_ref();
        need("datagram header", buf, HEADER_LEN)?;
        let declared = usize::from(self.length());
        if buf.len() < OVERHEAD {
            return Err(WireError::Truncated {
                what: "datagram",
                need: OVERHEAD + declared,
                have: buf.len(),
            });
        }
        let available = buf.len() - OVERHEAD;
        if declared > available {
            return Err(WireError::BadLength {
                what: "datagram length",
                declared,
                available,
            });
        }
        Ok(())
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Command.
    pub fn command(&self) -> Command {
        Command::from(self.buffer.as_ref()[fields::COMMAND])
    }

    /// Index (the master's tag for matching the returned datagram).
    pub fn index(&self) -> u8 {
        self.buffer.as_ref()[fields::INDEX]
    }

    /// The raw address: bytes 2-5 as a LE u32 (`adp | ado << 16`, or the logical address).
    pub fn address(&self) -> u32 {
        field::u32_le(self.buffer.as_ref(), fields::ADDRESS.start)
    }

    /// ADP (bytes 2-3): negative position, station address, or broadcast counter.
    pub fn adp(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::ADP.start)
    }

    /// ADO (bytes 4-5): register / memory offset in the slave.
    pub fn ado(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::ADO.start)
    }

    /// The address read according to the command (`None` for NOP / unknown commands).
    pub fn typed_address(&self) -> Option<DatagramAddress> {
        DatagramAddress::decode(self.command(), self.address())
    }

    /// The raw length/flags word (bytes 6-7).
    pub fn len_flags(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::LEN_FLAGS.start)
    }

    /// Data length (bits 0-10).
    pub fn length(&self) -> u16 {
        self.len_flags() & fields::LENGTH_MASK
    }

    /// The reserved bits 11-13, shifted down (must be 0).
    pub fn reserved(&self) -> u8 {
        ((self.len_flags() & fields::RESERVED_MASK) >> 11) as u8
    }

    /// C: the frame has passed a closed port 0 once (circulating frame detection).
    pub fn circulating(&self) -> bool {
        self.len_flags() & fields::CIRCULATING != 0
    }

    /// M: another datagram follows in this frame.
    pub fn more(&self) -> bool {
        self.len_flags() & fields::MORE != 0
    }

    /// IRQ word: ECAT event requests ORed in by the slaves.
    pub fn irq(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::IRQ.start)
    }

    /// The data: exactly `length` bytes.
    pub fn data(&self) -> &[u8] {
        let end = HEADER_LEN + usize::from(self.length());
        &self.buffer.as_ref()[fields::DATA.start..end]
    }

    /// Working counter after the data.
    pub fn wkc(&self) -> u16 {
        field::u16_le(
            self.buffer.as_ref(),
            HEADER_LEN + usize::from(self.length()),
        )
    }

    /// Size of the whole datagram: `length + 12`.
    pub fn total_len(&self) -> usize {
        OVERHEAD + usize::from(self.length())
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Datagram<T> {
    /// Sets the command.
    pub fn set_command(&mut self, value: Command) {
        self.buffer.as_mut()[fields::COMMAND] = u8::from(value);
    }

    /// Sets the index.
    pub fn set_index(&mut self, value: u8) {
        self.buffer.as_mut()[fields::INDEX] = value;
    }

    /// Sets the raw 4-byte address.
    pub fn set_address(&mut self, value: u32) {
        field::set_u32_le(self.buffer.as_mut(), fields::ADDRESS.start, value)
    }

    /// Sets ADP (what every slave increments for position and broadcast commands).
    pub fn set_adp(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::ADP.start, value)
    }

    /// Sets ADO.
    pub fn set_ado(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::ADO.start, value)
    }

    /// Sets the raw length/flags word.
    pub fn set_len_flags(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::LEN_FLAGS.start, value)
    }

    /// Sets the data length (masked to 11 bits), keeping the flags.
    pub fn set_length(&mut self, value: u16) {
        let flags = self.len_flags() & !fields::LENGTH_MASK;
        self.set_len_flags(flags | (value & fields::LENGTH_MASK))
    }

    /// Sets or clears C.
    pub fn set_circulating(&mut self, value: bool) {
        self.set_flag(fields::CIRCULATING, value)
    }

    /// Sets or clears M.
    pub fn set_more(&mut self, value: bool) {
        self.set_flag(fields::MORE, value)
    }

    fn set_flag(&mut self, mask: u16, value: bool) {
        let raw = self.len_flags();
        self.set_len_flags(if value { raw | mask } else { raw & !mask })
    }

    /// Sets the IRQ word.
    pub fn set_irq(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::IRQ.start, value)
    }

    /// Mutable data (`length` bytes).
    pub fn data_mut(&mut self) -> &mut [u8] {
        let end = HEADER_LEN + usize::from(self.length());
        &mut self.buffer.as_mut()[fields::DATA.start..end]
    }

    /// Sets the working counter.
    pub fn set_wkc(&mut self, value: u16) {
        let at = HEADER_LEN + usize::from(self.length());
        field::set_u16_le(self.buffer.as_mut(), at, value)
    }
}

/// A parsed datagram; `data` borrows from the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct DatagramRepr<'a> {
    /// Command.
    pub command: Command,
    /// Index.
    pub index: u8,
    /// Raw address, bytes 2-5 as a LE u32; see [`DatagramRepr::typed_address`].
    pub address: u32,
    /// Data, at most [`MAX_DATA_LEN`] bytes.
    pub data: &'a [u8],
    /// C flag.
    pub circulating: bool,
    /// M flag (the frame builder sets it itself).
    pub more: bool,
    /// IRQ word.
    pub irq: u16,
    /// Working counter.
    pub wkc: u16,
}

impl<'a> DatagramRepr<'a> {
    /// A request as a master sends it: flags, IRQ and WKC zero.
    pub fn request(command: Command, index: u8, address: DatagramAddress, data: &'a [u8]) -> Self {
        DatagramRepr {
            command,
            index,
            address: address.to_raw(),
            data,
            circulating: false,
            more: false,
            irq: 0,
            wkc: 0,
        }
    }

    /// Parses a checked view.
    ///
    /// Errors: the view's length checks, reserved bits 11-13 set
    /// ([`WireError::ReservedBits`]), or a data length above [`MAX_DATA_LEN`].
    pub fn parse<T: AsRef<[u8]> + ?Sized>(datagram: &Datagram<&'a T>) -> Result<Self> {
        datagram.check_len()?;
        check_flags_and_limit(datagram, false)?;
        let declared = usize::from(datagram.length());
        // Borrow the data for 'a (from the buffer), not for the lifetime of `datagram`.
        let buf: &'a [u8] = T::as_ref(datagram.buffer);
        let data = buf
            .get(HEADER_LEN..HEADER_LEN + declared)
            .unwrap_or_default();
        Ok(DatagramRepr {
            command: datagram.command(),
            index: datagram.index(),
            address: datagram.address(),
            data,
            circulating: datagram.circulating(),
            more: datagram.more(),
            irq: datagram.irq(),
            wkc: datagram.wkc(),
        })
    }

    /// Size on the wire: `data.len() + 12`.
    pub const fn buffer_len(&self) -> usize {
        OVERHEAD + self.data.len()
    }

    /// The address read according to the command (`None` for NOP / unknown commands).
    pub fn typed_address(&self) -> Option<DatagramAddress> {
        DatagramAddress::decode(self.command, self.address)
    }

    /// Writes the datagram at the start of `datagram`'s buffer (the reserved bits as 0).
    ///
    /// Refuses data longer than [`MAX_DATA_LEN`] and a buffer shorter than `buffer_len()`.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, datagram: &mut Datagram<T>) -> Result<()> {
        if self.data.len() > MAX_DATA_LEN {
            return Err(WireError::BadLength {
                what: "datagram length",
                declared: self.data.len(),
                available: MAX_DATA_LEN,
            });
        }
        room("datagram", datagram.buffer.as_ref(), self.buffer_len())?;
        let mut len_flags = self.data.len() as u16;
        if self.circulating {
            len_flags |= fields::CIRCULATING;
        }
        if self.more {
            len_flags |= fields::MORE;
        }
        datagram.set_command(self.command);
        datagram.set_index(self.index);
        datagram.set_address(self.address);
        datagram.set_len_flags(len_flags);
        datagram.set_irq(self.irq);
        datagram.data_mut().copy_from_slice(self.data);
        datagram.set_wkc(self.wkc);
        Ok(())
    }
}

impl fmt::Display for DatagramRepr<'_> {
    /// Wireshark-like summary: `FPWR idx=4 adp=0x1001 ado=0x0502 len=6 wkc=0`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} idx={}", self.command, self.index)?;
        match self.typed_address() {
            Some(address) => write!(f, " {address}")?,
            None => write!(f, " addr={:#010x}", self.address)?,
        }
        write!(f, " len={} wkc={}", self.data.len(), self.wkc)?;
        if self.circulating {
            f.write_str(" circulating")?;
        }
        if self.irq != 0 {
            write!(f, " irq={:#06x}", self.irq)?;
        }
        Ok(())
    }
}

/// Iterator over the datagram chain of an EtherCAT payload (spec-notes §datagram "M bit").
///
/// Walks `len + 12` bytes per datagram and stops after the datagram with M = 0; bytes after
/// it are padding and ignored. A malformed datagram, or an M = 1 datagram with nothing
/// after it, yields one `Err` and ends the iteration.
#[derive(Debug, Clone)]
pub struct Datagrams<'a> {
    payload: &'a [u8],
    offset: usize,
    done: bool,
}

impl<'a> Datagrams<'a> {
    /// Iterates the datagrams of `payload` (the bytes after the EtherCAT header).
    pub const fn new(payload: &'a [u8]) -> Self {
        Datagrams {
            payload,
            offset: 0,
            done: false,
        }
    }

    /// Offset in the payload of the next datagram (after the end: the chain's length).
    pub const fn offset(&self) -> usize {
        self.offset
    }

    fn fail(&mut self, error: WireError) -> Option<Result<DatagramRepr<'a>>> {
        self.done = true;
        Some(Err(error))
    }
}

impl<'a> Iterator for Datagrams<'a> {
    type Item = Result<DatagramRepr<'a>>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let rest = self.payload.get(self.offset..).unwrap_or_default();
        if rest.is_empty() && self.offset > 0 {
            // Only reached after a datagram with M = 1.
            return self.fail(WireError::Truncated {
                what: "datagram chain (M bit set)",
                need: OVERHEAD,
                have: 0,
            });
        }
        let repr = match Datagram::new_checked(rest).and_then(|d| DatagramRepr::parse(&d)) {
            Ok(repr) => repr,
            Err(error) => return self.fail(error),
        };
        self.offset += repr.buffer_len();
        self.done = !repr.more;
        Some(Ok(repr))
    }
}

/// Checks what [`DatagramRepr::parse`] checks beyond the view's lengths, so that the shared
/// and the mutable chain walks accept exactly the same chains.
fn check_flags_and_limit<T: AsRef<[u8]>>(
    datagram: &Datagram<T>,
    ignore_reserved: bool,
) -> Result<()> {
    let reserved = datagram.len_flags() & fields::RESERVED_MASK;
    if reserved != 0 && !ignore_reserved {
        return Err(WireError::ReservedBits {
            what: "datagram flags",
            value: u32::from(reserved),
        });
    }
    let declared = usize::from(datagram.length());
    if declared > MAX_DATA_LEN {
        return Err(WireError::BadLength {
            what: "datagram length",
            declared,
            available: MAX_DATA_LEN,
        });
    }
    Ok(())
}

/// Mutable iterator over a datagram chain, for whoever processes datagrams in place (an
/// emulated slave incrementing ADP and WKC, the master copying process data).
///
/// Same walk and same errors as [`Datagrams`]; each item is a view of exactly one datagram
/// (`len + 12` bytes).
#[derive(Debug)]
pub struct DatagramsMut<'a> {
    rest: &'a mut [u8],
    offset: usize,
    started: bool,
    done: bool,
    ignore_reserved: bool,
}

impl<'a> DatagramsMut<'a> {
    /// Iterates the datagrams of `payload` (the bytes after the EtherCAT header).
    pub fn new(payload: &'a mut [u8]) -> Self {
        DatagramsMut {
            rest: payload,
            offset: 0,
            started: false,
            done: false,
            ignore_reserved: false,
        }
    }

    /// Like [`DatagramsMut::new`], but datagrams with reserved bits 11-13 set are walked
    /// like any other (the bits stay as they are). This is what a slave controller does:
    /// it ignores the reserved bits, and some masters (KickCAT) leave them uninitialised.
    pub fn ignoring_reserved_bits(payload: &'a mut [u8]) -> Self {
        DatagramsMut {
            ignore_reserved: true,
            ..Self::new(payload)
        }
    }

    /// Offset in the payload of the next datagram.
    pub const fn offset(&self) -> usize {
        self.offset
    }
}

impl<'a> Iterator for DatagramsMut<'a> {
    type Item = Result<Datagram<&'a mut [u8]>>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        // Any error ends the walk; set it now and clear it on success.
        self.done = true;
        let rest = core::mem::take(&mut self.rest);
        if rest.is_empty() && self.started {
            return Some(Err(WireError::Truncated {
                what: "datagram chain (M bit set)",
                need: OVERHEAD,
                have: 0,
            }));
        }
        self.started = true;
        let ignore_reserved = self.ignore_reserved;
        let (total, more) = match Datagram::new_checked(&*rest).and_then(|d| {
            check_flags_and_limit(&d, ignore_reserved).map(|()| (d.total_len(), d.more()))
        }) {
            Ok(walk) => walk,
            Err(error) => return Some(Err(error)),
        };
        if total > rest.len() {
            // Unreachable after check_len; kept so that no input can panic split_at_mut.
            return Some(Err(WireError::BadLength {
                what: "datagram length",
                declared: total,
                available: rest.len(),
            }));
        }
        let (head, tail) = rest.split_at_mut(total);
        self.rest = tail;
        self.offset += total;
        self.done = !more;
        Some(Ok(Datagram::new_unchecked(head)))
    }
}

/// Zeros for [`FrameBuilder::push_zeroed`], so read requests need no buffer of their own.
static ZEROS: [u8; MAX_DATA_LEN] = [0; MAX_DATA_LEN];

/// Offset of the first datagram in an untagged Ethernet frame.
const FIRST_DATAGRAM: usize = ethernet::HEADER_LEN + frame::HEADER_LEN;

/// Packs datagrams into one Ethernet frame in a caller-provided buffer, without allocation.
///
/// [`push`](Self::push) appends a datagram and returns its offset in the frame (so the
/// returned frame's datagram can be found again, see
/// [`EthercatFrame::datagram_at`](crate::wire::frame::EthercatFrame::datagram_at)); it sets
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

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::wire::frame::EthercatFrame;
    use proptest::prelude::*;

    fn parse(bytes: &[u8]) -> Result<DatagramRepr<'_>> {
        DatagramRepr::parse(&Datagram::new_checked(bytes)?)
    }

    fn emit(repr: &DatagramRepr<'_>) -> Vec<u8> {
        let mut bytes = vec![0xa5u8; repr.buffer_len()];
        repr.emit(&mut Datagram::new_unchecked(&mut bytes[..]))
            .unwrap();
        bytes
    }

    /// Checks parse → expected and emit (into 0xa5) → identical bytes.
    fn check_exact(bytes: &[u8], expected: DatagramRepr<'_>) {
        assert_eq!(parse(bytes).unwrap(), expected);
        assert_eq!(emit(&expected), bytes);
    }

    fn node(station: u16, ado: u16) -> DatagramAddress {
        DatagramAddress::Node { station, ado }
    }

    // ETG.1000.4, spec-notes §commands, datagram part: BRD idx 1, ADP 0, ADO 0, len 2.
    static C1_BRD: [u8; 14] = [
        0x07, 0x01, 0x00, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    ];

    #[test]
    fn c1_brd() {
        check_exact(
            &C1_BRD,
            DatagramRepr::request(Command::Brd, 1, DatagramAddress::broadcast(0), &[0, 0]),
        );
    }

    #[test]
    fn c2_apwr_station_addresses() {
        let first = [
            0x02, 0x02, 0x00, 0x00, 0x10, 0x00, 0x02, 0x00, 0x00, 0x00, 0x01, 0x10, 0x00, 0x00,
        ];
        let second = [
            0x02, 0x03, 0xff, 0xff, 0x10, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x10, 0x00, 0x00,
        ];
        let pos = DatagramAddress::position;
        check_exact(
            &first,
            DatagramRepr::request(Command::Apwr, 2, pos(0, 0x0010), &[0x01, 0x10]),
        );
        check_exact(
            &second,
            DatagramRepr::request(Command::Apwr, 3, pos(1, 0x0010), &[0x02, 0x10]),
        );
        let parsed = parse(&second).unwrap();
        assert_eq!(parsed.typed_address().unwrap().ring_position(), Some(1));
        assert_eq!(
            parsed.to_string(),
            "APWR idx=3 adp=0xffff ado=0x0010 len=2 wkc=0"
        );
    }

    #[test]
    fn c3_sii_read() {
        let command = [
            0x05, 0x04, 0x01, 0x10, 0x02, 0x05, 0x06, 0x00, 0x00, 0x00, 0x00, 0x01, 0x08, 0x00,
            0x00, 0x00, 0x00, 0x00,
        ];
        let fpwr = DatagramRepr::request(
            Command::Fpwr,
            4,
            node(0x1001, 0x0502),
            &[0x00, 0x01, 0x08, 0x00, 0x00, 0x00],
        );
        check_exact(&command, fpwr);
        assert_eq!(
            fpwr.to_string(),
            "FPWR idx=4 adp=0x1001 ado=0x0502 len=6 wkc=0"
        );
        let data = [
            0x04, 0x05, 0x01, 0x10, 0x08, 0x05, 0x08, 0x00, 0x00, 0x00, 0, 0, 0, 0, 0, 0, 0, 0,
            0x00, 0x00,
        ];
        check_exact(
            &data,
            DatagramRepr::request(Command::Fprd, 5, node(0x1001, 0x0508), &[0; 8]),
        );
        // Returned from an EL2004 (spec-notes §esc.sii-if) with WKC 1: vendor 2, product 0x07D43052.
        let mut returned = data;
        returned[10..18].copy_from_slice(&[0x02, 0x00, 0x00, 0x00, 0x52, 0x30, 0xd4, 0x07]);
        returned[18] = 0x01;
        let parsed = parse(&returned).unwrap();
        assert_eq!(
            parsed.data,
            &[0x02, 0x00, 0x00, 0x00, 0x52, 0x30, 0xd4, 0x07]
        );
        assert_eq!(parsed.wkc, 1);
    }

    #[test]
    fn c4_mailbox_sync_managers() {
        // FPWR idx 6 to station 0x1001, ADO 0x0800, 16 bytes (header worked out by hand).
        let sm = [
            0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00, 0x80, 0x10, 0x80, 0x00, 0x22, 0x00,
            0x01, 0x00,
        ];
        let mut bytes = vec![0x05, 0x06, 0x01, 0x10, 0x00, 0x08, 0x10, 0x00, 0x00, 0x00];
        bytes.extend_from_slice(&sm);
        bytes.extend_from_slice(&[0x00, 0x00]);
        check_exact(
            &bytes,
            DatagramRepr::request(Command::Fpwr, 6, node(0x1001, 0x0800), &sm),
        );
    }

    #[test]
    fn c5_al_control() {
        for (data, idx) in [([0x02, 0x00], 7u8), ([0x12, 0x00], 8u8)] {
            let bytes = [
                0x05, idx, 0x01, 0x10, 0x20, 0x01, 0x02, 0x00, 0x00, 0x00, data[0], data[1], 0x00,
                0x00,
            ];
            check_exact(
                &bytes,
                DatagramRepr::request(Command::Fpwr, idx, node(0x1001, 0x0120), &data),
            );
        }
    }

    #[test]
    fn c17_dc_datagrams() {
        let latch = [
            0x08, 0x05, 0x00, 0x00, 0x00, 0x09, 0x04, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
            0x00, 0x00,
        ];
        check_exact(
            &latch,
            DatagramRepr::request(Command::Bwr, 5, DatagramAddress::broadcast(0x0900), &[0; 4]),
        );
        let frmw = [
            0x0e, 0x06, 0x01, 0x10, 0x10, 0x09, 0x08, 0x00, 0x00, 0x00, 0, 0, 0, 0, 0, 0, 0, 0,
            0x00, 0x00,
        ];
        check_exact(
            &frmw,
            DatagramRepr::request(Command::Frmw, 6, node(0x1001, 0x0910), &[0; 8]),
        );
    }

    #[test]
    fn c18_cyclic_lrw() {
        // Outputs o0 o1 = 0x12 0x34 (example values), 2 input bytes zero.
        let bytes = [
            0x0c, 0x07, 0x00, 0x00, 0x00, 0x00, 0x04, 0x00, 0x00, 0x00, 0x12, 0x34, 0x00, 0x00,
            0x00, 0x00,
        ];
        let lrw = DatagramRepr::request(
            Command::Lrw,
            7,
            DatagramAddress::Logical(0),
            &[0x12, 0x34, 0x00, 0x00],
        );
        check_exact(&bytes, lrw);
        // Returned with the expected WKC 3.
        let mut returned = bytes;
        returned[14] = 0x03;
        let parsed = parse(&returned).unwrap();
        assert_eq!(parsed.wkc, 3);
        assert_eq!(parsed.to_string(), "LRW idx=7 log=0x00000000 len=4 wkc=3");
    }

    #[test]
    fn seed_station_address_write() {
        // spec-notes §capture: APWR to position 0, ADO 0x0010, data 0x03E9 (TwinCAT's station 1001).
        let bytes = [
            0x02, 0x81, 0x00, 0x00, 0x10, 0x00, 0x02, 0x00, 0x00, 0x00, 0xe9, 0x03, 0x00, 0x00,
        ];
        check_exact(
            &bytes,
            DatagramRepr::request(
                Command::Apwr,
                0x81,
                DatagramAddress::position(0, 0x0010),
                &1001u16.to_le_bytes(),
            ),
        );
    }

    /// spec-notes §capture, first frame: BWR idx 0x80 to ADO 0x0101 (loop control), 1 byte 00,
    /// EtherCAT header 0x100d; the source MAC is all zeros in the capture.
    static SEED_FIRST_FRAME: [u8; 60] = [
        0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x88, 0xa4, 0x0d,
        0x10, // EtherCAT header 0x100d: type 1, length 13
        0x08, 0x80, 0x00, 0x00, 0x01, 0x01, 0x01, 0x00, 0x00, 0x00, // BWR header
        0x00, // data
        0x00, 0x00, // WKC
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        0, // 31 bytes of padding
    ];

    #[test]
    fn seed_first_frame_built_and_parsed() {
        let mut buffer = [0xa5u8; 128];
        let mut builder = FrameBuilder::new(&mut buffer).unwrap();
        let bwr =
            DatagramRepr::request(Command::Bwr, 0x80, DatagramAddress::broadcast(0x0101), &[0]);
        assert_eq!(builder.push(&bwr), Ok(16));
        let total = builder.finish([0; 6]).unwrap();
        assert_eq!(total, 60);
        assert_eq!(buffer[..60], SEED_FIRST_FRAME);
        let frame = EthercatFrame::parse(&SEED_FIRST_FRAME).unwrap();
        assert_eq!(frame.header.length, 13);
        let all: Vec<_> = frame.datagrams().unwrap().collect();
        assert_eq!(all, vec![Ok(bwr)]);
    }

    #[test]
    fn c1_frame_built() {
        let mut buffer = [0xa5u8; 60];
        let mut builder = FrameBuilder::new(&mut buffer).unwrap();
        let brd = DatagramRepr::request(Command::Brd, 1, DatagramAddress::broadcast(0), &[0, 0]);
        builder.push(&brd).unwrap();
        assert_eq!(builder.finish([0x02, 0, 0, 0, 0, 0x01]), Ok(60));
        let mut expected = [0u8; 60];
        expected[..6].copy_from_slice(&[0xff; 6]);
        expected[6..16].copy_from_slice(&[0x02, 0, 0, 0, 0, 0x01, 0x88, 0xa4, 0x0e, 0x10]);
        expected[16..30].copy_from_slice(&C1_BRD);
        assert_eq!(buffer, expected);
    }

    /// The cyclic frame of spec-notes §capture: LRD 0x11000 (inputs, 2 bytes), LWR 0x12000 (outputs, 2 bytes
    /// 0xAA 0x55), LRD 0x40000 (1 byte: SM1 status 0x080D via FMMU, bit 3 = mailbox full),
    /// FRMW 0x0910 from station 0x03E9 (8 bytes DC system time). Indices 0x10..=0x13.
    #[rustfmt::skip]
    static SEED_CYCLIC: [u8; 77] = [
        0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02, 0x00, 0x00, 0x00, 0x00, 0x01, 0x88, 0xa4,
        0x3d, 0x10, // 61 = 14 + 14 + 13 + 20 bytes, type 1
        0x0a, 0x10, 0x00, 0x10, 0x01, 0x00, 0x02, 0x80, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
        0x0b, 0x11, 0x00, 0x20, 0x01, 0x00, 0x02, 0x80, 0x00, 0x00, 0xaa, 0x55, 0x00, 0x00,
        0x0a, 0x12, 0x00, 0x00, 0x04, 0x00, 0x01, 0x80, 0x00, 0x00, 0x00, 0x00, 0x00,
        0x0e, 0x13, 0xe9, 0x03, 0x10, 0x09, 0x08, 0x00, 0x00, 0x00,
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    ];

    #[test]
    fn seed_cyclic_frame() {
        let mut buffer = [0xa5u8; 1514];
        let mut builder = FrameBuilder::new(&mut buffer).unwrap();
        let log = DatagramAddress::Logical;
        let offsets = [
            builder.push_zeroed(Command::Lrd, 0x10, log(0x11000), 2),
            builder.push(&DatagramRepr::request(
                Command::Lwr,
                0x11,
                log(0x12000),
                &[0xaa, 0x55],
            )),
            builder.push_zeroed(Command::Lrd, 0x12, log(0x40000), 1),
            builder.push_zeroed(Command::Frmw, 0x13, node(0x03E9, 0x0910), 8),
        ]
        .map(Result::unwrap);
        assert_eq!(offsets, [16, 30, 44, 57]);
        assert_eq!(builder.datagram_count(), 4);
        assert_eq!(builder.len(), 77);
        let total = builder.finish([0x02, 0, 0, 0, 0, 0x01]).unwrap();
        assert_eq!(total, 77, "above the minimum: no padding");
        assert_eq!(buffer[..77], SEED_CYCLIC);

        let frame = EthercatFrame::parse(&buffer[..total]).unwrap();
        assert_eq!(frame.header.length, 61);
        let parsed: Vec<_> = frame.datagrams().unwrap().map(Result::unwrap).collect();
        let more: Vec<_> = parsed.iter().map(|d| d.more).collect();
        assert_eq!(more, [true, true, true, false]);
        let commands: Vec<_> = parsed.iter().map(|d| d.command).collect();
        assert_eq!(
            commands,
            [Command::Lrd, Command::Lwr, Command::Lrd, Command::Frmw]
        );
        assert_eq!(parsed[1].data, &[0xaa, 0x55]);
        assert_eq!(parsed[3].typed_address(), Some(node(0x03E9, 0x0910)));
        // Read back by offset, as the bus loop does with the offsets `push` returned.
        for (offset, expected) in offsets.iter().zip(&parsed) {
            let view = frame.datagram_at(*offset).unwrap();
            assert_eq!(DatagramRepr::parse(&view).unwrap(), *expected);
        }
        assert_eq!(
            frame.to_string(),
            "ETH 02:00:00:00:00:01 > ff:ff:ff:ff:ff:ff type=0x88a4 ECAT EtherCAT command len=61\n  \
             LRD idx=16 log=0x00011000 len=2 wkc=0\n  \
             LWR idx=17 log=0x00012000 len=2 wkc=0\n  \
             LRD idx=18 log=0x00040000 len=1 wkc=0\n  \
             FRMW idx=19 adp=0x03e9 ado=0x0910 len=8 wkc=0"
        );
    }

    #[test]
    fn padding_after_last_datagram_is_ignored() {
        // The count-slaves BRD of spec-notes §commands followed by garbage that is not a datagram: M = 0 ends the chain.
        let mut payload = C1_BRD.to_vec();
        payload.extend_from_slice(&[0xff; 20]);
        let mut chain = Datagrams::new(&payload);
        assert!(chain.next().unwrap().is_ok());
        assert!(chain.next().is_none());
        assert_eq!(chain.offset(), 14);
    }

    #[test]
    fn more_bit_without_following_datagram_is_an_error() {
        let mut payload = C1_BRD;
        payload[7] = 0x80;
        let mut chain = Datagrams::new(&payload);
        assert!(chain.next().unwrap().unwrap().more);
        assert_eq!(
            chain.next().unwrap(),
            Err(WireError::Truncated {
                what: "datagram chain (M bit set)",
                need: 12,
                have: 0
            })
        );
        assert!(chain.next().is_none(), "an error ends the iteration");
        // M = 1 followed by a partial datagram is an error too.
        let mut longer = payload.to_vec();
        longer.extend_from_slice(&C1_BRD[..11]);
        let results: Vec<_> = Datagrams::new(&longer).collect();
        assert_eq!(results.len(), 2);
        assert!(results[1].is_err());
        // An empty payload has no datagram.
        assert!(Datagrams::new(&[]).next().unwrap().is_err());
    }

    #[test]
    fn mutable_walk_processes_in_place() {
        // The reference cyclic frame's chain as an emulated slave would see it: bump every WKC
        // and fill the 1-byte mailbox status read with bit 3 (SM1 full).
        let mut payload = SEED_CYCLIC[16..].to_vec();
        payload.extend_from_slice(&[0u8; 5]); // padding is ignored
        let mut walk = DatagramsMut::new(&mut payload);
        for item in walk.by_ref() {
            let mut datagram = item.unwrap();
            if datagram.typed_address() == Some(DatagramAddress::Logical(0x40000)) {
                datagram.data_mut()[0] = 0x08;
            }
            let wkc = datagram.wkc();
            datagram.set_wkc(wkc + 1);
        }
        assert_eq!(walk.offset(), 61);
        let wkcs: Vec<_> = Datagrams::new(&payload).map(|d| d.unwrap().wkc).collect();
        assert_eq!(wkcs, [1, 1, 1, 1]);
        assert_eq!(
            payload[38], 0x08,
            "data byte of the third datagram (offset 28 + 10)"
        );

        // Same errors as the shared walk.
        let mut dangling = C1_BRD;
        dangling[7] = 0x80;
        let results: Vec<_> = DatagramsMut::new(&mut dangling)
            .map(|r| r.map(|_| ()))
            .collect();
        assert_eq!(
            results,
            [
                Ok(()),
                Err(WireError::Truncated {
                    what: "datagram chain (M bit set)",
                    need: 12,
                    have: 0
                })
            ]
        );
        let mut reserved = C1_BRD;
        reserved[7] = 0x08;
        assert!(matches!(
            DatagramsMut::new(&mut reserved).next(),
            Some(Err(WireError::ReservedBits { .. }))
        ));
        // A slave controller's walk takes it, leaving the bits alone.
        let mut walk = DatagramsMut::ignoring_reserved_bits(&mut reserved);
        let datagram = walk.next().unwrap().unwrap();
        assert_eq!(datagram.len_flags() & 0x3800, 0x0800);
        assert!(walk.next().is_none());
        assert!(DatagramsMut::new(&mut []).next().unwrap().is_err());
    }

    #[test]
    fn length_beyond_bytes_is_bad_length() {
        // BRD declaring 3 data bytes: 10 + 3 + 2 = 15 needed, 14 present.
        let mut bytes = C1_BRD;
        bytes[6] = 0x03;
        assert_eq!(
            Datagram::new_checked(&bytes[..]).unwrap_err(),
            WireError::BadLength {
                what: "datagram length",
                declared: 3,
                available: 2
            }
        );
        assert!(matches!(
            Datagram::new_checked(&C1_BRD[..9]),
            Err(WireError::Truncated {
                what: "datagram header",
                ..
            })
        ));
        assert!(matches!(
            Datagram::new_checked(&C1_BRD[..11]),
            Err(WireError::Truncated {
                what: "datagram",
                need: 14,
                have: 11
            })
        ));
        // The declared length inside a frame counts too.
        assert!(matches!(
            Datagrams::new(&bytes).next(),
            Some(Err(WireError::BadLength { .. }))
        ));
    }

    #[test]
    fn reserved_bits_are_refused() {
        for bit in [0x08u8, 0x10, 0x20] {
            let mut bytes = C1_BRD;
            bytes[7] = bit;
            assert_eq!(
                parse(&bytes).unwrap_err(),
                WireError::ReservedBits {
                    what: "datagram flags",
                    value: u32::from(bit) << 8
                }
            );
        }
    }

    #[test]
    fn flags_and_irq() {
        // C = 0x4000, M = 0x8000 → len/flags `02 c0`; IRQ 0x0102 → `02 01`.
        let mut bytes = C1_BRD;
        bytes[7] = 0xc0;
        bytes[8] = 0x02;
        bytes[9] = 0x01;
        let repr = DatagramRepr {
            circulating: true,
            more: true,
            irq: 0x0102,
            ..DatagramRepr::request(Command::Brd, 1, DatagramAddress::broadcast(0), &[0, 0])
        };
        check_exact(&bytes, repr);
        assert_eq!(
            repr.to_string(),
            "BRD idx=1 adp=0x0000 ado=0x0000 len=2 wkc=0 circulating irq=0x0102"
        );
        let nop =
            DatagramRepr::request(Command::Unknown(0x20), 0, DatagramAddress::Logical(5), &[]);
        assert_eq!(
            nop.to_string(),
            "CMD(0x20) idx=0 addr=0x00000005 len=0 wkc=0"
        );
    }

    #[test]
    fn view_setters() {
        let mut bytes = C1_BRD;
        let mut view = Datagram::new_checked(&mut bytes[..]).unwrap();
        view.set_adp(3);
        view.set_wkc(3);
        view.set_more(true);
        view.set_more(false);
        view.set_circulating(true);
        view.data_mut().copy_from_slice(&[0x11, 0x00]);
        assert_eq!(view.total_len(), 14);
        assert_eq!(
            bytes,
            [
                0x07, 0x01, 0x03, 0x00, 0x00, 0x00, 0x02, 0x40, 0x00, 0x00, 0x11, 0x00, 0x03, 0x00
            ]
        );
    }

    #[test]
    fn emit_refusals_write_nothing() {
        let big = [0u8; MAX_DATA_LEN + 1];
        let repr = DatagramRepr::request(Command::Lrw, 0, DatagramAddress::Logical(0), &big);
        let mut bytes = vec![0u8; repr.buffer_len()];
        assert!(matches!(
            repr.emit(&mut Datagram::new_unchecked(&mut bytes[..])),
            Err(WireError::BadLength {
                declared: 1487,
                available: 1486,
                ..
            })
        ));
        assert!(bytes.iter().all(|b| *b == 0));
        let small = DatagramRepr::request(Command::Lrw, 0, DatagramAddress::Logical(0), &[1, 2]);
        let mut short = [0u8; 13];
        assert!(matches!(
            small.emit(&mut Datagram::new_unchecked(&mut short[..])),
            Err(WireError::BufferTooSmall {
                need: 14,
                have: 13,
                ..
            })
        ));
        assert_eq!(short, [0u8; 13]);
    }

    #[test]
    fn over_long_declared_length_is_refused_by_parse() {
        // len 1487 (0x05CF) with all bytes present: over the MTU limit.
        let mut bytes = vec![0u8; OVERHEAD + 1487];
        bytes[0] = 0x0c;
        bytes[6] = 0xcf;
        bytes[7] = 0x05;
        assert!(Datagram::new_checked(&bytes[..]).is_ok());
        assert!(matches!(
            parse(&bytes),
            Err(WireError::BadLength {
                declared: 1487,
                available: 1486,
                ..
            })
        ));
    }

    #[test]
    fn builder_limits() {
        let mut small = [0u8; 59];
        assert!(matches!(
            FrameBuilder::new(&mut small),
            Err(WireError::BufferTooSmall {
                need: 60,
                have: 59,
                ..
            })
        ));
        // A maximum datagram fills a 1514-byte frame exactly; nothing fits after it.
        let mut buffer = vec![0xa5u8; 2000];
        let mut builder = FrameBuilder::new(&mut buffer).unwrap();
        assert_eq!(builder.remaining_data(), MAX_DATA_LEN);
        let full = builder
            .push_zeroed(Command::Lrw, 0, DatagramAddress::Logical(0), MAX_DATA_LEN)
            .unwrap();
        assert_eq!(full, 16);
        assert_eq!(builder.remaining_data(), 0);
        assert_eq!(
            builder.push_zeroed(Command::Nop, 1, DatagramAddress::Logical(0), 0),
            Err(WireError::BufferTooSmall {
                what: "EtherCAT frame",
                need: 1526,
                have: 1514
            })
        );
        assert!(matches!(
            builder.push_zeroed(
                Command::Nop,
                1,
                DatagramAddress::Logical(0),
                MAX_DATA_LEN + 1
            ),
            Err(WireError::BadLength { .. })
        ));
        assert_eq!(builder.datagram_count(), 1);
        assert_eq!(builder.finish([0; 6]), Ok(1514));
        assert_eq!(buffer[14..16], [0xda, 0x15], "length 1498 = 0x5DA, type 1");
        assert_eq!(buffer[1514], 0xa5, "nothing written past the frame");

        // A 60-byte buffer takes datagrams up to 44 bytes in total.
        let mut buffer = [0u8; 60];
        let mut builder = FrameBuilder::new(&mut buffer).unwrap();
        builder
            .push_zeroed(Command::Brd, 0, DatagramAddress::broadcast(0), 30)
            .unwrap();
        assert!(matches!(
            builder.push_zeroed(Command::Brd, 1, DatagramAddress::broadcast(0), 1),
            Err(WireError::BufferTooSmall {
                need: 71,
                have: 60,
                ..
            })
        ));
        // An empty frame is refused.
        let mut buffer = [0u8; 60];
        assert!(
            FrameBuilder::new(&mut buffer)
                .unwrap()
                .finish([0; 6])
                .is_err()
        );
    }

    #[test]
    fn builder_datagram_mut_fills_in_place() {
        let mut buffer = [0u8; 64];
        let mut builder = FrameBuilder::new(&mut buffer).unwrap();
        let first = builder
            .push_zeroed(Command::Lwr, 1, DatagramAddress::Logical(0x1000), 2)
            .unwrap();
        builder
            .push_zeroed(Command::Lrd, 2, DatagramAddress::Logical(0x2000), 2)
            .unwrap();
        builder
            .datagram_mut(first)
            .unwrap()
            .data_mut()
            .copy_from_slice(&[7, 8]);
        assert!(builder.datagram_mut(3).is_err());
        let total = builder.finish([0; 6]).unwrap();
        let frame = EthercatFrame::parse(&buffer[..total]).unwrap();
        assert_eq!(frame.datagram_at(first).unwrap().data(), &[7, 8]);
    }

    pub(crate) fn arb_datagram(
        max_data: usize,
    ) -> impl Strategy<Value = (DatagramRepr<'static>, Vec<u8>)> {
        (
            any::<u8>(),
            any::<u8>(),
            any::<u32>(),
            proptest::collection::vec(any::<u8>(), 0..=max_data),
            any::<bool>(),
            any::<bool>(),
            any::<u16>(),
            any::<u16>(),
        )
            .prop_map(|(cmd, index, address, data, circulating, more, irq, wkc)| {
                (
                    DatagramRepr {
                        command: Command::from(cmd),
                        index,
                        address,
                        data: &[],
                        circulating,
                        more,
                        irq,
                        wkc,
                    },
                    data,
                )
            })
    }

    proptest! {
        #[test]
        fn round_trip((repr, data) in arb_datagram(64), tail in 0usize..4) {
            let repr = DatagramRepr { data: &data, ..repr };
            let mut bytes = vec![0u8; repr.buffer_len() + tail];
            repr.emit(&mut Datagram::new_unchecked(&mut bytes[..])).unwrap();
            prop_assert_eq!(parse(&bytes).unwrap(), repr);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            if let Ok(view) = Datagram::new_checked(&bytes[..]) {
                let _ = (view.data(), view.wkc(), view.typed_address(), view.total_len());
                let _ = DatagramRepr::parse(&view).map(|d| d.to_string());
            }
        }

        #[test]
        fn chain_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..128)) {
            let mut count = 0;
            for item in Datagrams::new(&bytes) {
                count += 1;
                let _ = item.map(|d| d.to_string());
            }
            // Each datagram takes at least 12 bytes, plus one final error at most.
            prop_assert!(count <= bytes.len() / OVERHEAD + 1);
        }

        #[test]
        fn mutable_chain_agrees_with_shared_chain(
            mut bytes in proptest::collection::vec(any::<u8>(), 0..128),
        ) {
            let shared: Vec<_> = Datagrams::new(&bytes)
                .map(|r| r.map(|d| d.buffer_len()))
                .collect();
            let mutable: Vec<_> = DatagramsMut::new(&mut bytes)
                .map(|r| r.map(|d| d.total_len()))
                .collect();
            prop_assert_eq!(shared, mutable);
        }

        #[test]
        fn builder_round_trip(
            datagrams in proptest::collection::vec(arb_datagram(40), 1..8),
            source: [u8; 6],
        ) {
            let mut buffer = vec![0xa5u8; 1514];
            let mut builder = FrameBuilder::new(&mut buffer).unwrap();
            let mut pushed = Vec::new();
            for (repr, data) in &datagrams {
                let repr = DatagramRepr { data, ..*repr };
                let offset = builder.push(&repr).unwrap();
                pushed.push((offset, repr));
            }
            let chain_len: usize = pushed.iter().map(|(_, d)| d.buffer_len()).sum();
            let total = builder.finish(source).unwrap();
            prop_assert_eq!(total, (16 + chain_len).max(60));
            let frame = EthercatFrame::parse(&buffer[..total]).unwrap();
            prop_assert_eq!(frame.ethernet.source, source);
            prop_assert_eq!(usize::from(frame.header.length), chain_len);
            prop_assert!(buffer[16 + chain_len..total].iter().all(|b| *b == 0));
            let parsed: Vec<_> = frame.datagrams().unwrap().collect::<Result<_>>().unwrap();
            prop_assert_eq!(parsed.len(), pushed.len());
            let last = pushed.len() - 1;
            for (i, ((offset, sent), got)) in pushed.iter().zip(&parsed).enumerate() {
                let expected = DatagramRepr { more: i != last, ..*sent };
                prop_assert_eq!(*got, expected);
                let view = frame.datagram_at(*offset).unwrap();
                prop_assert_eq!(DatagramRepr::parse(&view).unwrap(), expected);
            }
        }
    }
}
