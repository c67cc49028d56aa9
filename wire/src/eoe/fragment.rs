//! EoE fragment data (frame type 0) and the sender-side fragmenter (ETG.1000.6, spec-notes §eoe).

use core::fmt;

use super::header::{
    EoeFrameType, EoePacket, HEADER_LEN, MAX_FRAGMENT_NUMBER, MAX_FRAME_NUMBER, MAX_OFFSET_FIELD,
    MAX_PORT, OFFSET_UNIT, payload_of,
};
use crate::error::{Result, WireError, need, room};
use crate::field;
use crate::mailbox;

/// Size of an appended timestamp.
pub const TIMESTAMP_LEN: usize = 4;

/// The largest Ethernet frame (without FCS) the 6-bit size field can describe: 63 × 32.
pub const MAX_FRAME_LEN: usize = MAX_OFFSET_FIELD as usize * OFFSET_UNIT;

/// One fragment of an Ethernet frame (frame type 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FragmentRepr<'a> {
    /// Port, 0..=15 (0 = unspecified).
    pub port: u8,
    /// This is the last fragment of the frame.
    pub last: bool,
    /// The sender asks for a timestamp response (type 1).
    pub time_request: bool,
    /// Fragment number, 0..=63 (0 = first).
    pub fragment_number: u8,
    /// Fragment 0: the complete frame size in 32-byte units, rounded up (an upper bound, IgH
    /// over-reports by one unit for multiples of 32); others: byte offset of `data` / 32.
    pub offset_field: u8,
    /// Frame number, 0..=15, the same for all fragments of a frame.
    pub frame_number: u8,
    /// The fragment's bytes of the Ethernet frame.
    pub data: &'a [u8],
    /// A timestamp appended after the data (time-appended bit), normally on the last
    /// fragment only.
    pub timestamp: Option<u32>,
}

impl<'a> FragmentRepr<'a> {
    /// Parses a checked EoE view of frame type 0 (the type is not checked here, see
    /// [`super::EoeRepr::parse`]). With the time-appended bit the last 4 payload bytes are
    /// the timestamp. Reserved flag bits are ignored.
    pub fn parse<T: AsRef<[u8]> + ?Sized>(packet: &EoePacket<&'a T>) -> Result<Self> {
        packet.check_len()?;
        let payload = payload_of(packet);
        let (data, timestamp) = if packet.time_appended() {
            need("EoE appended timestamp", payload, TIMESTAMP_LEN)?;
            let (data, ts) = payload.split_at(payload.len() - TIMESTAMP_LEN);
            (data, Some(field::u32_le(ts, 0)))
        } else {
            (payload, None)
        };
        Ok(FragmentRepr {
            port: packet.port(),
            last: packet.last_fragment(),
            time_request: packet.time_request(),
            fragment_number: packet.fragment_number(),
            offset_field: packet.offset_field(),
            frame_number: packet.frame_number(),
            data,
            timestamp,
        })
    }

    /// Bytes needed on the wire.
    pub fn buffer_len(&self) -> usize {
        HEADER_LEN
            + self.data.len()
            + if self.timestamp.is_some() {
                TIMESTAMP_LEN
            } else {
                0
            }
    }

    /// Writes the fragment into the start of `packet`'s buffer; refuses fields wider than
    /// their bits.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, packet: &mut EoePacket<T>) -> Result<()> {
        room(
            "EoE fragment",
            packet.as_bytes().as_ref(),
            self.buffer_len(),
        )?;
        if self.port > MAX_PORT
            || self.fragment_number > MAX_FRAGMENT_NUMBER
            || self.offset_field > MAX_OFFSET_FIELD
            || self.frame_number > MAX_FRAME_NUMBER
        {
            return Err(WireError::Invalid {
                what: "EoE fragment",
                reason: "port, fragment number, offset or frame number out of range",
            });
        }
        packet.set_type_port(EoeFrameType::Fragment, self.port);
        packet.set_flags(self.last, self.timestamp.is_some(), self.time_request);
        packet.set_fragment_info(self.fragment_number, self.offset_field, self.frame_number);
        let n = self.data.len();
        let payload = packet.payload_mut();
        payload[..n].copy_from_slice(self.data);
        if let Some(ts) = self.timestamp {
            field::set_u32_le(payload, n, ts);
        }
        Ok(())
    }
}

impl fmt::Display for FragmentRepr<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let what = if self.fragment_number == 0 {
            "size"
        } else {
            "offset"
        };
        write!(
            f,
            "EoE frag #{} frame {} {what}={}x32",
            self.fragment_number, self.frame_number, self.offset_field
        )?;
        if self.last {
            f.write_str(" last")?;
        }
        if self.port != 0 {
            write!(f, " port {}", self.port)?;
        }
        if self.time_request {
            f.write_str(" time-req")?;
        }
        if let Some(ts) = self.timestamp {
            write!(f, " ts={ts}")?;
        }
        write!(f, " ({} bytes)", self.data.len())
    }
}

/// Splits an Ethernet frame into EoE fragments for a receiver mailbox (spec-notes §eoe, sender
/// rules): a fragment carries at most `M − 10` bytes; every non-last fragment carries a
/// multiple of 32 bytes (`((M − 10) / 32) × 32`, as IgH); fragment 0's size field is
/// `ceil(len / 32)`, later offset fields are `bytes sent / 32`.
#[derive(Debug, Clone)]
pub struct Fragmenter<'a> {
    frame: &'a [u8],
    last_capacity: usize,
    chunk: usize,
    frame_number: u8,
    port: u8,
    sent: usize,
    next_fragment: u8,
    done: bool,
}

impl<'a> Fragmenter<'a> {
    /// Prepares the fragments of `frame` (without FCS) for a receiver mailbox of
    /// `mailbox_size` bytes (the SyncManager length, header included).
    ///
    /// Refuses a frame number above 15, a frame longer than [`MAX_FRAME_LEN`], and a
    /// mailbox too small to carry a 32-byte non-last fragment when one is needed.
    pub fn new(frame: &'a [u8], mailbox_size: usize, frame_number: u8) -> Result<Self> {
        if frame_number > MAX_FRAME_NUMBER {
            return Err(WireError::Invalid {
                what: "EoE fragmenter",
                reason: "frame number above 15",
            });
        }
        if frame.len() > MAX_FRAME_LEN {
            return Err(WireError::BadLength {
                what: "EoE frame",
                declared: frame.len(),
                available: MAX_FRAME_LEN,
            });
        }
        let last_capacity = mailbox_size.saturating_sub(mailbox::HEADER_LEN + HEADER_LEN);
        let chunk = last_capacity / OFFSET_UNIT * OFFSET_UNIT;
        if frame.len() > last_capacity && chunk == 0 {
            return Err(WireError::Invalid {
                what: "EoE fragmenter",
                reason: "mailbox too small for a 32-byte fragment",
            });
        }
        Ok(Fragmenter {
            frame,
            last_capacity,
            chunk,
            frame_number,
            port: 0,
            sent: 0,
            next_fragment: 0,
            done: false,
        })
    }

    /// Uses `port` for every fragment. Not masked: a port above 15 is kept, so that emitting
    /// the fragments refuses it rather than silently sending another port.
    pub fn with_port(mut self, port: u8) -> Self {
        self.port = port;
        self
    }
}

impl<'a> Iterator for Fragmenter<'a> {
    type Item = FragmentRepr<'a>;

    fn next(&mut self) -> Option<FragmentRepr<'a>> {
        if self.done {
            return None;
        }
        let rest = self.frame.get(self.sent..)?;
        let (len, last) = if rest.len() <= self.last_capacity {
            (rest.len(), true)
        } else {
            (self.chunk, false)
        };
        // Both values are ≤ 63: the frame is at most 63 × 32 bytes (checked in `new`).
        let offset_field = if self.next_fragment == 0 {
            self.frame.len().div_ceil(OFFSET_UNIT)
        } else {
            self.sent / OFFSET_UNIT
        } as u8;
        let fragment = FragmentRepr {
            port: self.port,
            last,
            time_request: false,
            fragment_number: self.next_fragment,
            offset_field,
            frame_number: self.frame_number,
            data: rest.get(..len)?,
            timestamp: None,
        };
        self.sent += len;
        self.next_fragment = self.next_fragment.wrapping_add(1);
        self.done = last;
        Some(fragment)
    }
}
