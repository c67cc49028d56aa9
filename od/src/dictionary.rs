//! The interface the SDO server works against.
//!
//! [`Dictionary`] is deliberately small: list, describe, read, write. The simulator backs it
//! with a [`super::StaticDictionary`]; the master's ETG.1510 dictionary can compute values
//! when they are read. Everything the server derives (complete access, SDO Information,
//! segmentation) it builds from these calls, so each dictionary gets it for free.

use std::borrow::Cow;

use ecat_wire::coe::info::OdListType;
use ecat_wire::coe::{AbortCode, DataType, ObjectAccess, ObjectCode};
use ecat_wire::register::AlState;

use super::value::{bytes_for_bits, is_variable_length};

/// What SDO Information's Get Object Description reports about an object.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DictObjectInfo<'a> {
    /// Object index.
    pub index: u16,
    /// Object name.
    pub name: Cow<'a, str>,
    /// VAR, ARRAY or RECORD.
    pub object_code: ObjectCode,
    /// Type of a VAR, of the elements of an ARRAY, or of a RECORD (e.g. IDENTITY).
    pub data_type: DataType,
    /// Highest subindex the object declares (its capacity, not the current SI0 value).
    pub max_subindex: u8,
}

impl DictObjectInfo<'_> {
    /// Whether subindex 0 holds the number of entries (ARRAY and RECORD).
    pub fn has_count(&self) -> bool {
        matches!(self.object_code, ObjectCode::Array | ObjectCode::Record)
    }
}

/// What SDO Information's Get Entry Description reports about an entry, plus the byte
/// capacity the server needs to bound transfers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DictEntryInfo<'a> {
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
    /// Entry name.
    pub name: Cow<'a, str>,
    /// Data type.
    pub data_type: DataType,
    /// Size in bits (for strings and DOMAIN: the maximum, capped at 0xFFFF).
    pub bit_length: u16,
    /// Most bytes the value may have (the exact size for fixed-size types).
    pub max_len: usize,
    /// Access and mapping flags.
    pub access: ObjectAccess,
    /// Unit type (ETG.1004 / CiA 303-2 encoding), if declared.
    pub unit: Option<u32>,
    /// Default value bytes, if declared.
    pub default: Option<Cow<'a, [u8]>>,
    /// Minimum value bytes, if declared.
    pub minimum: Option<Cow<'a, [u8]>>,
    /// Maximum value bytes, if declared.
    pub maximum: Option<Cow<'a, [u8]>>,
}

impl DictEntryInfo<'_> {
    /// Whether the value has a variable length (strings, DOMAIN).
    pub fn is_variable_length(&self) -> bool {
        is_variable_length(self.data_type)
    }

    /// Bytes a fixed-size value has: ⌈bit length / 8⌉.
    pub fn fixed_len(&self) -> usize {
        bytes_for_bits(self.bit_length)
    }
}

/// One entry of a complete-access download, already cut out of the packed data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EntryWrite<'a> {
    /// Subindex.
    pub subindex: u8,
    /// The new value bytes.
    pub data: &'a [u8],
}

/// An object dictionary as the SDO server sees it.
///
/// Conventions for the abort codes (spec-notes §coe.abort, §master-od): unknown index 0x06020000; subindex
/// above the highest declared one 0x06090011; a gap below it 0x08000020. Reads and writes
/// check access for `state` (see [`super::access`]).
pub trait Dictionary {
    /// Indices of the objects in `list` (1 = all, 2 = RxPDO-mappable, 3 = TxPDO-mappable,
    /// 4 = backup, 5 = settings), ascending. List 0 and unknown lists give nothing: the
    /// server builds list 0 from the others.
    fn indices(&self, list: OdListType) -> Vec<u16>;

    /// Describes an object; `None` if it does not exist.
    fn object(&self, index: u16) -> Option<DictObjectInfo<'_>>;

    /// Describes an entry, or says why it does not exist.
    fn entry(&self, index: u16, subindex: u8) -> Result<DictEntryInfo<'_>, AbortCode>;

    /// Appends the current value of an entry to `out`.
    fn read(
        &mut self,
        index: u16,
        subindex: u8,
        state: AlState,
        out: &mut Vec<u8>,
    ) -> Result<(), AbortCode>;

    /// Writes one entry (one SDO download): checks access in `state`, the length against
    /// the type, the value against minimum/maximum, then stores it.
    fn write(
        &mut self,
        index: u16,
        subindex: u8,
        data: &[u8],
        state: AlState,
    ) -> Result<(), AbortCode>;

    /// Writes several entries of one object as one download (complete access). `writes`
    /// are in ascending subindex order; read-only entries have already been left out by
    /// the server. Either all entries are stored or none.
    ///
    /// The default writes entry by entry in the order of the PDO procedure (spec-notes §coe.pdo):
    /// SI0 = 0 first, then the entries, then SI0, so dictionaries that refuse entry writes
    /// while SI0 ≠ 0 accept it; it is not atomic. Dictionaries that can do better override
    /// it.
    fn write_entries(
        &mut self,
        index: u16,
        writes: &[EntryWrite<'_>],
        state: AlState,
    ) -> Result<(), AbortCode> {
        let count = writes.iter().find(|w| w.subindex == 0);
        if count.is_some() {
            self.write(index, 0, &[0], state)?;
        }
        for w in writes.iter().filter(|w| w.subindex != 0) {
            self.write(index, w.subindex, w.data, state)?;
        }
        if let Some(count) = count {
            self.write(index, 0, count.data, state)?;
        }
        Ok(())
    }
}
