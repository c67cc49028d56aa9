//! [`StaticDictionary`]: an in-memory dictionary (BTreeMap of [`Object`]s) implementing
//! [`Dictionary`], with write hooks and per-object / per-entry download counters.

use core::fmt;
use core::ops::{Bound, RangeBounds};
use std::collections::BTreeMap;

use thiserror::Error;

use ecat_wire::coe::info::OdListType;
use ecat_wire::coe::{AbortCode, ObjectAccess};
use ecat_wire::register::AlState;

use super::access::{check_read, check_write};
use super::builder::DictionaryBuilder;
use super::check::check_value;
use super::dictionary::{DictEntryInfo, DictObjectInfo, Dictionary, EntryWrite};
use super::hooks::{HookSlot, WriteEvent, WriteHook};
use super::object::Object;
use super::value::{DecodeValue, EncodeValue, ValueError};

/// Why a local (owner-side) read or write of a [`StaticDictionary`] failed.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum OdError {
    /// The object or entry does not exist (the abort code says which).
    #[error("{0}")]
    Missing(AbortCode),
    /// The value does not suit the entry's type.
    #[error(transparent)]
    Value(#[from] ValueError),
    /// The value is longer than a variable-length entry holds.
    #[error("value of {len} bytes exceeds the entry's {max_len}")]
    TooLong {
        /// Bytes given.
        len: usize,
        /// Bytes the entry holds.
        max_len: usize,
    },
}

/// An object dictionary held in memory.
#[derive(Default)]
pub struct StaticDictionary {
    objects: BTreeMap<u16, Object>,
    hooks: Vec<HookSlot>,
    object_writes: BTreeMap<u16, u32>,
    entry_writes: BTreeMap<(u16, u8), u32>,
}

impl fmt::Debug for StaticDictionary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("StaticDictionary")
            .field("objects", &self.objects)
            .field("hooks", &self.hooks.len())
            .field("object_writes", &self.object_writes)
            .finish()
    }
}

impl StaticDictionary {
    /// An empty dictionary.
    pub fn new() -> Self {
        Self::default()
    }

    /// A builder for declaring objects in code.
    pub fn builder() -> DictionaryBuilder {
        DictionaryBuilder::new()
    }

    /// Adds or replaces an object. Entries are sorted by subindex; of duplicate subindices
    /// the first is kept.
    pub fn insert(&mut self, mut object: Object) -> Option<Object> {
        object.entries.sort_by_key(|e| e.subindex);
        object.entries.dedup_by_key(|e| e.subindex);
        self.objects.insert(object.index, object)
    }

    /// Removes an object.
    pub fn remove(&mut self, index: u16) -> Option<Object> {
        self.objects.remove(&index)
    }

    /// An object by index.
    pub fn get_object(&self, index: u16) -> Option<&Object> {
        self.objects.get(&index)
    }

    /// An object by index, mutably (changes bypass checks, hooks and counters).
    pub fn get_object_mut(&mut self, index: u16) -> Option<&mut Object> {
        self.objects.get_mut(&index)
    }

    /// All objects in index order.
    pub fn objects(&self) -> impl Iterator<Item = &Object> {
        self.objects.values()
    }

    /// The raw bytes of an entry's value.
    pub fn get_bytes(&self, index: u16, subindex: u8) -> Result<&[u8], OdError> {
        let object = self
            .objects
            .get(&index)
            .ok_or(OdError::Missing(AbortCode::ObjectDoesNotExist))?;
        let entry = object.entry(subindex).map_err(OdError::Missing)?;
        Ok(&entry.value)
    }

    /// An entry's value as a Rust type (no access check: this is the owner's view).
    pub fn get<T: DecodeValue>(&self, index: u16, subindex: u8) -> Result<T, OdError> {
        let object = self
            .objects
            .get(&index)
            .ok_or(OdError::Missing(AbortCode::ObjectDoesNotExist))?;
        let entry = object.entry(subindex).map_err(OdError::Missing)?;
        Ok(T::decode(entry.data_type, &entry.value)?)
    }

    /// Sets an entry's value from a Rust type. This is the owner's (device application's)
    /// write: it checks the type and length but not access rights or minimum/maximum, runs
    /// no hooks and counts no download.
    pub fn set<T: EncodeValue + ?Sized>(
        &mut self,
        index: u16,
        subindex: u8,
        value: &T,
    ) -> Result<(), OdError> {
        let entry = self
            .objects
            .get_mut(&index)
            .ok_or(OdError::Missing(AbortCode::ObjectDoesNotExist))?
            .entry_mut(subindex)
            .map_err(OdError::Missing)?;
        let bytes = value.encode(entry.data_type)?;
        let fits = if entry.is_variable_length() {
            bytes.len() <= entry.max_len
        } else {
            bytes.len() == entry.max_len
        };
        if !fits {
            return Err(OdError::TooLong {
                len: bytes.len(),
                max_len: entry.max_len,
            });
        }
        entry.value = bytes;
        Ok(())
    }

    /// Registers a hook for SDO downloads to objects in `indices` (see [`super::hooks`]).
    /// Hooks run in registration order; the first refusal wins.
    pub fn on_write(
        &mut self,
        indices: impl RangeBounds<u16>,
        hook: impl FnMut(&WriteEvent<'_>, &StaticDictionary) -> Result<(), AbortCode> + Send + 'static,
    ) {
        let first = match indices.start_bound() {
            Bound::Included(&i) => i,
            Bound::Excluded(&i) => i.saturating_add(1),
            Bound::Unbounded => 0,
        };
        let last = match indices.end_bound() {
            Bound::Included(&i) => i,
            Bound::Excluded(&i) => i.saturating_sub(1),
            Bound::Unbounded => u16::MAX,
        };
        let hook: WriteHook = Box::new(hook);
        self.hooks.push(HookSlot { first, last, hook });
    }

    /// Successful SDO downloads to an object (a complete-access download counts once).
    pub fn write_count(&self, index: u16) -> u32 {
        self.object_writes.get(&index).copied().unwrap_or(0)
    }

    /// Successful SDO downloads that wrote an entry (complete access counts every entry it
    /// wrote).
    pub fn entry_write_count(&self, index: u16, subindex: u8) -> u32 {
        self.entry_writes
            .get(&(index, subindex))
            .copied()
            .unwrap_or(0)
    }

    /// Sets every download counter back to zero.
    pub fn reset_write_counts(&mut self) {
        self.object_writes.clear();
        self.entry_writes.clear();
    }

    fn find(&self, index: u16) -> Result<&Object, AbortCode> {
        self.objects
            .get(&index)
            .ok_or(AbortCode::ObjectDoesNotExist)
    }

    /// Checks one entry write except the zero-count rule; returns nothing on success.
    fn check_entry(
        &self,
        index: u16,
        subindex: u8,
        data: &[u8],
        state: AlState,
    ) -> Result<(), AbortCode> {
        let entry = self.find(index)?.entry(subindex)?;
        check_write(entry.access, state)?;
        check_value(&entry.info(index), data)
    }

    /// Stores checked values, runs the hooks, and rolls back if one refuses.
    fn commit(
        &mut self,
        index: u16,
        writes: &[EntryWrite<'_>],
        complete_access: bool,
        state: AlState,
    ) -> Result<(), AbortCode> {
        let object = self
            .objects
            .get_mut(&index)
            .ok_or(AbortCode::ObjectDoesNotExist)?;
        let mut old = Vec::with_capacity(writes.len());
        for w in writes {
            let entry = object.entry_mut(w.subindex)?;
            old.push(std::mem::replace(&mut entry.value, w.data.to_vec()));
        }
        let subindices: Vec<u8> = writes.iter().map(|w| w.subindex).collect();
        let event = WriteEvent {
            index,
            subindices: &subindices,
            complete_access,
            state,
        };
        // Hooks get the whole dictionary by shared reference, so they are moved out while
        // they run.
        let mut hooks = std::mem::take(&mut self.hooks);
        let verdict = hooks
            .iter_mut()
            .filter(|slot| slot.watches(index))
            .try_for_each(|slot| (slot.hook)(&event, self));
        self.hooks = hooks;
        if let Err(code) = verdict {
            if let Some(object) = self.objects.get_mut(&index) {
                for (w, value) in writes.iter().zip(old) {
                    if let Ok(entry) = object.entry_mut(w.subindex) {
                        entry.value = value;
                    }
                }
            }
            return Err(code);
        }
        *self.object_writes.entry(index).or_default() += 1;
        for w in writes {
            *self.entry_writes.entry((index, w.subindex)).or_default() += 1;
        }
        Ok(())
    }
}

impl Dictionary for StaticDictionary {
    fn indices(&self, list: OdListType) -> Vec<u16> {
        let mask = match list {
            OdListType::All => 0,
            OdListType::RxPdoMappable => ObjectAccess::RXPDO_MAPPABLE,
            OdListType::TxPdoMappable => ObjectAccess::TXPDO_MAPPABLE,
            OdListType::Backup => ObjectAccess::BACKUP,
            OdListType::Settings => ObjectAccess::SETTINGS,
            OdListType::Lengths | OdListType::Unknown(_) => return Vec::new(),
        };
        self.objects
            .values()
            .filter(|o| mask == 0 || o.any_entry_has(mask))
            .map(|o| o.index)
            .collect()
    }

    fn object(&self, index: u16) -> Option<DictObjectInfo<'_>> {
        self.objects.get(&index).map(Object::info)
    }

    fn entry(&self, index: u16, subindex: u8) -> Result<DictEntryInfo<'_>, AbortCode> {
        Ok(self.find(index)?.entry(subindex)?.info(index))
    }

    fn read(
        &mut self,
        index: u16,
        subindex: u8,
        state: AlState,
        out: &mut Vec<u8>,
    ) -> Result<(), AbortCode> {
        let entry = self.find(index)?.entry(subindex)?;
        check_read(entry.access, state)?;
        out.extend_from_slice(&entry.value);
        Ok(())
    }

    fn write(
        &mut self,
        index: u16,
        subindex: u8,
        data: &[u8],
        state: AlState,
    ) -> Result<(), AbortCode> {
        self.check_entry(index, subindex, data, state)?;
        let object = self.find(index)?;
        // Strict PDO procedure (spec-notes §coe.pdo): mapping/assignment entries change only while the
        // object is switched off with SI0 = 0.
        if object.zero_count_to_write && subindex != 0 && object.count() != Some(0) {
            return Err(AbortCode::SubindexNotWritable);
        }
        self.commit(index, &[EntryWrite { subindex, data }], false, state)
    }

    /// Atomic: every entry is checked before any is stored, and a hook's refusal undoes
    /// all of them. A download that includes SI0 replaces the whole object, so the
    /// zero-count rule does not apply to it; one that starts at subindex 1 must find SI0 = 0
    /// on a guarded object.
    fn write_entries(
        &mut self,
        index: u16,
        writes: &[EntryWrite<'_>],
        state: AlState,
    ) -> Result<(), AbortCode> {
        for w in writes {
            self.check_entry(index, w.subindex, w.data, state)?;
        }
        let object = self.find(index)?;
        if object.zero_count_to_write
            && !writes.iter().any(|w| w.subindex == 0)
            && object.count() != Some(0)
        {
            return Err(AbortCode::SubindexNotWritable);
        }
        self.commit(index, writes, true, state)
    }
}
