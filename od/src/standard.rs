//! Standard communication-area objects (spec-notes §coe.objects, §coe.pdo): identity, device type and
//! names, PDO mapping and assignment, sync manager types — declared through the builder,
//! and read back for the process-data layout.

use ecat_wire::coe::{DataType, ObjectAccess};

use super::access::presets::RW_PREOP;
use super::builder::DictionaryBuilder;
use super::static_dictionary::StaticDictionary;

/// 0x1000 Device type.
pub const DEVICE_TYPE: u16 = 0x1000;
/// 0x1001 Error register.
pub const ERROR_REGISTER: u16 = 0x1001;
/// 0x1008 Manufacturer device name.
pub const DEVICE_NAME: u16 = 0x1008;
/// 0x1009 Manufacturer hardware version.
pub const HARDWARE_VERSION: u16 = 0x1009;
/// 0x100A Manufacturer software version.
pub const SOFTWARE_VERSION: u16 = 0x100A;
/// 0x1018 Identity.
pub const IDENTITY: u16 = 0x1018;
/// 0x1C00 Sync manager communication type.
pub const SM_TYPES: u16 = 0x1C00;
/// 0x1C12 SM2 (outputs) PDO assignment.
pub const RX_PDO_ASSIGN: u16 = 0x1C12;
/// 0x1C13 SM3 (inputs) PDO assignment.
pub const TX_PDO_ASSIGN: u16 = 0x1C13;

/// The four identity values of 0x1018 (also SII words 8-15); one type with the master's
/// slave snapshot.
pub use ecat_wire::identity::Identity;

/// One PDO mapping entry: `(index << 16) | (subindex << 8) | bit_length`; index 0 is a
/// gap of `bit_length` bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PdoEntry {
    /// Mapped object index (0 for padding).
    pub index: u16,
    /// Mapped subindex.
    pub subindex: u8,
    /// Bits taken in the PDO.
    pub bit_length: u8,
}

impl PdoEntry {
    /// A mapping entry.
    pub const fn new(index: u16, subindex: u8, bit_length: u8) -> Self {
        PdoEntry {
            index,
            subindex,
            bit_length,
        }
    }

    /// The UNSIGNED32 stored in 0x16xx/0x1Axx.
    pub const fn to_u32(self) -> u32 {
        ((self.index as u32) << 16) | ((self.subindex as u32) << 8) | self.bit_length as u32
    }

    /// Reads a stored mapping value.
    pub const fn from_u32(raw: u32) -> Self {
        PdoEntry {
            index: (raw >> 16) as u16,
            subindex: (raw >> 8) as u8,
            bit_length: raw as u8,
        }
    }
}

/// Sync manager communication type (0x1C00 entries).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum SmType {
    /// 0: unused.
    Unused = 0,
    /// 1: mailbox receive (master → slave).
    MailboxOut = 1,
    /// 2: mailbox send (slave → master).
    MailboxIn = 2,
    /// 3: process data outputs.
    Outputs = 3,
    /// 4: process data inputs.
    Inputs = 4,
}

impl DictionaryBuilder {
    /// 0x1000 Device type (profile number in the low word, e.g. 0x0192 = 402).
    pub fn device_type(self, value: u32) -> Self {
        self.var(
            DEVICE_TYPE,
            "Device type",
            DataType::Unsigned32,
            ObjectAccess::RO,
            value,
        )
    }

    /// 0x1001 Error register (the value emergencies carry), TxPDO-mappable.
    pub fn error_register(self, value: u8) -> Self {
        self.var(
            ERROR_REGISTER,
            "Error register",
            DataType::Unsigned8,
            ObjectAccess(ObjectAccess::RO.0 | ObjectAccess::TXPDO_MAPPABLE),
            value,
        )
    }

    /// 0x1008 Manufacturer device name.
    pub fn device_name(self, name: &str) -> Self {
        self.string(
            DEVICE_NAME,
            "Manufacturer device name",
            ObjectAccess::RO,
            name,
            name.len(),
        )
    }

    /// 0x1009 Manufacturer hardware version.
    pub fn hardware_version(self, version: &str) -> Self {
        self.string(
            HARDWARE_VERSION,
            "Manufacturer hardware version",
            ObjectAccess::RO,
            version,
            version.len(),
        )
    }

    /// 0x100A Manufacturer software version.
    pub fn software_version(self, version: &str) -> Self {
        self.string(
            SOFTWARE_VERSION,
            "Manufacturer software version",
            ObjectAccess::RO,
            version,
            version.len(),
        )
    }

    /// 0x1018 Identity: RECORD of type IDENTITY, SI0 = 4, all read-only.
    pub fn identity(self, id: Identity) -> Self {
        let u32_ro = |r: super::builder::ObjectBuilder, sub, name, v: u32| {
            r.entry(sub, name, DataType::Unsigned32, ObjectAccess::RO, v)
        };
        self.record(IDENTITY, "Identity", |r| {
            let r = r.data_type(DataType::Identity);
            let r = u32_ro(r, 1, "Vendor ID", id.vendor_id);
            let r = u32_ro(r, 2, "Product code", id.product_code);
            let r = u32_ro(r, 3, "Revision number", id.revision);
            u32_ro(r, 4, "Serial number", id.serial)
        })
    }

    /// A PDO mapping object (0x1600.. RxPDO, 0x1A00.. TxPDO) with room for `capacity`
    /// entries, `entries` mapped. SI0 and entries are writable in PREOP only, entries only
    /// while SI0 = 0 (ETG.1000.6, spec-notes §coe.pdo).
    pub fn pdo_mapping(self, index: u16, name: &str, entries: &[PdoEntry], capacity: u8) -> Self {
        let mapped = u8::try_from(entries.len()).unwrap_or(u8::MAX);
        let capacity = capacity.max(mapped);
        self.record(index, name, |mut r| {
            r = r
                .data_type(DataType::PdoMapping)
                .count(mapped)
                .count_access(RW_PREOP)
                .zero_count_to_write();
            for sub in 1..=capacity {
                let value = entries.get(usize::from(sub - 1)).map_or(0, |e| e.to_u32());
                r = r.entry(
                    sub,
                    &format!("SubIndex {sub:03}"),
                    DataType::Unsigned32,
                    RW_PREOP,
                    value,
                );
            }
            r
        })
    }

    /// A PDO assignment ARRAY of UNSIGNED16 (0x1C12 outputs, 0x1C13 inputs) with room for
    /// `capacity` PDOs, `pdos` assigned; writable in PREOP, entries only while SI0 = 0.
    pub fn pdo_assignment(self, index: u16, name: &str, pdos: &[u16], capacity: u8) -> Self {
        let assigned = u8::try_from(pdos.len()).unwrap_or(u8::MAX);
        let capacity = capacity.max(assigned);
        self.array_with(index, name, DataType::Unsigned16, |mut a| {
            a = a
                .count(assigned)
                .count_access(RW_PREOP)
                .zero_count_to_write();
            for sub in 1..=capacity {
                let value = pdos.get(usize::from(sub - 1)).copied().unwrap_or(0);
                a = a.entry(
                    sub,
                    &format!("SubIndex {sub:03}"),
                    DataType::Unsigned16,
                    RW_PREOP,
                    value,
                );
            }
            a
        })
    }

    /// 0x1C12 RxPDO assignment (SM2, outputs).
    pub fn rx_pdo_assign(self, pdos: &[u16], capacity: u8) -> Self {
        self.pdo_assignment(RX_PDO_ASSIGN, "RxPDO assign", pdos, capacity)
    }

    /// 0x1C13 TxPDO assignment (SM3, inputs).
    pub fn tx_pdo_assign(self, pdos: &[u16], capacity: u8) -> Self {
        self.pdo_assignment(TX_PDO_ASSIGN, "TxPDO assign", pdos, capacity)
    }

    /// 0x1C00 Sync manager communication types, one per SM, read-only.
    pub fn sm_types(self, types: &[SmType]) -> Self {
        self.array(
            SM_TYPES,
            "Sync manager type",
            DataType::Unsigned8,
            ObjectAccess::RO,
            types.iter().map(|&t| t as u8),
        )
    }
}

impl StaticDictionary {
    /// The PDOs currently assigned by 0x1C12/0x1C13 (the first SI0 entries).
    pub fn assigned_pdos(&self, assign_index: u16) -> Vec<u16> {
        let count = self
            .get_object(assign_index)
            .and_then(|o| o.count())
            .unwrap_or(0);
        (1..=count)
            .filter_map(|sub| self.get::<u16>(assign_index, sub).ok())
            .collect()
    }

    /// The entries a PDO mapping object currently maps (the first SI0 entries).
    pub fn mapped_entries(&self, pdo_index: u16) -> Vec<PdoEntry> {
        let count = self
            .get_object(pdo_index)
            .and_then(|o| o.count())
            .unwrap_or(0);
        (1..=count)
            .filter_map(|sub| self.get::<u32>(pdo_index, sub).ok())
            .map(PdoEntry::from_u32)
            .collect()
    }

    /// Bits of process data the assignment yields: the sum of the mapped bit lengths of
    /// every assigned PDO (round up to bytes for the SM length).
    pub fn process_data_bits(&self, assign_index: u16) -> u32 {
        self.assigned_pdos(assign_index)
            .into_iter()
            .flat_map(|pdo| self.mapped_entries(pdo))
            .map(|e| u32::from(e.bit_length))
            .sum()
    }
}
