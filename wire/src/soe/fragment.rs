//! Splitting a value into the fragments of an SoE write or read response.

use core::ops::Range;

use crate::error::{Result, WireError};

/// One fragment of an SoE write (or read response) sequence, from [`fragments`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SoeFragment {
    /// The bytes of the whole value this fragment carries.
    pub range: Range<usize>,
    /// `Some(n)`: not the last fragment (Incomplete = 1, bytes 2-3 = n fragments still to
    /// follow); `None`: the last fragment (Incomplete = 0, bytes 2-3 = the IDN).
    pub fragments_left: Option<u16>,
}

/// Iterator over the fragments of a value, see [`fragments`].
#[derive(Debug, Clone)]
pub struct SoeFragments {
    total: usize,
    capacity: usize,
    offset: usize,
    done: bool,
}

impl Iterator for SoeFragments {
    type Item = SoeFragment;

    fn next(&mut self) -> Option<SoeFragment> {
        if self.done {
            return None;
        }
        let remaining = self.total - self.offset;
        let start = self.offset;
        if remaining <= self.capacity {
            self.done = true;
            return Some(SoeFragment {
                range: start..self.total,
                fragments_left: None,
            });
        }
        // IgH: fragments_left = ceil(remaining / capacity) − 1; checked to fit in u16 by
        // `fragments`, since it only decreases.
        let left = remaining.div_ceil(self.capacity) - 1;
        self.offset += self.capacity;
        Some(SoeFragment {
            range: start..self.offset,
            fragments_left: Some(u16::try_from(left).unwrap_or(u16::MAX)),
        })
    }
}

/// Splits a value of `total_len` bytes into fragments of at most `capacity` bytes
/// (`capacity` = [`fragment_capacity`](super::fragment_capacity) of the receiver's mailbox) following IgH's rule
/// (ETG.1000.6, spec-notes §soe): every fragment but the last is full, Incomplete = 1 and carries
/// `ceil(remaining / capacity) − 1`; the last carries the IDN. A value that fits (including
/// an empty one) is a single last fragment.
///
/// Refuses a zero capacity for a non-empty value and more than 65 535 fragments-left.
pub fn fragments(total_len: usize, capacity: usize) -> Result<SoeFragments> {
    if capacity == 0 && total_len > 0 {
        return Err(WireError::Invalid {
            what: "SoE fragments",
            reason: "zero fragment capacity",
        });
    }
    if total_len > capacity && total_len.div_ceil(capacity) - 1 > usize::from(u16::MAX) {
        return Err(WireError::BadLength {
            what: "SoE fragments",
            declared: total_len,
            available: capacity.saturating_mul(usize::from(u16::MAX) + 1),
        });
    }
    Ok(SoeFragments {
        total: total_len,
        capacity,
        offset: 0,
        done: false,
    })
}
