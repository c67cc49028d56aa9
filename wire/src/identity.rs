//! A device's identity: vendor, product, revision and serial number, as the SII holds them
//! in words 0x08–0x0F (ETG.2010) and the CoE identity object 0x1018 in subindices 1–4
//! (ETG.1000.6). One type for the master's slave snapshot and for object dictionaries.

/// Vendor, product, revision and serial number.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Identity {
    /// Vendor ID (SII word 0x08, 0x1018:01).
    pub vendor_id: u32,
    /// Product code (SII word 0x0A, 0x1018:02).
    pub product_code: u32,
    /// Revision number (SII word 0x0C, 0x1018:03).
    pub revision: u32,
    /// Serial number (SII word 0x0E, 0x1018:04; 0 if unused).
    pub serial: u32,
}
