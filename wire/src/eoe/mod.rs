//! EoE — Ethernet over EtherCAT (mailbox type 2, ETG.1000.6, spec-notes §eoe).
//!
//! - [`header`]: the 4-byte EoE header view, frame types and result codes (spec-notes §eoe);
//! - [`fragment`]: Ethernet frame fragments (type 0) and the sender's [`Fragmenter`] (spec-notes §eoe);
//! - [`reassembly`]: the receiver's bounded [`Reassembler`] (ETG.1000.6, spec-notes §eoe);
//! - [`ip`]: the Set IP request / Get IP response body (ETG.1000.6, spec-notes §eoe);
//! - [`filter`]: the Set address filter request body (ETG.1000.6, spec-notes §eoe, best effort);
//! - here: [`EoeRepr`], one parsed EoE message of any frame type.
//!
//! All views cover the mailbox *data* (after the 6-byte mailbox header).

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field;

pub mod filter;
pub mod fragment;
pub mod header;
pub mod ip;
pub mod reassembly;

pub use filter::AddressFilter;
pub use fragment::{FragmentRepr, Fragmenter};
pub use header::{EoeFrameType, EoePacket, EoeResult, HEADER_LEN};
pub use ip::IpParameters;
pub use reassembly::{ReassembledFrame, Reassembler, ReassemblyError};

use header::{MAX_FRAME_NUMBER, MAX_PORT, payload_of};

/// Size of the timestamp of a timestamp response.
const TIMESTAMP_LEN: usize = 4;

/// One parsed EoE message.
///
/// For frame types other than 0 and 1 the flag byte (byte 1) is ignored on parse and written
/// 0 on emit (spec-notes §eoe; bytes 2-3 are the result in responses and 0 in requests).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EoeRepr<'a> {
    /// Type 0: a fragment of an Ethernet frame.
    Fragment(FragmentRepr<'a>),
    /// Type 1: timestamp response. Of the fragment fields only the frame number is kept
    /// (the others are written 0); which clock the timestamp uses is **Uncertain** (spec-notes §eoe).
    Timestamp {
        /// Port.
        port: u8,
        /// The frame the timestamp belongs to.
        frame_number: u8,
        /// The timestamp (ns).
        timestamp: u32,
    },
    /// Type 2: Set IP parameter request.
    SetIpRequest {
        /// Port.
        port: u8,
        /// The parameters to set.
        params: IpParameters<'a>,
    },
    /// Type 3: Set IP parameter response.
    SetIpResponse {
        /// Port.
        port: u8,
        /// Result.
        result: EoeResult,
    },
    /// Type 4: Set address filter request.
    SetAddressFilterRequest {
        /// Port.
        port: u8,
        /// The filter.
        filter: AddressFilter,
    },
    /// Type 5: Set address filter response.
    SetAddressFilterResponse {
        /// Port.
        port: u8,
        /// Result.
        result: EoeResult,
    },
    /// Type 6: Get IP parameter request (header only; any body is ignored).
    GetIpRequest {
        /// Port.
        port: u8,
    },
    /// Type 7: Get IP parameter response. An empty body (typical with an error result)
    /// parses as no parameters; emit always writes at least the flags.
    GetIpResponse {
        /// Port.
        port: u8,
        /// Result.
        result: EoeResult,
        /// The parameters reported.
        params: IpParameters<'a>,
    },
    /// Types 8, 9 (get address filter, layout unknown) and unknown types: kept as raw data.
    Other {
        /// The frame type (never 0..=7 on emit: those have their own variants).
        frame_type: EoeFrameType,
        /// Port.
        port: u8,
        /// Bytes 2-3.
        info: u16,
        /// The body after the header.
        body: &'a [u8],
    },
}

impl<'a> EoeRepr<'a> {
    /// Parses a checked EoE view according to its frame type.
    pub fn parse<T: AsRef<[u8]> + ?Sized>(packet: &EoePacket<&'a T>) -> Result<Self> {
        packet.check_len()?;
        let port = packet.port();
        let body = payload_of(packet);
        Ok(match packet.frame_type() {
            EoeFrameType::Fragment => EoeRepr::Fragment(FragmentRepr::parse(packet)?),
            EoeFrameType::TimestampResponse => {
                need("EoE timestamp", body, TIMESTAMP_LEN)?;
                EoeRepr::Timestamp {
                    port,
                    frame_number: packet.frame_number(),
                    timestamp: field::u32_le(body, 0),
                }
            }
            EoeFrameType::SetIpRequest => EoeRepr::SetIpRequest {
                port,
                params: IpParameters::parse_body(body)?,
            },
            EoeFrameType::SetIpResponse => EoeRepr::SetIpResponse {
                port,
                result: packet.result(),
            },
            EoeFrameType::SetAddressFilterRequest => EoeRepr::SetAddressFilterRequest {
                port,
                filter: AddressFilter::parse_body(body)?,
            },
            EoeFrameType::SetAddressFilterResponse => EoeRepr::SetAddressFilterResponse {
                port,
                result: packet.result(),
            },
            EoeFrameType::GetIpRequest => EoeRepr::GetIpRequest { port },
            EoeFrameType::GetIpResponse => EoeRepr::GetIpResponse {
                port,
                result: packet.result(),
                params: if body.is_empty() {
                    IpParameters::default()
                } else {
                    IpParameters::parse_body(body)?
                },
            },
            frame_type => EoeRepr::Other {
                frame_type,
                port,
                info: packet.info(),
                body,
            },
        })
    }

    /// The frame type of this message.
    pub fn frame_type(&self) -> EoeFrameType {
        match self {
            EoeRepr::Fragment(_) => EoeFrameType::Fragment,
            EoeRepr::Timestamp { .. } => EoeFrameType::TimestampResponse,
            EoeRepr::SetIpRequest { .. } => EoeFrameType::SetIpRequest,
            EoeRepr::SetIpResponse { .. } => EoeFrameType::SetIpResponse,
            EoeRepr::SetAddressFilterRequest { .. } => EoeFrameType::SetAddressFilterRequest,
            EoeRepr::SetAddressFilterResponse { .. } => EoeFrameType::SetAddressFilterResponse,
            EoeRepr::GetIpRequest { .. } => EoeFrameType::GetIpRequest,
            EoeRepr::GetIpResponse { .. } => EoeFrameType::GetIpResponse,
            EoeRepr::Other { frame_type, .. } => *frame_type,
        }
    }

    /// Bytes needed on the wire.
    pub fn buffer_len(&self) -> usize {
        HEADER_LEN
            + match self {
                EoeRepr::Fragment(f) => return f.buffer_len(),
                EoeRepr::Timestamp { .. } => TIMESTAMP_LEN,
                EoeRepr::SetIpRequest { params, .. } | EoeRepr::GetIpResponse { params, .. } => {
                    params.buffer_len()
                }
                EoeRepr::SetAddressFilterRequest { filter, .. } => filter.buffer_len(),
                EoeRepr::SetIpResponse { .. }
                | EoeRepr::SetAddressFilterResponse { .. }
                | EoeRepr::GetIpRequest { .. } => 0,
                EoeRepr::Other { body, .. } => body.len(),
            }
    }

    /// Writes the message into the start of `packet`'s buffer. Refuses (writing nothing) a
    /// port above 15, a frame number above 15, an `Other` with a frame type that has its own
    /// variant, and whatever the body emitters refuse.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, packet: &mut EoePacket<T>) -> Result<()> {
        let (port, info) = match *self {
            EoeRepr::Fragment(f) => return f.emit(packet),
            EoeRepr::Timestamp {
                port, frame_number, ..
            } => {
                if frame_number > MAX_FRAME_NUMBER {
                    return Err(WireError::Invalid {
                        what: "EoE timestamp",
                        reason: "frame number above 15",
                    });
                }
                (port, u16::from(frame_number) << 12)
            }
            EoeRepr::SetIpRequest { port, .. }
            | EoeRepr::SetAddressFilterRequest { port, .. }
            | EoeRepr::GetIpRequest { port } => (port, 0),
            EoeRepr::SetIpResponse { port, result }
            | EoeRepr::SetAddressFilterResponse { port, result }
            | EoeRepr::GetIpResponse { port, result, .. } => (port, u16::from(result)),
            EoeRepr::Other {
                frame_type,
                port,
                info,
                ..
            } => {
                if u8::from(frame_type) <= 7 || u8::from(frame_type) > 15 {
                    return Err(WireError::Invalid {
                        what: "EoE message",
                        reason: "raw message with a structured or out-of-range frame type",
                    });
                }
                (port, info)
            }
        };
        if port > MAX_PORT {
            return Err(WireError::Invalid {
                what: "EoE header",
                reason: "port above 15",
            });
        }
        room("EoE message", packet.as_bytes().as_ref(), self.buffer_len())?;
        // Body first: its emitters check their own values and write nothing on refusal.
        let body = packet.payload_mut();
        match *self {
            EoeRepr::Timestamp { timestamp, .. } => field::set_u32_le(body, 0, timestamp),
            EoeRepr::SetIpRequest { params, .. } | EoeRepr::GetIpResponse { params, .. } => {
                params.emit_body(body)?
            }
            EoeRepr::SetAddressFilterRequest { filter, .. } => filter.emit_body(body)?,
            EoeRepr::Other { body: raw, .. } => body[..raw.len()].copy_from_slice(raw),
            _ => {}
        }
        packet.set_type_port(self.frame_type(), port);
        packet.set_flags(false, false, false);
        packet.set_info(info);
        Ok(())
    }
}

impl fmt::Display for EoeRepr<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let port = match *self {
            EoeRepr::Fragment(frag) => return frag.fmt(f),
            EoeRepr::Timestamp {
                port,
                frame_number,
                timestamp,
            } => {
                write!(f, "EoE timestamp frame {frame_number} ts={timestamp}")?;
                port
            }
            EoeRepr::SetIpRequest { port, params } => {
                f.write_str("EoE set-IP")?;
                if params.flags() != 0 {
                    write!(f, " {params}")?;
                }
                port
            }
            EoeRepr::SetIpResponse { port, result }
            | EoeRepr::SetAddressFilterResponse { port, result } => {
                write!(
                    f,
                    "EoE {} {:#06x} {}",
                    self.frame_type().name(),
                    u16::from(result),
                    result.description()
                )?;
                port
            }
            EoeRepr::SetAddressFilterRequest { port, filter } => {
                write!(f, "EoE set-filter {filter}")?;
                port
            }
            EoeRepr::GetIpRequest { port } => {
                f.write_str("EoE get-IP")?;
                port
            }
            EoeRepr::GetIpResponse {
                port,
                result,
                params,
            } => {
                write!(
                    f,
                    "EoE get-IP resp {:#06x} {}",
                    u16::from(result),
                    result.description()
                )?;
                if params.flags() != 0 {
                    write!(f, " {params}")?;
                }
                port
            }
            EoeRepr::Other {
                frame_type,
                port,
                info,
                body,
            } => {
                write!(f, "EoE {}", frame_type.name())?;
                if let EoeFrameType::Unknown(raw) = frame_type {
                    write!(f, " {raw}")?;
                }
                write!(f, " info={info:#06x} ({} bytes)", body.len())?;
                port
            }
        };
        if port != 0 {
            write!(f, " port {port}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
