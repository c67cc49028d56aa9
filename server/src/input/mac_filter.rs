//! The EoE address filter as callers write it: MAC addresses as text (ETG.1000.6, Set
//! address filter; spec-notes §eoe on its layout).

use serde::Deserialize;
use utoipa::ToSchema;

use master_core::wire::eoe::AddressFilter;
use master_core::wire::eoe::filter::{FILTER_SLOTS, MASK_SLOTS};

use super::ip::parse_mac;
use crate::error::ApiError;

/// The most MAC filters a request carries (a 4-bit count).
pub const MAX_FILTERS: usize = 15;
/// The most masks a request carries (a 2-bit count).
pub const MAX_MASKS: usize = 3;

/// Which frames the slave passes to its device: those to one of `macs` (none: every
/// unicast), broadcasts unless `no_broadcasts`; `masks` as the slave applies them.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct MacFilterView {
    /// MAC addresses (`02:00:00:00:aa:01`), at most 15.
    #[serde(default)]
    pub macs: Vec<String>,
    /// Filter masks, at most 3.
    #[serde(default)]
    pub masks: Vec<String>,
    /// Do not pass broadcasts.
    #[serde(default)]
    pub no_broadcasts: bool,
}

/// The request body for `view`, or the field that is wrong.
pub fn to_filter(view: &MacFilterView) -> Result<AddressFilter, ApiError> {
    if view.macs.len() > MAX_FILTERS.min(FILTER_SLOTS) {
        return Err(ApiError::invalid_field(
            "macs",
            format!("at most {MAX_FILTERS} MAC filters, not {}", view.macs.len()),
        ));
    }
    if view.masks.len() > MAX_MASKS.min(MASK_SLOTS) {
        return Err(ApiError::invalid_field(
            "masks",
            format!("at most {MAX_MASKS} masks, not {}", view.masks.len()),
        ));
    }
    let mut filter = AddressFilter {
        filter_count: view.macs.len() as u8,
        mask_count: view.masks.len() as u8,
        no_broadcasts: view.no_broadcasts,
        ..AddressFilter::default()
    };
    for (slot, text) in filter.filters.iter_mut().zip(&view.macs) {
        *slot = parse_mac(text).map_err(|err| ApiError::invalid_field("macs", err))?;
    }
    for (slot, text) in filter.masks.iter_mut().zip(&view.masks) {
        *slot = parse_mac(text).map_err(|err| ApiError::invalid_field("masks", err))?;
    }
    Ok(filter)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn macs_fill_the_counted_slots_and_bad_ones_name_their_field() {
        let filter = to_filter(&MacFilterView {
            macs: vec!["02:45:43:53:00:00".into()],
            masks: vec![],
            no_broadcasts: true,
        })
        .unwrap();
        assert_eq!(filter.filter_count, 1);
        assert_eq!(filter.filters[0], [0x02, 0x45, 0x43, 0x53, 0, 0]);
        assert!(filter.no_broadcasts);
        let bad = to_filter(&MacFilterView {
            macs: vec!["02:45:43".into()],
            ..MacFilterView::default()
        })
        .unwrap_err();
        assert_eq!(bad.field, Some("macs"));
        let many = to_filter(&MacFilterView {
            macs: vec!["02:00:00:00:00:01".into(); 16],
            ..MacFilterView::default()
        })
        .unwrap_err();
        assert_eq!(many.field, Some("macs"));
    }
}
