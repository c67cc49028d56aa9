//! The dictionary model: objects and their entries, values stored as CoE bytes.

use std::borrow::Cow;

use ecat_wire::coe::{AbortCode, DataType, ObjectAccess, ObjectCode};

use super::dictionary::{DictEntryInfo, DictObjectInfo};
use super::value::{EncodeValue, ValueError, bytes_for_bits, is_variable_length};

/// One entry (subindex) of an object.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entry {
    /// Subindex.
    pub subindex: u8,
    /// Name (SDO Information entry description).
    pub name: String,
    /// Data type.
    pub data_type: DataType,
    /// Size in bits as SDO Information reports it (for strings and DOMAIN the maximum,
    /// capped at 0xFFFF bits).
    pub bit_length: u16,
    /// Most bytes the value may hold; for fixed-size types exactly ⌈bit_length / 8⌉.
    pub max_len: usize,
    /// Access per state, PDO mapping, backup and settings flags.
    pub access: ObjectAccess,
    /// The current value, little-endian CoE bytes.
    pub value: Vec<u8>,
    /// Default value (SDO Information value info bit 4).
    pub default: Option<Vec<u8>>,
    /// Smallest value a download may write.
    pub minimum: Option<Vec<u8>>,
    /// Largest value a download may write.
    pub maximum: Option<Vec<u8>>,
    /// Unit type (SDO Information value info bit 3).
    pub unit: Option<u32>,
}

impl Entry {
    /// An entry of a fixed-size type (integers, reals, BOOLEAN, BITn), its bit length
    /// taken from the type.
    pub fn new(
        subindex: u8,
        name: impl Into<String>,
        data_type: DataType,
        access: ObjectAccess,
        value: impl EncodeValue,
    ) -> Result<Entry, ValueError> {
        let value = value.encode(data_type)?;
        if is_variable_length(data_type) {
            let max_len = value.len();
            return Ok(Self::with_capacity(
                subindex, name, data_type, access, value, max_len,
            ));
        }
        let bit_length = data_type
            .bit_size()
            .unwrap_or_else(|| (value.len() * 8).min(usize::from(u16::MAX)) as u16);
        Ok(Entry {
            subindex,
            name: name.into(),
            data_type,
            bit_length,
            max_len: bytes_for_bits(bit_length),
            access,
            value,
            default: None,
            minimum: None,
            maximum: None,
            unit: None,
        })
    }

    /// A variable-length entry (string, DOMAIN) holding up to `max_len` bytes; the value
    /// is cut to `max_len`.
    pub fn with_capacity(
        subindex: u8,
        name: impl Into<String>,
        data_type: DataType,
        access: ObjectAccess,
        mut value: Vec<u8>,
        max_len: usize,
    ) -> Entry {
        value.truncate(max_len);
        Entry {
            subindex,
            name: name.into(),
            data_type,
            // SDO Information has 16 bits for the length; larger DOMAINs report the cap.
            bit_length: max_len.saturating_mul(8).min(usize::from(u16::MAX)) as u16,
            max_len,
            access,
            value,
            default: None,
            minimum: None,
            maximum: None,
            unit: None,
        }
    }

    /// Whether the value has a variable length.
    pub fn is_variable_length(&self) -> bool {
        is_variable_length(self.data_type)
    }

    /// The description the server and SDO Information use.
    pub fn info(&self, index: u16) -> DictEntryInfo<'_> {
        DictEntryInfo {
            index,
            subindex: self.subindex,
            name: Cow::Borrowed(&self.name),
            data_type: self.data_type,
            bit_length: self.bit_length,
            max_len: self.max_len,
            access: self.access,
            unit: self.unit,
            default: self.default.as_deref().map(Cow::Borrowed),
            minimum: self.minimum.as_deref().map(Cow::Borrowed),
            maximum: self.maximum.as_deref().map(Cow::Borrowed),
        }
    }
}

/// One object: a VAR (a single entry at subindex 0), or an ARRAY/RECORD whose subindex 0
/// holds the number of entries (u8) followed by the entries.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Object {
    /// Index.
    pub index: u16,
    /// Name (SDO Information object description).
    pub name: String,
    /// VAR, ARRAY or RECORD.
    pub object_code: ObjectCode,
    /// Type of the VAR, of the ARRAY's elements, or of the RECORD (0 if it has none).
    pub data_type: DataType,
    /// Entries in ascending subindex order; subindices may have gaps.
    pub entries: Vec<Entry>,
    /// Entries other than SI0 may only be written while SI0 is 0 (PDO mapping and
    /// assignment, ETG.1000.6, spec-notes §coe.pdo); otherwise abort 0x06010003.
    pub zero_count_to_write: bool,
}

impl Object {
    /// Highest declared subindex (the capacity of an ARRAY/RECORD, 0 for a VAR).
    pub fn max_subindex(&self) -> u8 {
        self.entries.last().map_or(0, |e| e.subindex)
    }

    /// Whether subindex 0 holds the number of entries.
    pub fn has_count(&self) -> bool {
        matches!(self.object_code, ObjectCode::Array | ObjectCode::Record)
    }

    /// The current SI0 value of an ARRAY/RECORD (`None` for a VAR).
    pub fn count(&self) -> Option<u8> {
        if !self.has_count() {
            return None;
        }
        self.entries
            .first()
            .filter(|e| e.subindex == 0)
            .and_then(|e| e.value.first().copied())
    }

    /// Position of a subindex in `entries`, or the abort code for a missing one: 0x06090011
    /// above the highest subindex, 0x08000020 for a gap below it.
    fn position(&self, subindex: u8) -> Result<usize, AbortCode> {
        self.entries
            .binary_search_by_key(&subindex, |e| e.subindex)
            .map_err(|_| {
                if subindex > self.max_subindex() {
                    AbortCode::SubindexDoesNotExist
                } else {
                    AbortCode::TransferFailed
                }
            })
    }

    /// The entry at `subindex`, or why there is none.
    pub fn entry(&self, subindex: u8) -> Result<&Entry, AbortCode> {
        self.position(subindex).map(|i| &self.entries[i])
    }

    /// The entry at `subindex`, mutably.
    pub fn entry_mut(&mut self, subindex: u8) -> Result<&mut Entry, AbortCode> {
        self.position(subindex).map(move |i| &mut self.entries[i])
    }

    /// The description the server and SDO Information use.
    pub fn info(&self) -> DictObjectInfo<'_> {
        DictObjectInfo {
            index: self.index,
            name: Cow::Borrowed(&self.name),
            object_code: self.object_code,
            data_type: self.data_type,
            max_subindex: self.max_subindex(),
        }
    }

    /// Whether any entry has all bits of `mask` in its access word (OD lists 2-5).
    pub fn any_entry_has(&self, mask: u16) -> bool {
        self.entries.iter().any(|e| e.access.contains(mask))
    }
}
