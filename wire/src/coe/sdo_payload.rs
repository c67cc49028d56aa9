//! The data of an SDO initiate frame (spec-notes §coe.sdo): expedited value, normal transfer
//! with complete size, or normal transfer without size — shared by the initiate download
//! request and the initiate upload response, which have the same command-bit layout.

use core::fmt;

use super::display::Hex;
use super::sdo::{SDO_DATA_FIELD_OFFSET, SDO_INITIATE_LEN, SdoFrame, cmd};
use crate::error::{Result, WireError, need};

/// The data of an initiate download request or initiate upload response.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SdoPayload<'a> {
    /// Expedited: 1 to 4 bytes in the data field (emitted with size indicated).
    Expedited(&'a [u8]),
    /// Normal transfer with size indicated: the complete size of the object and the part of
    /// the data carried in this frame (the rest follows in segments).
    Normal {
        /// Size of the whole transfer in bytes.
        complete_size: u32,
        /// Data in this frame (at most `complete_size` bytes).
        data: &'a [u8],
    },
    /// Normal transfer without size indication (command bits 0-1 clear): data only.
    SizeUnspecified {
        /// Data in this frame (never empty: an empty one reads as a tolerated expedited).
        data: &'a [u8],
    },
}

impl<'a> SdoPayload<'a> {
    /// Decodes the payload of a checked initiate frame (command bits 0-3 and the data).
    pub(crate) fn decode(what: &'static str, frame: &SdoFrame<&'a [u8]>) -> Result<Self> {
        let bytes = frame.bytes();
        let command = frame.command();
        let data_field = frame.data_field_ref();
        let expedited = command & cmd::EXPEDITED != 0;
        let sized = command & cmd::SIZE_INDICATED != 0;
        match (expedited, sized) {
            (true, true) => {
                let unused = usize::from((command >> cmd::EXPEDITED_UNUSED_SHIFT) & 0x03);
                let n = 4 - unused;
                need(what, bytes, SDO_DATA_FIELD_OFFSET + n)?;
                Ok(SdoPayload::Expedited(data_field.get(..n).unwrap_or(&[])))
            }
            // Expedited without size: the whole 4-byte field (ETG.1000.6, spec-notes §coe.sdo).
            (true, false) => {
                need(what, bytes, SDO_INITIATE_LEN)?;
                Ok(SdoPayload::Expedited(data_field))
            }
            (false, true) => {
                need(what, bytes, SDO_INITIATE_LEN)?;
                let complete_size = frame.data_field_u32().unwrap_or(0);
                let data = frame.extra_ref();
                if data.len() as u64 > u64::from(complete_size) {
                    return Err(WireError::Invalid {
                        what,
                        reason: "more data than the complete size",
                    });
                }
                Ok(SdoPayload::Normal {
                    complete_size,
                    data,
                })
            }
            (false, false) => {
                if bytes.len() <= SDO_INITIATE_LEN {
                    // Sample-client style 0x20 with the value in the data field: expedited,
                    // size from the bytes present.
                    need(what, bytes, SDO_DATA_FIELD_OFFSET + 1)?;
                    Ok(SdoPayload::Expedited(data_field))
                } else {
                    Ok(SdoPayload::SizeUnspecified {
                        data: frame.extra_ref(),
                    })
                }
            }
        }
    }

    /// Frame length (mailbox length) of an initiate frame carrying this payload.
    pub fn frame_len(&self) -> usize {
        match self {
            SdoPayload::Expedited(_) => SDO_INITIATE_LEN,
            SdoPayload::Normal { data, .. } | SdoPayload::SizeUnspecified { data } => {
                SDO_INITIATE_LEN + data.len()
            }
        }
    }

    /// Checks the values emit would write.
    pub(crate) fn validate(&self, what: &'static str) -> Result<()> {
        match self {
            SdoPayload::Expedited(value) if value.is_empty() || value.len() > 4 => {
                Err(WireError::Invalid {
                    what,
                    reason: "expedited value must have 1 to 4 bytes",
                })
            }
            SdoPayload::Normal {
                complete_size,
                data,
            } if data.len() as u64 > u64::from(*complete_size) => Err(WireError::Invalid {
                what,
                reason: "more data than the complete size",
            }),
            SdoPayload::SizeUnspecified { data: [] } => Err(WireError::Invalid {
                what,
                reason: "a transfer without size indication needs data",
            }),
            _ => Ok(()),
        }
    }

    /// Command bits 0-3 for this payload.
    pub(crate) fn command_bits(&self) -> u8 {
        match self {
            SdoPayload::Expedited(value) => {
                let unused = 4u8.saturating_sub(value.len() as u8);
                cmd::EXPEDITED | cmd::SIZE_INDICATED | (unused << cmd::EXPEDITED_UNUSED_SHIFT)
            }
            SdoPayload::Normal { .. } => cmd::SIZE_INDICATED,
            SdoPayload::SizeUnspecified { .. } => 0,
        }
    }

    /// The 4-byte data field and the further data.
    pub(crate) fn field_and_data(&self) -> ([u8; 4], &'a [u8]) {
        match *self {
            SdoPayload::Expedited(value) => {
                let mut f = [0u8; 4];
                let n = value.len().min(4);
                f[..n].copy_from_slice(&value[..n]);
                (f, &[])
            }
            SdoPayload::Normal {
                complete_size,
                data,
            } => (complete_size.to_le_bytes(), data),
            SdoPayload::SizeUnspecified { data } => ([0; 4], data),
        }
    }
}

impl fmt::Display for SdoPayload<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SdoPayload::Expedited(value) => {
                write!(f, "expedited {} bytes {}", value.len(), Hex(value))
            }
            SdoPayload::Normal {
                complete_size,
                data,
            } => write!(
                f,
                "normal size {complete_size}, {} bytes {}",
                data.len(),
                Hex(data)
            ),
            SdoPayload::SizeUnspecified { data } => {
                write!(f, "size unspecified, {} bytes {}", data.len(), Hex(data))
            }
        }
    }
}
