//! SDO Information service (CoE service 8; ETG.1000.6 SDO Information, spec-notes §coe.info).
//!
//! ```text
//! mailbox data offset 0  u16  CoE header `00 80`
//!                     2  u8   bits 0-6 opcode, bit 7 incomplete (more fragments follow)
//!                     3  u8   reserved
//!                     4  u16  fragments left (after this one)
//!                     6  ...  service data
//! ```
//! A long response comes in several mailbox messages; the client concatenates their service
//! data. Each message parses on its own here.

pub mod entry;
pub mod object;
pub mod od_list;

use core::fmt;

use super::abort::AbortCode;
use super::display::Hex;
use super::header::{CoeFrame, CoeService, put_header};
use crate::error::{Result, WireError, need, room};
use crate::field::{self, Field, Rest};
use crate::macros::enum_with_unknown;

pub use entry::{EntryDescription, UNIT_TYPE_LEN, ValueInfo};
pub use object::ObjectDescription;
pub use od_list::{OdList, OdListType};

mod fields {
    use super::{Field, Rest};
    pub const OPCODE: usize = 2;
    pub const FRAGMENTS_LEFT: Field = 4..6;
    pub const DATA: Rest = 6..;
}

/// Bytes in front of the service data (CoE header + SDO Info header).
pub const SDO_INFO_HEADER_LEN: usize = fields::DATA.start;

const INCOMPLETE: u8 = 0x80;
const OPCODE_MASK: u8 = 0x7F;

enum_with_unknown! {
    /// SDO Information opcode (7 bits, ETG.1000.6, spec-notes §coe.info).
    pub enum SdoInfoOpcode(u8) {
        /// 1: Get OD List request.
        OdListRequest = 1,
        /// 2: Get OD List response.
        OdListResponse = 2,
        /// 3: Get Object Description request.
        ObjectDescriptionRequest = 3,
        /// 4: Get Object Description response.
        ObjectDescriptionResponse = 4,
        /// 5: Get Entry Description request.
        EntryDescriptionRequest = 5,
        /// 6: Get Entry Description response.
        EntryDescriptionResponse = 6,
        /// 7: SDO Info Error request (the server's error reply).
        Error = 7,
    }
}

impl SdoInfoOpcode {
    /// Short name used in Display.
    pub fn name(self) -> &'static str {
        match self {
            SdoInfoOpcode::OdListRequest => "OD list req",
            SdoInfoOpcode::OdListResponse => "OD list rsp",
            SdoInfoOpcode::ObjectDescriptionRequest => "object description req",
            SdoInfoOpcode::ObjectDescriptionResponse => "object description rsp",
            SdoInfoOpcode::EntryDescriptionRequest => "entry description req",
            SdoInfoOpcode::EntryDescriptionResponse => "entry description rsp",
            SdoInfoOpcode::Error => "error",
            SdoInfoOpcode::Unknown(_) => "unknown opcode",
        }
    }
}

/// A view of an SDO Information message (mailbox data, CoE header included).
#[derive(Debug, Clone)]
pub struct SdoInfoFrame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> SdoInfoFrame<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        SdoInfoFrame { buffer }
    }

    /// Wraps a buffer and checks that both headers are present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let f = Self::new_unchecked(buffer);
        f.check_len()?;
        Ok(f)
    }

    /// Checks that the CoE header and the 4-byte SDO Info header are present.
    pub fn check_len(&self) -> Result<()> {
        need("SDO Info header", self.buffer.as_ref(), SDO_INFO_HEADER_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// CoE service (8 for SDO Information).
    pub fn service(&self) -> CoeService {
        CoeFrame::new_unchecked(self.buffer.as_ref()).service()
    }

    /// The opcode (bits 0-6).
    pub fn opcode(&self) -> SdoInfoOpcode {
        SdoInfoOpcode::from(self.buffer.as_ref()[fields::OPCODE] & OPCODE_MASK)
    }

    /// More fragments follow (bit 7).
    pub fn incomplete(&self) -> bool {
        self.buffer.as_ref()[fields::OPCODE] & INCOMPLETE != 0
    }

    /// Number of fragments still to come after this one.
    pub fn fragments_left(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::FRAGMENTS_LEFT.start)
    }

    /// The service data.
    pub fn data(&self) -> &[u8] {
        &self.buffer.as_ref()[fields::DATA]
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> SdoInfoFrame<T> {
    /// Sets opcode (7 bits, masked) and the incomplete flag; clears the reserved byte.
    pub fn set_opcode(&mut self, opcode: SdoInfoOpcode, incomplete: bool) {
        let buf = self.buffer.as_mut();
        buf[fields::OPCODE] =
            (u8::from(opcode) & OPCODE_MASK) | if incomplete { INCOMPLETE } else { 0 };
        buf[fields::OPCODE + 1] = 0;
    }

    /// Sets the fragments-left count.
    pub fn set_fragments_left(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::FRAGMENTS_LEFT.start, value)
    }

    /// Mutable service data.
    pub fn data_mut(&mut self) -> &mut [u8] {
        &mut self.buffer.as_mut()[fields::DATA]
    }
}

impl<'a> SdoInfoFrame<&'a [u8]> {
    fn data_ref(&self) -> &'a [u8] {
        self.buffer.get(fields::DATA).unwrap_or(&[])
    }
}

/// The service data of an SDO Information message, by opcode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SdoInfoService<'a> {
    /// Get OD List request.
    OdListRequest {
        /// Which list.
        list_type: OdListType,
    },
    /// Get OD List response fragment (see [`OdList`] for the first-fragment rule).
    OdListResponse(OdList<'a>),
    /// Get Object Description request.
    ObjectDescriptionRequest {
        /// Object index.
        index: u16,
    },
    /// Get Object Description response.
    ObjectDescriptionResponse(ObjectDescription<'a>),
    /// Get Entry Description request.
    EntryDescriptionRequest {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Optional parts wanted.
        value_info: ValueInfo,
    },
    /// Get Entry Description response.
    EntryDescriptionResponse(EntryDescription<'a>),
    /// SDO Info Error: an abort code (ETG.1000.6, spec-notes §coe.abort table).
    Error {
        /// Why.
        code: AbortCode,
    },
    /// An opcode this version does not name; the data are kept.
    Other {
        /// The raw opcode (not 1..=7, at most 127).
        opcode: u8,
        /// The service data.
        data: &'a [u8],
    },
}

impl SdoInfoService<'_> {
    /// The opcode of this service.
    pub fn opcode(&self) -> SdoInfoOpcode {
        match self {
            SdoInfoService::OdListRequest { .. } => SdoInfoOpcode::OdListRequest,
            SdoInfoService::OdListResponse(_) => SdoInfoOpcode::OdListResponse,
            SdoInfoService::ObjectDescriptionRequest { .. } => {
                SdoInfoOpcode::ObjectDescriptionRequest
            }
            SdoInfoService::ObjectDescriptionResponse(_) => {
                SdoInfoOpcode::ObjectDescriptionResponse
            }
            SdoInfoService::EntryDescriptionRequest { .. } => {
                SdoInfoOpcode::EntryDescriptionRequest
            }
            SdoInfoService::EntryDescriptionResponse(_) => SdoInfoOpcode::EntryDescriptionResponse,
            SdoInfoService::Error { .. } => SdoInfoOpcode::Error,
            SdoInfoService::Other { opcode, .. } => SdoInfoOpcode::from(*opcode),
        }
    }
}

/// A parsed SDO Information message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SdoInfoRepr<'a> {
    /// More fragments follow.
    pub incomplete: bool,
    /// Fragments still to come after this one.
    pub fragments_left: u16,
    /// Opcode and service data.
    pub service: SdoInfoService<'a>,
}

impl<'a> SdoInfoRepr<'a> {
    /// Parses an SDO Information message (CoE service must be 8). Bytes after a fixed-size
    /// request or error are ignored.
    pub fn parse(frame: &SdoInfoFrame<&'a [u8]>) -> Result<Self> {
        const WHAT: &str = "SDO Info service data";
        frame.check_len()?;
        let service = frame.service();
        if service != CoeService::SdoInfo {
            return Err(WireError::UnknownType {
                what: "CoE service of an SDO Info message",
                value: u32::from(u8::from(service)),
            });
        }
        let data = frame.data_ref();
        let u16_at = |at: usize| field::u16_le(data, at);
        let service = match frame.opcode() {
            SdoInfoOpcode::OdListRequest => {
                need(WHAT, data, 2)?;
                SdoInfoService::OdListRequest {
                    list_type: OdListType::from(u16_at(0)),
                }
            }
            SdoInfoOpcode::OdListResponse => SdoInfoService::OdListResponse(OdList(data)),
            SdoInfoOpcode::ObjectDescriptionRequest => {
                need(WHAT, data, 2)?;
                SdoInfoService::ObjectDescriptionRequest { index: u16_at(0) }
            }
            SdoInfoOpcode::ObjectDescriptionResponse => {
                SdoInfoService::ObjectDescriptionResponse(ObjectDescription::parse(data)?)
            }
            SdoInfoOpcode::EntryDescriptionRequest => {
                need(WHAT, data, entry::ENTRY_REQUEST_LEN)?;
                SdoInfoService::EntryDescriptionRequest {
                    index: u16_at(0),
                    subindex: data[2],
                    value_info: ValueInfo(data[3]),
                }
            }
            SdoInfoOpcode::EntryDescriptionResponse => {
                SdoInfoService::EntryDescriptionResponse(EntryDescription::parse(data)?)
            }
            SdoInfoOpcode::Error => {
                need(WHAT, data, 4)?;
                SdoInfoService::Error {
                    code: AbortCode::from(field::u32_le(data, 0)),
                }
            }
            SdoInfoOpcode::Unknown(opcode) => SdoInfoService::Other { opcode, data },
        };
        Ok(SdoInfoRepr {
            incomplete: frame.incomplete(),
            fragments_left: frame.fragments_left(),
            service,
        })
    }

    fn data_len(&self) -> usize {
        match &self.service {
            SdoInfoService::OdListRequest { .. }
            | SdoInfoService::ObjectDescriptionRequest { .. } => 2,
            SdoInfoService::OdListResponse(list) => list.raw().len(),
            SdoInfoService::ObjectDescriptionResponse(o) => o.buffer_len(),
            SdoInfoService::EntryDescriptionRequest { .. } => entry::ENTRY_REQUEST_LEN,
            SdoInfoService::EntryDescriptionResponse(e) => e.buffer_len(),
            SdoInfoService::Error { .. } => 4,
            SdoInfoService::Other { data, .. } => data.len(),
        }
    }

    /// Mailbox length of the message (CoE header included).
    pub fn buffer_len(&self) -> usize {
        SDO_INFO_HEADER_LEN + self.data_len()
    }

    /// Writes the message. Refuses an `Other` opcode that is named (1..=7) or above 127, and
    /// an entry description whose optional values disagree with its value info.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, frame: &mut SdoInfoFrame<T>) -> Result<()> {
        match &self.service {
            SdoInfoService::Other { opcode, .. }
                if *opcode > OPCODE_MASK
                    || !matches!(SdoInfoOpcode::from(*opcode), SdoInfoOpcode::Unknown(_)) =>
            {
                return Err(WireError::Invalid {
                    what: "SDO Info message",
                    reason: "raw opcode is a named one or wider than 7 bits",
                });
            }
            SdoInfoService::EntryDescriptionResponse(e) => e.validate()?,
            _ => {}
        }
        let len = self.buffer_len();
        room("SDO Info message", frame.buffer.as_ref(), len)?;
        put_header(frame.buffer.as_mut(), CoeService::SdoInfo);
        frame.set_opcode(self.service.opcode(), self.incomplete);
        frame.set_fragments_left(self.fragments_left);
        let out = &mut frame.data_mut()[..len - SDO_INFO_HEADER_LEN];
        match &self.service {
            SdoInfoService::OdListRequest { list_type } => {
                field::set_u16_le(out, 0, (*list_type).into())
            }
            SdoInfoService::OdListResponse(list) => out.copy_from_slice(list.raw()),
            SdoInfoService::ObjectDescriptionRequest { index } => field::set_u16_le(out, 0, *index),
            SdoInfoService::ObjectDescriptionResponse(o) => o.write(out),
            SdoInfoService::EntryDescriptionRequest {
                index,
                subindex,
                value_info,
            } => {
                field::set_u16_le(out, 0, *index);
                out[2] = *subindex;
                out[3] = value_info.0;
            }
            SdoInfoService::EntryDescriptionResponse(e) => e.write(out),
            SdoInfoService::Error { code } => field::set_u32_le(out, 0, (*code).into()),
            SdoInfoService::Other { data, .. } => out.copy_from_slice(data),
        }
        Ok(())
    }
}

impl fmt::Display for SdoInfoRepr<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "CoE SDO-Info {}", self.service.opcode().name())?;
        if self.incomplete {
            write!(f, " (incomplete, {} left)", self.fragments_left)?;
        } else if self.fragments_left != 0 {
            write!(f, " ({} left)", self.fragments_left)?;
        }
        match &self.service {
            SdoInfoService::OdListRequest { list_type } => write!(f, " {list_type}"),
            SdoInfoService::OdListResponse(list) => write!(f, " {list}"),
            SdoInfoService::ObjectDescriptionRequest { index } => write!(f, " 0x{index:04X}"),
            SdoInfoService::ObjectDescriptionResponse(o) => write!(f, " {o}"),
            SdoInfoService::EntryDescriptionRequest {
                index,
                subindex,
                value_info,
            } => write!(
                f,
                " 0x{index:04X}:{subindex:02X} value info {:#04x}",
                value_info.0
            ),
            SdoInfoService::EntryDescriptionResponse(e) => write!(f, " {e}"),
            SdoInfoService::Error { code } => write!(f, " {code}"),
            SdoInfoService::Other { opcode, data } => {
                write!(f, " {opcode:#04x} {} bytes {}", data.len(), Hex(data))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::entry::tests::{arb_entry_parts, entry_from};
    use super::*;
    use crate::coe::data_type::{DataType, ObjectAccess, ObjectCode};
    use crate::mailbox::{HEADER_LEN, Mailbox};
    use proptest::prelude::*;

    fn parse(data: &[u8]) -> Result<SdoInfoRepr<'_>> {
        SdoInfoRepr::parse(&SdoInfoFrame::new_checked(data)?)
    }

    fn emit(repr: &SdoInfoRepr<'_>) -> Vec<u8> {
        let mut out = vec![0xa5u8; repr.buffer_len()];
        repr.emit(&mut SdoInfoFrame::new_unchecked(&mut out[..]))
            .unwrap();
        out
    }

    #[test]
    fn c10_od_list_request() {
        let bytes = [
            0x08, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00,
        ];
        let mbx = Mailbox::new_checked(&bytes[..]).unwrap();
        let repr = parse(mbx.data()).unwrap();
        let expected = SdoInfoRepr {
            incomplete: false,
            fragments_left: 0,
            service: SdoInfoService::OdListRequest {
                list_type: OdListType::All,
            },
        };
        assert_eq!(repr, expected);
        assert_eq!(emit(&expected), bytes[HEADER_LEN..]);
        assert_eq!(repr.to_string(), "CoE SDO-Info OD list req all objects");
    }

    #[test]
    fn c10_od_list_fragments() {
        // First fragment: opcode 2 | incomplete, 2 left, list type 1, 0x1000 0x1008 0x1009.
        let first = [
            0x00, 0x80, 0x82, 0x00, 0x02, 0x00, 0x01, 0x00, 0x00, 0x10, 0x08, 0x10, 0x09, 0x10,
        ];
        let repr = parse(&first).unwrap();
        assert!(repr.incomplete);
        assert_eq!(repr.fragments_left, 2);
        let SdoInfoService::OdListResponse(list) = repr.service else {
            panic!("not an OD list response: {repr:?}")
        };
        let (ty, indices) = list.first_fragment().unwrap();
        assert_eq!(ty, OdListType::All);
        assert_eq!(
            indices.words().collect::<Vec<_>>(),
            [0x1000, 0x1008, 0x1009]
        );
        assert_eq!(emit(&repr), first);
        assert_eq!(
            repr.to_string(),
            "CoE SDO-Info OD list rsp (incomplete, 2 left) 4 words [0x0001 0x1000 0x1008 0x1009]"
        );

        // Continuation fragments: indices only; the last has incomplete = 0, 0 left.
        let second = [0x00, 0x80, 0x82, 0x00, 0x01, 0x00, 0x18, 0x10, 0x00, 0x16];
        let third = [0x00, 0x80, 0x02, 0x00, 0x00, 0x00, 0x12, 0x1c];
        let r2 = parse(&second).unwrap();
        let r3 = parse(&third).unwrap();
        assert_eq!((r2.incomplete, r2.fragments_left), (true, 1));
        assert_eq!((r3.incomplete, r3.fragments_left), (false, 0));
        assert_eq!(
            r2.service,
            SdoInfoService::OdListResponse(OdList(&[0x18, 0x10, 0x00, 0x16]))
        );
        assert_eq!(
            r3.service,
            SdoInfoService::OdListResponse(OdList(&[0x12, 0x1c]))
        );
        assert_eq!(emit(&r2), second);
        assert_eq!(emit(&r3), third);
    }

    #[test]
    fn object_description() {
        // By hand: 0x1018, IDENTITY (0x0023), max sub 4, RECORD (9), "Identity".
        let req = [0x00, 0x80, 0x03, 0x00, 0x00, 0x00, 0x18, 0x10];
        let r = parse(&req).unwrap();
        assert_eq!(
            r.service,
            SdoInfoService::ObjectDescriptionRequest { index: 0x1018 }
        );
        assert_eq!(emit(&r), req);
        let rsp = [
            0x00, 0x80, 0x04, 0x00, 0x00, 0x00, 0x18, 0x10, 0x23, 0x00, 0x04, 0x09, b'I', b'd',
            b'e', b'n', b't', b'i', b't', b'y',
        ];
        let r = parse(&rsp).unwrap();
        assert_eq!(
            r.service,
            SdoInfoService::ObjectDescriptionResponse(ObjectDescription {
                index: 0x1018,
                data_type: DataType::Identity,
                max_subindex: 4,
                object_code: ObjectCode::Record,
                name: b"Identity",
            })
        );
        assert_eq!(emit(&r), rsp);
        assert_eq!(
            r.to_string(),
            "CoE SDO-Info object description rsp 0x1018 RECORD IDENTITY max sub 4 \"Identity\""
        );
    }

    #[test]
    fn entry_description() {
        // Request 0x1018:01, value info 0.
        let req = [0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x18, 0x10, 0x01, 0x00];
        let r = parse(&req).unwrap();
        assert_eq!(
            r.service,
            SdoInfoService::EntryDescriptionRequest {
                index: 0x1018,
                subindex: 1,
                value_info: ValueInfo(0)
            }
        );
        assert_eq!(emit(&r), req);
        // Response: UNSIGNED32, 32 bits, RO, "Vendor ID".
        let rsp = [
            0x00, 0x80, 0x06, 0x00, 0x00, 0x00, 0x18, 0x10, 0x01, 0x00, 0x07, 0x00, 0x20, 0x00,
            0x07, 0x00, b'V', b'e', b'n', b'd', b'o', b'r', b' ', b'I', b'D',
        ];
        let r = parse(&rsp).unwrap();
        let SdoInfoService::EntryDescriptionResponse(e) = r.service else {
            panic!("{r:?}")
        };
        assert_eq!(
            (e.data_type, e.bit_length, e.access),
            (DataType::Unsigned32, 32, ObjectAccess::RO)
        );
        assert_eq!(e.description, b"Vendor ID");
        assert_eq!(emit(&r), rsp);
        assert_eq!(
            r.to_string(),
            "CoE SDO-Info entry description rsp 0x1018:01 UNSIGNED32 32 bits RO (0x0007) \"Vendor ID\""
        );
    }

    #[test]
    fn info_error() {
        let bytes = [0x00, 0x80, 0x07, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x06];
        let r = parse(&bytes).unwrap();
        assert_eq!(
            r.service,
            SdoInfoService::Error {
                code: AbortCode::ObjectDoesNotExist
            }
        );
        assert_eq!(emit(&r), bytes);
        assert_eq!(
            r.to_string(),
            "CoE SDO-Info error 0x06020000 Object does not exist in the object dictionary"
        );
    }

    #[test]
    fn errors() {
        assert!(SdoInfoFrame::new_checked(&[0x00, 0x80, 0x01, 0x00, 0x00][..]).is_err());
        // Wrong service.
        assert!(matches!(
            parse(&[0x00, 0x30, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00]),
            Err(WireError::UnknownType { value: 3, .. })
        ));
        // Truncated request data.
        assert!(parse(&[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01]).is_err());
        assert!(parse(&[0x00, 0x80, 0x04, 0x00, 0x00, 0x00, 0x18, 0x10, 0x23]).is_err());
        assert!(parse(&[0x00, 0x80, 0x07, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02]).is_err());
        // Unknown opcodes are data; a named raw opcode is refused on emit.
        let r = parse(&[0x00, 0x80, 0x09, 0x00, 0x00, 0x00, 0xaa]).unwrap();
        assert_eq!(
            r.service,
            SdoInfoService::Other {
                opcode: 9,
                data: &[0xaa]
            }
        );
        let mut out = [0u8; 8];
        for opcode in [1u8, 0x80] {
            let bad = SdoInfoRepr {
                incomplete: false,
                fragments_left: 0,
                service: SdoInfoService::Other { opcode, data: &[] },
            };
            assert!(
                bad.emit(&mut SdoInfoFrame::new_unchecked(&mut out[..]))
                    .is_err()
            );
        }
        assert_eq!(out, [0u8; 8]);
        // Entry description whose default value is missing although value info asks for it.
        let bad = SdoInfoRepr {
            incomplete: false,
            fragments_left: 0,
            service: SdoInfoService::EntryDescriptionResponse(EntryDescription {
                index: 0,
                subindex: 0,
                value_info: ValueInfo(ValueInfo::DEFAULT),
                data_type: DataType::Unsigned8,
                bit_length: 8,
                access: ObjectAccess::RO,
                unit_type: None,
                default: None,
                minimum: None,
                maximum: None,
                description: b"",
            }),
        };
        let mut out = [0u8; 32];
        assert!(
            bad.emit(&mut SdoInfoFrame::new_unchecked(&mut out[..]))
                .is_err()
        );
        assert_eq!(out, [0u8; 32]);
    }

    proptest! {
        #[test]
        fn round_trip(
            which in 0u8..8,
            incomplete in any::<bool>(),
            fragments_left in any::<u16>(),
            a in any::<u16>(),
            b in any::<u16>(),
            c in any::<u8>(),
            d in any::<u8>(),
            code in any::<u32>(),
            other_opcode in 8u8..128,
            bytes in proptest::collection::vec(any::<u8>(), 0..30),
            (i, s, vi, dt, bits, acc, unit, values, desc) in arb_entry_parts(),
        ) {
            let service = match which {
                0 => SdoInfoService::OdListRequest { list_type: OdListType::from(a) },
                1 => SdoInfoService::OdListResponse(OdList(&bytes)),
                2 => SdoInfoService::ObjectDescriptionRequest { index: a },
                3 => SdoInfoService::ObjectDescriptionResponse(ObjectDescription {
                    index: a, data_type: DataType::from(b), max_subindex: c,
                    object_code: ObjectCode::from(d), name: &bytes,
                }),
                4 => SdoInfoService::EntryDescriptionRequest {
                    index: a, subindex: c, value_info: ValueInfo(d),
                },
                5 => SdoInfoService::EntryDescriptionResponse(
                    entry_from((i, s, vi, dt, bits, acc, unit), &values, &desc)),
                6 => SdoInfoService::Error { code: AbortCode::from(code) },
                _ => SdoInfoService::Other { opcode: other_opcode, data: &bytes },
            };
            let repr = SdoInfoRepr { incomplete, fragments_left, service };
            let out = emit(&repr);
            prop_assert_eq!(parse(&out).unwrap(), repr);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
            if let Ok(frame) = SdoInfoFrame::new_checked(&bytes[..]) {
                let _ = (frame.opcode(), frame.incomplete(), frame.fragments_left(), frame.data());
                if let Ok(r) = SdoInfoRepr::parse(&frame) {
                    let _ = r.to_string();
                }
            }
        }
    }
}
