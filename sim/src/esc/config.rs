//! Static configuration of an emulated ESC: what the information block reports, how much
//! process RAM it has, and how its distributed clock behaves on the simulated time base.

use ecat_wire::register::{EscFeatures, PortType};

/// Identity and capabilities of an emulated ESC (spec-notes §esc.info), fixed for its lifetime.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EscConfig {
    /// ESC type, register 0x0000.
    pub esc_type: u8,
    /// ESC revision, register 0x0001.
    pub revision: u8,
    /// ESC build, register 0x0002.
    pub build: u16,
    /// Number of FMMUs, register 0x0004 (at most 16).
    pub fmmu_count: u8,
    /// Number of SyncManagers, register 0x0005 (at most 16).
    pub sm_count: u8,
    /// Process RAM in bytes, starting at 0x1000. Rounded down to whole KiB and capped at
    /// 60 KiB (the 64 KiB address space minus the register area); register 0x0006 reports
    /// it in KiB.
    pub ram_size: usize,
    /// Physical port types, register 0x0007.
    pub ports: [PortType; 4],
    /// Feature bits, register 0x0008. Bit 2 (DC) switches the clock emulation on.
    pub features: EscFeatures,
    /// EEPROM reads return 8 bytes (0x0502 bit 6) instead of 4.
    pub eeprom_read_8_bytes: bool,
    /// Distributed-clock behaviour.
    pub dc: DcConfig,
}

/// How an emulated ESC's local clock runs against the simulated time base (spec-notes §dc).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DcConfig {
    /// One-way delay in ns between the device before this slave (the master or the previous
    /// slave) and this slave's port 0, including that device's forwarding. Symmetric: the
    /// returning frame takes as long. A master measuring propagation delays (spec-notes §dc) finds
    /// exactly this value per hop.
    pub hop_delay_ns: u32,
    /// Local time at power-on in ns. Different values per slave give a master's offset
    /// compensation (ETG.1000.4, spec-notes §dc) something to do.
    pub clock_start_ns: u64,
    /// Drift of the local clock in parts per billion against the time base (positive:
    /// the local clock runs fast).
    pub drift_ppb: i32,
}

/// Default ESC type: 0x04, an IP core (as KickCAT's emulator reports); masters treat the
/// type as information only.
const DEFAULT_TYPE: u8 = 0x04;
/// Features of the default ESC: DC, 64-bit DC, enhanced MII link detection, separate FCS
/// error handling, enhanced DC SYNC activation (KickCAT's emulator value 0x01CC); bit 0 = 0
/// means bit-granular FMMUs, bits 9/10 = 0 mean LRW and xRW are supported.
const DEFAULT_FEATURES: u16 = 0x01CC;
/// Largest process RAM an ESC can have: 0x1000..=0xFFFF.
pub const MAX_RAM_SIZE: usize = 0xF000;

impl Default for DcConfig {
    /// 150 ns per hop (a typical EBUS terminal), clock starting at 0, no drift.
    fn default() -> Self {
        DcConfig {
            hop_delay_ns: 150,
            clock_start_ns: 0,
            drift_ppb: 0,
        }
    }
}

impl Default for EscConfig {
    /// An IP-core ESC with 8 FMMUs, 8 SyncManagers, 8 KiB RAM, two MII ports and 64-bit DC.
    fn default() -> Self {
        EscConfig {
            esc_type: DEFAULT_TYPE,
            revision: 0x01,
            build: 0x0001,
            fmmu_count: 8,
            sm_count: 8,
            ram_size: 8 * 1024,
            ports: [
                PortType::Mii,
                PortType::Mii,
                PortType::NotImplemented,
                PortType::NotImplemented,
            ],
            features: EscFeatures(DEFAULT_FEATURES),
            eeprom_read_8_bytes: true,
            dc: DcConfig::default(),
        }
    }
}

impl EscConfig {
    /// The RAM size actually emulated: whole KiB, at most [`MAX_RAM_SIZE`].
    pub fn effective_ram_size(&self) -> usize {
        (self.ram_size.min(MAX_RAM_SIZE) / 1024) * 1024
    }

    /// FMMU count actually emulated (at most 16).
    pub fn effective_fmmu_count(&self) -> u8 {
        self.fmmu_count.min(16)
    }

    /// SyncManager count actually emulated (at most 16).
    pub fn effective_sm_count(&self) -> u8 {
        self.sm_count.min(16)
    }

    /// Whether the distributed clock is emulated (feature bit 2).
    pub fn dc_supported(&self) -> bool {
        self.features.dc_supported()
    }
}
