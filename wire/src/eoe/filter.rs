//! The body of a Set address filter request (type 4), ETG.1000.6, spec-notes §eoe — best effort.
//!
//! ```text
//! u16 options: bits 0-3 MAC filter count, bits 4-5 MAC filter mask count, bit 7 no
//!              broadcasts; bits 6, 8-15 reserved
//! 16 × 6 bytes MAC filters, 4 × 6 bytes filter masks
//! ```
//!
//! **Uncertain** (spec-notes §eoe): the only source is Wireshark's struct, itself marked "may not
//! be specified correctly"; it is unknown whether the options field is 2 or 4 bytes and
//! whether unused slots are sent. We emit Wireshark's fixed layout (2 + 96 + 24 = 122 bytes)
//! and parse either that (body ≥ 122 bytes: all slots read, so unused slots round-trip) or a
//! packed layout with only the counted filters and masks (other slots zero).

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field;

mod options {
    pub const FILTER_COUNT_MASK: u16 = 0x000F;
    pub const MASK_COUNT_SHIFT: u32 = 4;
    pub const MASK_COUNT_MASK: u16 = 0x3;
    pub const NO_BROADCASTS: u16 = 0x0080;
}

/// Size of the options field.
pub const OPTIONS_LEN: usize = 2;
/// Number of MAC filter slots.
pub const FILTER_SLOTS: usize = 16;
/// Number of mask slots.
pub const MASK_SLOTS: usize = 4;
/// Size of the fixed layout.
pub const FIXED_LEN: usize = OPTIONS_LEN + 6 * (FILTER_SLOTS + MASK_SLOTS);

/// A Set address filter request body.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct AddressFilter {
    /// Number of valid MAC filters, 0..=15 (4 bits).
    pub filter_count: u8,
    /// Number of valid masks, 0..=3 (2 bits).
    pub mask_count: u8,
    /// Do not forward broadcasts.
    pub no_broadcasts: bool,
    /// MAC filter slots.
    pub filters: [[u8; 6]; FILTER_SLOTS],
    /// Mask slots.
    pub masks: [[u8; 6]; MASK_SLOTS],
    /// Written (and found) in the packed layout: only the counted filters, then the counted
    /// masks. The master sends it to a slave whose mailbox cannot hold the fixed layout
    /// (a 128-byte mailbox holds 122 bytes of EoE, 4 of them its header); spec-notes §eoe.
    pub packed: bool,
}

fn mac_at(body: &[u8], at: usize) -> [u8; 6] {
    let mut mac = [0u8; 6];
    mac.copy_from_slice(&body[at..at + 6]);
    mac
}

impl AddressFilter {
    /// Parses the body after the EoE header (see the module docs for the layouts).
    /// Reserved option bits are ignored.
    pub fn parse_body(body: &[u8]) -> Result<Self> {
        need("EoE address filter", body, OPTIONS_LEN)?;
        let opts = field::u16_le(body, 0);
        let filter_count = (opts & options::FILTER_COUNT_MASK) as u8;
        let mask_count = ((opts >> options::MASK_COUNT_SHIFT) & options::MASK_COUNT_MASK) as u8;
        let mut filter = AddressFilter {
            filter_count,
            mask_count,
            no_broadcasts: opts & options::NO_BROADCASTS != 0,
            packed: body.len() < FIXED_LEN,
            ..AddressFilter::default()
        };
        let (filters, masks, mask_start) = if body.len() >= FIXED_LEN {
            (FILTER_SLOTS, MASK_SLOTS, OPTIONS_LEN + 6 * FILTER_SLOTS)
        } else {
            let f = usize::from(filter_count);
            let m = usize::from(mask_count);
            need("EoE address filter", body, OPTIONS_LEN + 6 * (f + m))?;
            (f, m, OPTIONS_LEN + 6 * f)
        };
        for (i, slot) in filter.filters.iter_mut().take(filters).enumerate() {
            *slot = mac_at(body, OPTIONS_LEN + 6 * i);
        }
        for (i, slot) in filter.masks.iter_mut().take(masks).enumerate() {
            *slot = mac_at(body, mask_start + 6 * i);
        }
        Ok(filter)
    }

    /// Bytes of the body: the fixed layout's, or the packed one's for the counts.
    pub const fn buffer_len(&self) -> usize {
        if self.packed {
            OPTIONS_LEN + 6 * (self.filter_count as usize + self.mask_count as usize)
        } else {
            FIXED_LEN
        }
    }

    /// Writes the fixed or the packed layout; refuses counts wider than their bits
    /// (writing nothing).
    pub fn emit_body(&self, body: &mut [u8]) -> Result<()> {
        if u16::from(self.filter_count) > options::FILTER_COUNT_MASK
            || u16::from(self.mask_count) > options::MASK_COUNT_MASK
        {
            return Err(WireError::Invalid {
                what: "EoE address filter",
                reason: "filter count above 15 or mask count above 3",
            });
        }
        room("EoE address filter", body, self.buffer_len())?;
        let mut opts = u16::from(self.filter_count)
            | (u16::from(self.mask_count) << options::MASK_COUNT_SHIFT);
        if self.no_broadcasts {
            opts |= options::NO_BROADCASTS;
        }
        field::set_u16_le(body, 0, opts);
        let (filters, masks) = if self.packed {
            (
                &self.filters[..usize::from(self.filter_count)],
                &self.masks[..usize::from(self.mask_count)],
            )
        } else {
            (&self.filters[..], &self.masks[..])
        };
        for (i, mac) in filters.iter().chain(masks.iter()).enumerate() {
            let at = OPTIONS_LEN + 6 * i;
            body[at..at + 6].copy_from_slice(mac);
        }
        Ok(())
    }
}

impl fmt::Display for AddressFilter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "filters={} masks={}", self.filter_count, self.mask_count)?;
        if self.no_broadcasts {
            f.write_str(" no-broadcasts")?;
        }
        Ok(())
    }
}
