//! The master's own identity objects (spec-notes §master-od): 0x1000, 0x1008, 0x1009, 0x100A, 0x1018.

use crate::od::DictionaryBuilder;
use crate::wire::coe::{DataType, ObjectAccess};

use super::text::fit;

/// Longest device name and version string the dictionary holds (their SDO Information bit
/// length is fixed, so clients see the same description whatever the text).
pub const IDENTITY_TEXT_LEN: usize = 64;

/// What the master reports about itself at 0x1000-0x1018.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MasterIdentity {
    /// 0x1000 device type. Default 0 (no device profile).
    pub device_type: u32,
    /// 0x1008 manufacturer device name. Default "ecatd".
    pub device_name: String,
    /// 0x1009 manufacturer hardware version. Default "" (software master).
    pub hardware_version: String,
    /// 0x100A manufacturer software version. Default this crate's version.
    pub software_version: String,
    /// 0x1018:01 vendor ID. Default 0 (none assigned by the ETG).
    pub vendor_id: u32,
    /// 0x1018:02 product code. Default 0.
    pub product_code: u32,
    /// 0x1018:03 revision number. Default the crate's major.minor as 0xMMMMmmmm.
    pub revision: u32,
    /// 0x1018:04 serial number. Default 0 (not used).
    pub serial: u32,
}

impl Default for MasterIdentity {
    fn default() -> MasterIdentity {
        let major: u32 = env!("CARGO_PKG_VERSION_MAJOR").parse().unwrap_or(0);
        let minor: u32 = env!("CARGO_PKG_VERSION_MINOR").parse().unwrap_or(0);
        MasterIdentity {
            device_type: 0,
            device_name: "ecatd".to_owned(),
            hardware_version: String::new(),
            software_version: env!("CARGO_PKG_VERSION").to_owned(),
            vendor_id: 0,
            product_code: 0,
            revision: (major << 16) | (minor & 0xFFFF),
            serial: 0,
        }
    }
}

/// Declares 0x1000-0x1018.
pub(crate) fn declare(b: DictionaryBuilder, id: &MasterIdentity) -> DictionaryBuilder {
    let ro = ObjectAccess::RO;
    b.var(
        0x1000,
        "Device type",
        DataType::Unsigned32,
        ro,
        id.device_type,
    )
    .string(
        0x1008,
        "Manufacturer device name",
        ro,
        fit(&id.device_name, IDENTITY_TEXT_LEN),
        IDENTITY_TEXT_LEN,
    )
    .string(
        0x1009,
        "Manufacturer hardware version",
        ro,
        fit(&id.hardware_version, IDENTITY_TEXT_LEN),
        IDENTITY_TEXT_LEN,
    )
    .string(
        0x100A,
        "Manufacturer software version",
        ro,
        fit(&id.software_version, IDENTITY_TEXT_LEN),
        IDENTITY_TEXT_LEN,
    )
    .record(0x1018, "Identity", |r| {
        r.data_type(DataType::Identity)
            .entry(1, "Vendor ID", DataType::Unsigned32, ro, id.vendor_id)
            .entry(2, "Product code", DataType::Unsigned32, ro, id.product_code)
            .entry(3, "Revision number", DataType::Unsigned32, ro, id.revision)
            .entry(4, "Serial number", DataType::Unsigned32, ro, id.serial)
    })
}
