//! The IDNs every simulated drive starts with: a small servo drive's parameter set, enough
//! for a master's start-up (cycle time, AT/MDT configuration lists, operation mode) and for
//! exercising every element and error path.

use ecat_wire::soe::SoeDataType;

use super::idn::IdnEntry;

/// S-0-0017, "IDN list of all operation data": kept up to date by the service.
pub const IDN_LIST_OF_ALL: u16 = 17;

/// S-0-0030, "Manufacturer version": a text long enough to need fragments in small mailboxes.
pub const MANUFACTURER_VERSION: u16 = 30;

/// The text of S-0-0030.
pub const MANUFACTURER_VERSION_TEXT: &str =
    "ecatd simulator, SoE servo drive emulation, firmware 1.0.0";

/// The default parameter set of one drive, as (IDN, entry) pairs.
pub fn default_idns() -> Vec<(u16, IdnEntry)> {
    let i32_bytes = |v: i32| v.to_le_bytes().to_vec();
    let u16_bytes = |v: u16| v.to_le_bytes().to_vec();
    vec![
        (
            1,
            IdnEntry::u16("NC cycle time (TNcyc)", SoeDataType::Unsigned, 1000)
                .with_unit("us")
                .with_limits(u16_bytes(125), u16_bytes(65000))
                .with_default(u16_bytes(1000))
                .protected_in(false, true, true),
        ),
        (
            11,
            IdnEntry::u16("Class 1 diagnostic", SoeDataType::Binary, 0).read_only(),
        ),
        (
            15,
            IdnEntry::u16("Telegram type parameter", SoeDataType::Unsigned, 7)
                .with_limits(u16_bytes(0), u16_bytes(7))
                .protected_in(false, true, true),
        ),
        (
            16,
            IdnEntry::idn_list("Configuration list of AT", &[51, 40], 16)
                .protected_in(false, true, true),
        ),
        (
            IDN_LIST_OF_ALL,
            IdnEntry::idn_list("IDN-list of all operation data", &[], 0).read_only(),
        ),
        (
            24,
            IdnEntry::idn_list("Configuration list of MDT", &[47, 36], 16)
                .protected_in(false, true, true),
        ),
        (
            MANUFACTURER_VERSION,
            IdnEntry::text("Manufacturer version", MANUFACTURER_VERSION_TEXT, 64).read_only(),
        ),
        (
            32,
            IdnEntry::u16("Primary operation mode", SoeDataType::Hex, 0x0002)
                .with_default(u16_bytes(0x0002)),
        ),
        (
            36,
            IdnEntry::i32("Velocity command value", 0)
                .with_unit("rpm")
                .with_limits(i32_bytes(-1_000_000), i32_bytes(1_000_000)),
        ),
        (
            40,
            IdnEntry::i32("Velocity feedback value 1", 0)
                .with_unit("rpm")
                .read_only(),
        ),
        (
            47,
            IdnEntry::i32("Position command value", 0).with_unit("incr"),
        ),
        (
            51,
            IdnEntry::i32("Position feedback value 1", 0)
                .with_unit("incr")
                .read_only(),
        ),
        (
            91,
            IdnEntry::u32("Bipolar velocity limit value", 3_000_000)
                .with_unit("rpm")
                .with_limits(
                    0u32.to_le_bytes().to_vec(),
                    5_000_000u32.to_le_bytes().to_vec(),
                )
                .with_default(3_000_000u32.to_le_bytes().to_vec()),
        ),
    ]
}
