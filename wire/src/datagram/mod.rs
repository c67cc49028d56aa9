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
//!
//! The frame builder lives with the frame ([`crate::frame::FrameBuilder`]) and is
//! re-exported here; the tests are in `tests.rs` beside this file.

use core::fmt;

use crate::command::{Command, DatagramAddress};
use crate::error::{Result, WireError, need, room};
use crate::field::{self, Field, Rest};
use crate::frame;

pub use crate::frame::FrameBuilder;

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

#[cfg(test)]
pub(crate) mod tests;
