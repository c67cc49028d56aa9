//! ESC information block 0x0000–0x0009 (ETG.1000.4, spec-notes §esc.info).
//!
//! ```text
//! 0 u8 type | 1 u8 revision | 2 u16 build | 4 u8 #FMMU | 5 u8 #SM | 6 u8 RAM KiB
//! 7 u8 port descriptor (2 bits per port) | 8 u16 features
//! ```
//! Type is at 0x0000 and revision at 0x0001 (spec-notes §esc.info; Wireshark has them swapped).

use core::fmt;

use crate::error::{Result, need, room};
use crate::field::{self, Field};

mod fields {
    use super::Field;
    pub const TYPE: usize = 0;
    pub const REVISION: usize = 1;
    pub const BUILD: Field = 2..4;
    pub const FMMU_COUNT: usize = 4;
    pub const SM_COUNT: usize = 5;
    pub const RAM_SIZE: usize = 6;
    pub const PORT_DESCRIPTOR: usize = 7;
    pub const FEATURES: Field = 8..10;
}

/// Size of the information block.
pub const INFO_LEN: usize = fields::FEATURES.end;

/// Physical type of one port in the port descriptor 0x0007 (2 bits per port).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum PortType {
    /// 00: not implemented.
    #[default]
    NotImplemented,
    /// 01: not configured (SII).
    NotConfigured,
    /// 10: EBUS.
    Ebus,
    /// 11: MII / RMII / RGMII.
    Mii,
}

impl PortType {
    /// Decodes the two low bits of `bits`.
    pub const fn from_bits(bits: u8) -> Self {
        match bits & 0x3 {
            0 => PortType::NotImplemented,
            1 => PortType::NotConfigured,
            2 => PortType::Ebus,
            _ => PortType::Mii,
        }
    }

    /// The 2-bit encoding.
    pub const fn bits(self) -> u8 {
        match self {
            PortType::NotImplemented => 0,
            PortType::NotConfigured => 1,
            PortType::Ebus => 2,
            PortType::Mii => 3,
        }
    }

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            PortType::NotImplemented => "-",
            PortType::NotConfigured => "not configured",
            PortType::Ebus => "EBUS",
            PortType::Mii => "MII",
        }
    }
}

/// ESC features supported, register 0x0008 (u16). The raw value is kept; accessors name
/// the bits of the ETG.1000.4 table (spec-notes §esc.info).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct EscFeatures(pub u16);

impl EscFeatures {
    fn bit(self, n: u16) -> bool {
        self.0 & (1 << n) != 0
    }
    /// Bit 0: FMMUs are byte-oriented only.
    pub fn fmmu_byte_oriented(self) -> bool {
        self.bit(0)
    }
    /// Bit 1: unused register access not supported.
    pub fn unused_register_access_unsupported(self) -> bool {
        self.bit(1)
    }
    /// Bit 2: distributed clocks supported.
    pub fn dc_supported(self) -> bool {
        self.bit(2)
    }
    /// Bit 3: 64-bit DC system time.
    pub fn dc_64bit(self) -> bool {
        self.bit(3)
    }
    /// Bit 4: low-jitter EBUS.
    pub fn low_jitter_ebus(self) -> bool {
        self.bit(4)
    }
    /// Bit 5: enhanced link detection EBUS.
    pub fn enhanced_link_ebus(self) -> bool {
        self.bit(5)
    }
    /// Bit 6: enhanced link detection MII.
    pub fn enhanced_link_mii(self) -> bool {
        self.bit(6)
    }
    /// Bit 7: separate handling of FCS errors.
    pub fn separate_fcs_errors(self) -> bool {
        self.bit(7)
    }
    /// Bit 8: enhanced DC SYNC activation.
    pub fn enhanced_dc_sync_activation(self) -> bool {
        self.bit(8)
    }
    /// Bit 9 (inverted): LRW supported.
    pub fn lrw_supported(self) -> bool {
        !self.bit(9)
    }
    /// Bit 10 (inverted): BRW/APRW/FPRW supported.
    pub fn read_write_supported(self) -> bool {
        !self.bit(10)
    }
    /// Bit 11: fixed FMMU/SM configuration.
    pub fn fixed_fmmu_sm_config(self) -> bool {
        self.bit(11)
    }
}

/// View of the 10-byte information block.
#[derive(Debug, Clone)]
pub struct EscInfo<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> EscInfo<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        EscInfo { buffer }
    }

    /// Wraps a buffer and checks that the 10 bytes are present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let view = Self::new_unchecked(buffer);
        view.check_len()?;
        Ok(view)
    }

    /// Checks that the 10 bytes are present.
    pub fn check_len(&self) -> Result<()> {
        need("ESC information", self.buffer.as_ref(), INFO_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// ESC type.
    pub fn esc_type(&self) -> u8 {
        self.buffer.as_ref()[fields::TYPE]
    }

    /// ESC revision.
    pub fn revision(&self) -> u8 {
        self.buffer.as_ref()[fields::REVISION]
    }

    /// ESC build.
    pub fn build(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::BUILD.start)
    }

    /// Number of FMMUs.
    pub fn fmmu_count(&self) -> u8 {
        self.buffer.as_ref()[fields::FMMU_COUNT]
    }

    /// Number of SyncManagers.
    pub fn sm_count(&self) -> u8 {
        self.buffer.as_ref()[fields::SM_COUNT]
    }

    /// Process RAM in KiB.
    pub fn ram_kib(&self) -> u8 {
        self.buffer.as_ref()[fields::RAM_SIZE]
    }

    /// Raw port descriptor.
    pub fn port_descriptor(&self) -> u8 {
        self.buffer.as_ref()[fields::PORT_DESCRIPTOR]
    }

    /// Features.
    pub fn features(&self) -> EscFeatures {
        EscFeatures(field::u16_le(self.buffer.as_ref(), fields::FEATURES.start))
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> EscInfo<T> {
    /// Sets type and revision.
    pub fn set_type_revision(&mut self, esc_type: u8, revision: u8) {
        let buf = self.buffer.as_mut();
        buf[fields::TYPE] = esc_type;
        buf[fields::REVISION] = revision;
    }

    /// Sets the build.
    pub fn set_build(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::BUILD.start, value)
    }

    /// Sets the FMMU count, SM count and RAM size.
    pub fn set_counts(&mut self, fmmus: u8, sms: u8, ram_kib: u8) {
        let buf = self.buffer.as_mut();
        buf[fields::FMMU_COUNT] = fmmus;
        buf[fields::SM_COUNT] = sms;
        buf[fields::RAM_SIZE] = ram_kib;
    }

    /// Sets the raw port descriptor.
    pub fn set_port_descriptor(&mut self, value: u8) {
        self.buffer.as_mut()[fields::PORT_DESCRIPTOR] = value
    }

    /// Sets the features.
    pub fn set_features(&mut self, value: EscFeatures) {
        field::set_u16_le(self.buffer.as_mut(), fields::FEATURES.start, value.0)
    }
}

/// Parsed information block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct EscInfoRepr {
    /// ESC type (0x0000).
    pub esc_type: u8,
    /// ESC revision (0x0001).
    pub revision: u8,
    /// ESC build.
    pub build: u16,
    /// Number of FMMUs.
    pub fmmu_count: u8,
    /// Number of SyncManagers.
    pub sm_count: u8,
    /// Process RAM in KiB.
    pub ram_kib: u8,
    /// Port types 0-3.
    pub ports: [PortType; 4],
    /// Feature bits.
    pub features: EscFeatures,
}

impl EscInfoRepr {
    /// Parses a checked view.
    pub fn parse<T: AsRef<[u8]>>(view: &EscInfo<T>) -> Result<Self> {
        view.check_len()?;
        let pd = view.port_descriptor();
        Ok(EscInfoRepr {
            esc_type: view.esc_type(),
            revision: view.revision(),
            build: view.build(),
            fmmu_count: view.fmmu_count(),
            sm_count: view.sm_count(),
            ram_kib: view.ram_kib(),
            ports: [0, 2, 4, 6].map(|s| PortType::from_bits(pd >> s)),
            features: view.features(),
        })
    }

    /// Bytes written by [`Self::emit`].
    pub const fn buffer_len(&self) -> usize {
        INFO_LEN
    }

    /// Writes the 10 bytes.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, view: &mut EscInfo<T>) -> Result<()> {
        room("ESC information", view.buffer.as_ref(), INFO_LEN)?;
        let pd = self
            .ports
            .iter()
            .enumerate()
            .fold(0u8, |acc, (n, p)| acc | (p.bits() << (2 * n)));
        view.set_type_revision(self.esc_type, self.revision);
        view.set_build(self.build);
        view.set_counts(self.fmmu_count, self.sm_count, self.ram_kib);
        view.set_port_descriptor(pd);
        view.set_features(self.features);
        Ok(())
    }
}

impl fmt::Display for EscInfoRepr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ESC type {:#04x} rev {} build {:#06x}, {} FMMUs, {} SMs, {} KiB RAM, ports {}/{}/{}/{}{}",
            self.esc_type,
            self.revision,
            self.build,
            self.fmmu_count,
            self.sm_count,
            self.ram_kib,
            self.ports[0].name(),
            self.ports[1].name(),
            self.ports[2].name(),
            self.ports[3].name(),
            if self.features.dc_supported() {
                ", DC"
            } else {
                ""
            }
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn worked_example() {
        // KickCAT's emulator (spec-notes §esc.info): type 0x04, build 0x0301, features 0x01CC; port
        // descriptor 0x0F = ports 0 and 1 MII. Other fields chosen by hand.
        let bytes = [0x04, 0x01, 0x01, 0x03, 0x08, 0x08, 0x08, 0x0F, 0xCC, 0x01];
        let r = EscInfoRepr::parse(&EscInfo::new_checked(&bytes[..]).unwrap()).unwrap();
        assert_eq!((r.esc_type, r.revision, r.build), (0x04, 0x01, 0x0301));
        assert_eq!((r.fmmu_count, r.sm_count, r.ram_kib), (8, 8, 8));
        assert_eq!(
            r.ports,
            [
                PortType::Mii,
                PortType::Mii,
                PortType::NotImplemented,
                PortType::NotImplemented
            ]
        );
        let f = r.features;
        assert!(f.dc_supported() && f.dc_64bit() && f.enhanced_link_mii());
        assert!(f.separate_fcs_errors() && f.enhanced_dc_sync_activation());
        assert!(!f.fmmu_byte_oriented() && f.lrw_supported() && f.read_write_supported());
        let mut out = [0xa5u8; 10];
        r.emit(&mut EscInfo::new_unchecked(&mut out[..])).unwrap();
        assert_eq!(out, bytes);
        assert!(EscInfo::new_checked(&bytes[..9]).is_err());
    }

    proptest! {
        #[test]
        fn round_trip(bytes in proptest::array::uniform10(any::<u8>())) {
            // Every bit of the block is named or raw, so parse/emit is the identity.
            let r = EscInfoRepr::parse(&EscInfo::new_checked(&bytes[..]).unwrap()).unwrap();
            let mut out = [0u8; INFO_LEN];
            r.emit(&mut EscInfo::new_unchecked(&mut out[..])).unwrap();
            prop_assert_eq!(out, bytes);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..12)) {
            if let Ok(view) = EscInfo::new_checked(&bytes[..]) {
                let _ = EscInfoRepr::parse(&view).map(|r| r.to_string());
            }
        }
    }
}
