//! Write hooks: how the owner of a [`super::StaticDictionary`] observes and vetoes SDO
//! downloads.
//!
//! A hook runs after a download has passed every check and its values are in place, with
//! the whole dictionary in view, so it can validate the new state as a whole (a PDO mapping
//! that does not fit, an assignment naming a missing PDO) and recompute what depends on it
//! (process-data sizes). Returning an abort code rolls the values back and sends that code
//! to the client. Values set locally by the owner ([`super::StaticDictionary::set`]) do
//! not run hooks.

use ecat_wire::coe::AbortCode;
use ecat_wire::register::AlState;

use super::static_dictionary::StaticDictionary;

/// One SDO download, as a hook sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WriteEvent<'a> {
    /// Object index.
    pub index: u16,
    /// Subindices written, ascending (one unless `complete_access`).
    pub subindices: &'a [u8],
    /// Whether the download used complete access.
    pub complete_access: bool,
    /// The AL state the download happened in.
    pub state: AlState,
}

/// A write hook: `Ok` accepts the download, `Err(code)` undoes it and aborts with `code`.
pub type WriteHook =
    Box<dyn FnMut(&WriteEvent<'_>, &StaticDictionary) -> Result<(), AbortCode> + Send>;

/// A hook and the index range it watches.
pub(crate) struct HookSlot {
    pub(crate) first: u16,
    pub(crate) last: u16,
    pub(crate) hook: WriteHook,
}

impl HookSlot {
    pub(crate) fn watches(&self, index: u16) -> bool {
        (self.first..=self.last).contains(&index)
    }
}
