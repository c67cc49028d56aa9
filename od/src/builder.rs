//! Declaring a dictionary in code.
//!
//! ```
//! use ecat_od::StaticDictionary;
//! use ecat_wire::coe::{DataType, ObjectAccess};
//!
//! let dict = StaticDictionary::builder()
//!     .var(0x6040, "Controlword", DataType::Unsigned16, ObjectAccess::RW, 0u16)
//!     .range(0u16, 0x00FFu16)
//!     .record(0x1018, "Identity", |r| {
//!         r.data_type(DataType::Identity)
//!             .entry(1, "Vendor ID", DataType::Unsigned32, ObjectAccess::RO, 2u32)
//!             .entry(2, "Product code", DataType::Unsigned32, ObjectAccess::RO, 0x07D4_3052u32)
//!     })
//!     .array(0x1C00, "Sync manager type", DataType::Unsigned8, ObjectAccess::RO, [1u8, 2, 3, 4])
//!     .build()
//!     .unwrap();
//! assert_eq!(dict.get::<u32>(0x1018, 1).unwrap(), 2);
//! assert_eq!(dict.get::<u8>(0x1018, 0).unwrap(), 2);
//! ```
//!
//! Mistakes (a value that does not fit its type, a duplicate index) do not panic: the
//! builder remembers the first one and [`DictionaryBuilder::build`] returns it.
//! `default_value`, `range` and `unit` apply to the entry declared last.

use std::collections::BTreeMap;

use thiserror::Error;

use ecat_wire::coe::{DataType, ObjectAccess, ObjectCode};

use super::object::{Entry, Object};
use super::static_dictionary::StaticDictionary;
use super::value::{EncodeValue, ValueError};

/// Why a declared dictionary is not valid.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("object 0x{index:04X}{}: {kind}", subindex.map(|s| format!(":{s:02X}")).unwrap_or_default())]
pub struct BuildError {
    /// The object.
    pub index: u16,
    /// The entry, when the problem is one entry's.
    pub subindex: Option<u8>,
    /// What is wrong.
    pub kind: BuildErrorKind,
}

/// What is wrong with a declaration.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum BuildErrorKind {
    /// A value does not suit its entry's type.
    #[error(transparent)]
    Value(#[from] ValueError),
    /// The index is declared twice.
    #[error("index declared twice")]
    DuplicateIndex,
    /// The subindex is declared twice, or 0 is declared in an ARRAY/RECORD (SI0 is made by
    /// the builder).
    #[error("subindex declared twice or reserved")]
    DuplicateSubindex,
    /// `default_value`, `range` or `unit` came before any entry.
    #[error("value detail given before any entry")]
    NoEntry,
    /// The SI0 value is above the highest declared subindex.
    #[error("number of entries above the highest subindex")]
    CountTooHigh,
}

fn fail(index: u16, subindex: Option<u8>, kind: impl Into<BuildErrorKind>) -> BuildError {
    BuildError {
        index,
        subindex,
        kind: kind.into(),
    }
}

/// Default value, range and unit of the last declared entry.
fn apply_detail(
    entry: Option<&mut Entry>,
    index: u16,
    detail: impl FnOnce(&mut Entry) -> Result<(), ValueError>,
) -> Result<(), BuildError> {
    let entry = entry.ok_or_else(|| fail(index, None, BuildErrorKind::NoEntry))?;
    let subindex = entry.subindex;
    detail(entry).map_err(|e| fail(index, Some(subindex), e))
}

/// Builds a [`StaticDictionary`].
#[derive(Debug, Default)]
pub struct DictionaryBuilder {
    objects: BTreeMap<u16, Object>,
    last: Option<u16>,
    error: Option<BuildError>,
}

impl DictionaryBuilder {
    /// An empty builder.
    pub fn new() -> Self {
        Self::default()
    }

    fn record_error(&mut self, e: BuildError) {
        self.error.get_or_insert(e);
    }

    /// Adds a finished object (refusing a duplicate index).
    pub fn object(mut self, object: Object) -> Self {
        let index = object.index;
        match self.objects.entry(index) {
            std::collections::btree_map::Entry::Occupied(_) => {
                self.record_error(fail(index, None, BuildErrorKind::DuplicateIndex));
            }
            std::collections::btree_map::Entry::Vacant(slot) => {
                slot.insert(object);
                self.last = Some(index);
            }
        }
        self
    }

    fn var_entry(self, index: u16, name: &str, entry: Result<Entry, ValueError>) -> Self {
        match entry {
            Ok(entry) => self.object(Object {
                index,
                name: name.to_string(),
                object_code: ObjectCode::Var,
                data_type: entry.data_type,
                entries: vec![entry],
                zero_count_to_write: false,
            }),
            Err(e) => {
                let mut s = self;
                s.record_error(fail(index, Some(0), e));
                s
            }
        }
    }

    /// A VAR object of a fixed-size type (or a variable-length one sized to `value`).
    pub fn var(
        self,
        index: u16,
        name: &str,
        data_type: DataType,
        access: ObjectAccess,
        value: impl EncodeValue,
    ) -> Self {
        let entry = Entry::new(0, name, data_type, access, value);
        self.var_entry(index, name, entry)
    }

    /// A VISIBLE_STRING VAR holding up to `max_len` bytes.
    pub fn string(
        self,
        index: u16,
        name: &str,
        access: ObjectAccess,
        text: &str,
        max_len: usize,
    ) -> Self {
        let entry = text.encode(DataType::VisibleString).map(|bytes| {
            Entry::with_capacity(0, name, DataType::VisibleString, access, bytes, max_len)
        });
        self.var_entry(index, name, entry)
    }

    /// A VAR of a variable-length type (OCTET_STRING, DOMAIN, UNICODE_STRING) holding up to
    /// `max_len` bytes; large DOMAINs (firmware, logs) are transferred segmented.
    pub fn bytes(
        self,
        index: u16,
        name: &str,
        data_type: DataType,
        access: ObjectAccess,
        value: Vec<u8>,
        max_len: usize,
    ) -> Self {
        let entry = Entry::with_capacity(0, name, data_type, access, value, max_len);
        self.var_entry(index, name, Ok(entry))
    }

    /// An ARRAY of `values`, subindices 1..=n, SI0 = n read-only.
    pub fn array<V: EncodeValue>(
        self,
        index: u16,
        name: &str,
        element_type: DataType,
        access: ObjectAccess,
        values: impl IntoIterator<Item = V>,
    ) -> Self {
        self.array_with(index, name, element_type, |mut a| {
            for (i, v) in values.into_iter().enumerate() {
                let sub = u8::try_from(i + 1).unwrap_or(u8::MAX);
                a = a.entry(sub, &format!("SubIndex {sub:03}"), element_type, access, v);
            }
            a
        })
    }

    /// An ARRAY declared entry by entry.
    pub fn array_with(
        self,
        index: u16,
        name: &str,
        element_type: DataType,
        declare: impl FnOnce(ObjectBuilder) -> ObjectBuilder,
    ) -> Self {
        let builder = ObjectBuilder::new(index, name, ObjectCode::Array, element_type);
        self.finish_object(declare(builder))
    }

    /// A RECORD declared entry by entry.
    pub fn record(
        self,
        index: u16,
        name: &str,
        declare: impl FnOnce(ObjectBuilder) -> ObjectBuilder,
    ) -> Self {
        let builder = ObjectBuilder::new(index, name, ObjectCode::Record, DataType::from(0));
        self.finish_object(declare(builder))
    }

    fn finish_object(mut self, builder: ObjectBuilder) -> Self {
        match builder.finish() {
            Ok(object) => self.object(object),
            Err(e) => {
                self.record_error(e);
                self
            }
        }
    }

    fn last_entry(&mut self) -> (u16, Option<&mut Entry>) {
        let index = self.last.unwrap_or(0);
        let entry = self
            .last
            .and_then(|i| self.objects.get_mut(&i))
            .and_then(|o| o.entries.last_mut());
        (index, entry)
    }

    fn detail(mut self, f: impl FnOnce(&mut Entry) -> Result<(), ValueError>) -> Self {
        let (index, entry) = self.last_entry();
        if let Err(e) = apply_detail(entry, index, f) {
            self.record_error(e);
        }
        self
    }

    /// Default value of the entry declared last (SDO Information value info bit 4).
    pub fn default_value(self, value: impl EncodeValue) -> Self {
        self.detail(|e| {
            e.default = Some(value.encode(e.data_type)?);
            Ok(())
        })
    }

    /// Minimum and maximum of the entry declared last; downloads outside abort with
    /// 0x06090032 / 0x06090031.
    pub fn range(self, min: impl EncodeValue, max: impl EncodeValue) -> Self {
        self.detail(|e| {
            e.minimum = Some(min.encode(e.data_type)?);
            e.maximum = Some(max.encode(e.data_type)?);
            Ok(())
        })
    }

    /// Unit type of the entry declared last (SDO Information value info bit 3).
    pub fn unit(self, unit: u32) -> Self {
        self.detail(|e| {
            e.unit = Some(unit);
            Ok(())
        })
    }

    /// The dictionary, or the first declaration mistake.
    pub fn build(self) -> Result<StaticDictionary, BuildError> {
        if let Some(e) = self.error {
            return Err(e);
        }
        let mut dict = StaticDictionary::new();
        for object in self.objects.into_values() {
            dict.insert(object);
        }
        Ok(dict)
    }
}

/// Declares the entries of an ARRAY or RECORD. SI0 (the number of entries, UNSIGNED8) is
/// made when the object is finished: its value is the highest subindex unless
/// [`ObjectBuilder::count`] says otherwise, it is read-only unless
/// [`ObjectBuilder::count_access`] says otherwise, and its maximum is the highest subindex.
#[derive(Debug)]
pub struct ObjectBuilder {
    index: u16,
    name: String,
    object_code: ObjectCode,
    data_type: DataType,
    entries: Vec<Entry>,
    count: Option<u8>,
    count_access: ObjectAccess,
    zero_count_to_write: bool,
    error: Option<BuildError>,
}

impl ObjectBuilder {
    fn new(index: u16, name: &str, object_code: ObjectCode, data_type: DataType) -> Self {
        ObjectBuilder {
            index,
            name: name.to_string(),
            object_code,
            data_type,
            entries: Vec::new(),
            count: None,
            count_access: ObjectAccess::RO,
            zero_count_to_write: false,
            error: None,
        }
    }

    fn push(mut self, subindex: u8, entry: Result<Entry, ValueError>) -> Self {
        let clash = subindex == 0 || self.entries.iter().any(|e| e.subindex == subindex);
        let result = match entry {
            Err(e) => Err(fail(self.index, Some(subindex), e)),
            Ok(_) if clash => Err(fail(
                self.index,
                Some(subindex),
                BuildErrorKind::DuplicateSubindex,
            )),
            Ok(entry) => Ok(entry),
        };
        match result {
            Ok(entry) => self.entries.push(entry),
            Err(e) => {
                self.error.get_or_insert(e);
            }
        }
        self
    }

    /// An entry of a fixed-size type.
    pub fn entry(
        self,
        subindex: u8,
        name: &str,
        data_type: DataType,
        access: ObjectAccess,
        value: impl EncodeValue,
    ) -> Self {
        let entry = Entry::new(subindex, name, data_type, access, value);
        self.push(subindex, entry)
    }

    /// A VISIBLE_STRING entry holding up to `max_len` bytes.
    pub fn string(
        self,
        subindex: u8,
        name: &str,
        access: ObjectAccess,
        text: &str,
        max_len: usize,
    ) -> Self {
        let entry = text.encode(DataType::VisibleString).map(|bytes| {
            Entry::with_capacity(
                subindex,
                name,
                DataType::VisibleString,
                access,
                bytes,
                max_len,
            )
        });
        self.push(subindex, entry)
    }

    /// An entry built by hand.
    pub fn raw(self, entry: Entry) -> Self {
        self.push(entry.subindex, Ok(entry))
    }

    /// The RECORD's data type (e.g. IDENTITY, PDO_MAPPING); ARRAYs have their element type.
    pub fn data_type(mut self, data_type: DataType) -> Self {
        self.data_type = data_type;
        self
    }

    /// The initial SI0 value (default: the highest subindex).
    pub fn count(mut self, count: u8) -> Self {
        self.count = Some(count);
        self
    }

    /// SI0's access (default read-only); e.g. writable in PREOP for PDO assignment.
    pub fn count_access(mut self, access: ObjectAccess) -> Self {
        self.count_access = access;
        self
    }

    /// Entries other than SI0 may only be written while SI0 = 0 (abort 0x06010003).
    pub fn zero_count_to_write(mut self) -> Self {
        self.zero_count_to_write = true;
        self
    }

    fn detail(mut self, f: impl FnOnce(&mut Entry) -> Result<(), ValueError>) -> Self {
        if let Err(e) = apply_detail(self.entries.last_mut(), self.index, f) {
            self.error.get_or_insert(e);
        }
        self
    }

    /// Default value of the entry declared last.
    pub fn default_value(self, value: impl EncodeValue) -> Self {
        self.detail(|e| {
            e.default = Some(value.encode(e.data_type)?);
            Ok(())
        })
    }

    /// Minimum and maximum of the entry declared last.
    pub fn range(self, min: impl EncodeValue, max: impl EncodeValue) -> Self {
        self.detail(|e| {
            e.minimum = Some(min.encode(e.data_type)?);
            e.maximum = Some(max.encode(e.data_type)?);
            Ok(())
        })
    }

    /// Unit type of the entry declared last.
    pub fn unit(self, unit: u32) -> Self {
        self.detail(|e| {
            e.unit = Some(unit);
            Ok(())
        })
    }

    fn finish(mut self) -> Result<Object, BuildError> {
        if let Some(e) = self.error {
            return Err(e);
        }
        self.entries.sort_by_key(|e| e.subindex);
        let max = self.entries.last().map_or(0, |e| e.subindex);
        let count = self.count.unwrap_or(max);
        if count > max {
            return Err(fail(self.index, Some(0), BuildErrorKind::CountTooHigh));
        }
        let si0 = Entry {
            minimum: Some(vec![0]),
            maximum: Some(vec![max]),
            ..Entry::new(
                0,
                "Number of entries",
                DataType::Unsigned8,
                self.count_access,
                count,
            )
            .map_err(|e| fail(self.index, Some(0), e))?
        };
        self.entries.insert(0, si0);
        Ok(Object {
            index: self.index,
            name: self.name,
            object_code: self.object_code,
            data_type: self.data_type,
            entries: self.entries,
            zero_count_to_write: self.zero_count_to_write,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::access::presets::RW_PREOP;

    #[test]
    fn mistakes_are_reported_not_panicked() {
        let err = DictionaryBuilder::new()
            .var(0x2000, "x", DataType::Unsigned8, ObjectAccess::RW, 300u16)
            .build()
            .unwrap_err();
        assert_eq!((err.index, err.subindex), (0x2000, Some(0)));
        assert!(matches!(
            err.kind,
            BuildErrorKind::Value(ValueError::OutOfRange { .. })
        ));
        assert_eq!(
            err.to_string(),
            "object 0x2000:00: UNSIGNED8: value 300 out of range"
        );

        let twice = DictionaryBuilder::new()
            .var(0x2000, "x", DataType::Unsigned8, ObjectAccess::RW, 1u8)
            .var(0x2000, "y", DataType::Unsigned8, ObjectAccess::RW, 1u8)
            .build()
            .unwrap_err();
        assert_eq!(twice.kind, BuildErrorKind::DuplicateIndex);

        let sub0 = DictionaryBuilder::new()
            .record(0x2001, "r", |r| {
                r.entry(0, "no", DataType::Unsigned8, ObjectAccess::RW, 1u8)
            })
            .build()
            .unwrap_err();
        assert_eq!(sub0.kind, BuildErrorKind::DuplicateSubindex);

        let count = DictionaryBuilder::new()
            .array_with(0x2002, "a", DataType::Unsigned8, |a| {
                a.entry(1, "e", DataType::Unsigned8, RW_PREOP, 0u8).count(2)
            })
            .build()
            .unwrap_err();
        assert_eq!(count.kind, BuildErrorKind::CountTooHigh);

        let early = DictionaryBuilder::new().unit(1).build().unwrap_err();
        assert_eq!(early.kind, BuildErrorKind::NoEntry);
    }

    #[test]
    fn declared_objects_have_their_shape() {
        let dict = DictionaryBuilder::new()
            .array(
                0x1C00,
                "SM types",
                DataType::Unsigned8,
                ObjectAccess::RO,
                [1u8, 2, 3, 4],
            )
            .string(0x1008, "Name", ObjectAccess::RO, "abc", 8)
            .record(0x2000, "R", |r| {
                r.entry(1, "a", DataType::Integer32, ObjectAccess::RW, -1i32)
                    .range(-5i32, 5i32)
                    .default_value(0i32)
                    .unit(7)
            })
            .build()
            .unwrap();
        let sm = dict.get_object(0x1C00).unwrap();
        assert_eq!(
            (sm.object_code, sm.max_subindex(), sm.count()),
            (ObjectCode::Array, 4, Some(4))
        );
        assert_eq!(sm.entries[0].access, ObjectAccess::RO);
        assert_eq!(dict.get::<u8>(0x1C00, 3).unwrap(), 3);
        let name = &dict.get_object(0x1008).unwrap().entries[0];
        assert_eq!(
            (name.bit_length, name.max_len, name.value.as_slice()),
            (64, 8, &b"abc"[..])
        );
        let e = &dict.get_object(0x2000).unwrap().entries[1];
        assert_eq!(e.minimum.as_deref(), Some(&(-5i32).to_le_bytes()[..]));
        assert_eq!(e.default.as_deref(), Some(&[0u8; 4][..]));
        assert_eq!(e.unit, Some(7));
        assert_eq!(dict.get::<i64>(0x2000, 1).unwrap(), -1);
    }
}
