//! GENERAL category, type 30: 32 bytes (ETG.2010, spec-notes §sii.categories).
//!
//! ```text
//! 0x00 u8 group idx | 0x01 u8 image idx | 0x02 u8 order idx | 0x03 u8 name idx
//! 0x04 u8 reserved (legacy physical layer) | 0x05 u8 CoE details | 0x06 u8 FoE details
//! 0x07 u8 EoE details | 0x08 u8 SoE channels | 0x09 u8 DS402 channels | 0x0A u8 SysmanClass
//! 0x0B u8 flags | 0x0C i16 current on EBus (mA) | 0x0E u8 group idx (dup) | 0x0F reserved
//! 0x10 u16 physical ports (4 bits per port) | 0x12 u16 physical memory address
//! 0x14 12 bytes reserved
//! ```
//! The physical-port word is at 0x10 (KickCAT; consistent with the EK1100 hardware), not at
//! 0x0E as ethercrab reads it (spec-notes §sii.categories).

use core::fmt;

use crate::error::{Result, need, room};
use crate::field::{self, Field};
use crate::macros::enum_with_unknown;

mod fields {
    use super::Field;
    pub const GROUP: usize = 0x00;
    pub const IMAGE: usize = 0x01;
    pub const ORDER: usize = 0x02;
    pub const NAME: usize = 0x03;
    pub const PHYSICAL_LAYER: usize = 0x04;
    pub const COE: usize = 0x05;
    pub const FOE: usize = 0x06;
    pub const EOE: usize = 0x07;
    pub const SOE: usize = 0x08;
    pub const DS402: usize = 0x09;
    pub const SYSMAN: usize = 0x0A;
    pub const FLAGS: usize = 0x0B;
    pub const CURRENT: Field = 0x0C..0x0E;
    pub const GROUP2: usize = 0x0E;
    pub const RESERVED_0F: usize = 0x0F;
    pub const PORTS: Field = 0x10..0x12;
    pub const PHYS_MEMORY: Field = 0x12..0x14;
    pub const RESERVED: Field = 0x14..0x20;
}

/// Size of the GENERAL category data.
pub const GENERAL_LEN: usize = fields::RESERVED.end;

/// CoE details, byte 0x05.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct CoeDetails(pub u8);

impl CoeDetails {
    /// Bit 0: SDO supported.
    pub fn sdo(self) -> bool {
        self.0 & 0x01 != 0
    }
    /// Bit 1: SDO information service.
    pub fn sdo_info(self) -> bool {
        self.0 & 0x02 != 0
    }
    /// Bit 2: PDO assignment.
    pub fn pdo_assign(self) -> bool {
        self.0 & 0x04 != 0
    }
    /// Bit 3: PDO configuration.
    pub fn pdo_config(self) -> bool {
        self.0 & 0x08 != 0
    }
    /// Bit 4: upload at startup.
    pub fn upload_at_startup(self) -> bool {
        self.0 & 0x10 != 0
    }
    /// Bit 5: SDO complete access.
    pub fn complete_access(self) -> bool {
        self.0 & 0x20 != 0
    }
}

/// Flags, byte 0x0B.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct GeneralFlags(pub u8);

impl GeneralFlags {
    /// Bit 0: enable SAFEOP.
    pub fn enable_safeop(self) -> bool {
        self.0 & 0x01 != 0
    }
    /// Bit 1: the slave cannot handle LRW (notLRW).
    pub fn not_lrw(self) -> bool {
        self.0 & 0x02 != 0
    }
    /// Bit 2: supports the mailbox repeat procedure (MBoxDataLinkLayer, spec-notes §mbx.repeat).
    pub fn mailbox_data_link_layer(self) -> bool {
        self.0 & 0x04 != 0
    }
    /// Bit 3: identification via AL status.
    pub fn ident_al_status(self) -> bool {
        self.0 & 0x08 != 0
    }
    /// Bit 4: identification via physical memory.
    pub fn ident_phys_memory(self) -> bool {
        self.0 & 0x10 != 0
    }
}

enum_with_unknown! {
    /// Physical port type in the GENERAL physical-port word (4 bits per port).
    pub enum PhysicalPort(u8) {
        /// 0: not used.
        NotUsed = 0,
        /// 1: MII.
        Mii = 1,
        /// 2: reserved.
        Reserved = 2,
        /// 3: EBUS.
        Ebus = 3,
        /// 4: fast hot-connect MII.
        FastHotConnect = 4,
    }
}

/// The physical-port word, offset 0x10.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct PhysicalPorts(pub u16);

impl PhysicalPorts {
    /// Type of port `n` (0-3); `NotUsed` for other ports.
    pub fn port(self, n: usize) -> PhysicalPort {
        if n < 4 {
            PhysicalPort::from(((self.0 >> (4 * n)) & 0xF) as u8)
        } else {
            PhysicalPort::NotUsed
        }
    }
}

/// The parsed GENERAL category. Reserved bytes 0x0F and 0x14-0x1F are dropped (written 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct GeneralRepr {
    /// Group string index.
    pub group_idx: u8,
    /// Image string index.
    pub image_idx: u8,
    /// Order (device type) string index.
    pub order_idx: u8,
    /// Name string index.
    pub name_idx: u8,
    /// Byte 0x04: reserved (IgH reads a legacy physical-layer field here); kept raw.
    pub physical_layer_legacy: u8,
    /// CoE details.
    pub coe_details: CoeDetails,
    /// FoE details (bit 0 enable).
    pub foe_details: u8,
    /// EoE details (bit 0 enable).
    pub eoe_details: u8,
    /// SoE channels.
    pub soe_channels: u8,
    /// DS402 channels.
    pub ds402_channels: u8,
    /// SysmanClass (reserved).
    pub sysman_class: u8,
    /// Flags.
    pub flags: GeneralFlags,
    /// Current on EBus in mA; negative = the device feeds current.
    pub ebus_current_ma: i16,
    /// Byte 0x0E: group index duplicate (meaning unclear, spec-notes §sii.categories); kept raw.
    pub group_idx_dup: u8,
    /// Physical ports.
    pub physical_ports: PhysicalPorts,
    /// ESC address of the identification value (IdentPhyM).
    pub phys_memory_addr: u16,
}

impl GeneralRepr {
    /// Parses the category data; at least 32 bytes are needed (extra bytes are ignored).
    pub fn parse(data: &[u8]) -> Result<Self> {
        need("SII GENERAL", data, GENERAL_LEN)?;
        Ok(GeneralRepr {
            group_idx: data[fields::GROUP],
            image_idx: data[fields::IMAGE],
            order_idx: data[fields::ORDER],
            name_idx: data[fields::NAME],
            physical_layer_legacy: data[fields::PHYSICAL_LAYER],
            coe_details: CoeDetails(data[fields::COE]),
            foe_details: data[fields::FOE],
            eoe_details: data[fields::EOE],
            soe_channels: data[fields::SOE],
            ds402_channels: data[fields::DS402],
            sysman_class: data[fields::SYSMAN],
            flags: GeneralFlags(data[fields::FLAGS]),
            ebus_current_ma: field::u16_le(data, fields::CURRENT.start) as i16,
            group_idx_dup: data[fields::GROUP2],
            physical_ports: PhysicalPorts(field::u16_le(data, fields::PORTS.start)),
            phys_memory_addr: field::u16_le(data, fields::PHYS_MEMORY.start),
        })
    }

    /// Size of the category data.
    pub const fn buffer_len(&self) -> usize {
        GENERAL_LEN
    }

    /// Writes the 32 bytes.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        room("SII GENERAL", buf, GENERAL_LEN)?;
        buf[fields::GROUP] = self.group_idx;
        buf[fields::IMAGE] = self.image_idx;
        buf[fields::ORDER] = self.order_idx;
        buf[fields::NAME] = self.name_idx;
        buf[fields::PHYSICAL_LAYER] = self.physical_layer_legacy;
        buf[fields::COE] = self.coe_details.0;
        buf[fields::FOE] = self.foe_details;
        buf[fields::EOE] = self.eoe_details;
        buf[fields::SOE] = self.soe_channels;
        buf[fields::DS402] = self.ds402_channels;
        buf[fields::SYSMAN] = self.sysman_class;
        buf[fields::FLAGS] = self.flags.0;
        field::set_u16_le(buf, fields::CURRENT.start, self.ebus_current_ma as u16);
        buf[fields::GROUP2] = self.group_idx_dup;
        buf[fields::RESERVED_0F] = 0;
        field::set_u16_le(buf, fields::PORTS.start, self.physical_ports.0);
        field::set_u16_le(buf, fields::PHYS_MEMORY.start, self.phys_memory_addr);
        buf[fields::RESERVED].fill(0);
        Ok(())
    }
}

impl fmt::Display for GeneralRepr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "GENERAL name #{} order #{} group #{} EBus {} mA ports {:#06x} CoE {:#04x}",
            self.name_idx,
            self.order_idx,
            self.group_idx,
            self.ebus_current_ma,
            self.physical_ports.0,
            self.coe_details.0
        )
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    /// GENERAL bytes 0x00–0x11 of three dumps (spec-notes §sii.categories), padded with zeros to 32 bytes.
    fn dump(head: [u8; 18]) -> [u8; 32] {
        let mut d = [0u8; 32];
        d[..18].copy_from_slice(&head);
        d
    }

    const EL2004: [u8; 18] = [
        0x02, 0x00, 0x01, 0x04, 0x0c, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x64, 0x00, 0x03,
        0x00, 0x33, 0x00,
    ];
    const EK1100: [u8; 18] = [
        0x02, 0x00, 0x01, 0x04, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x30, 0xf8, 0x03,
        0x00, 0x31, 0x01,
    ];
    const EL2262: [u8; 18] = [
        0x02, 0x00, 0x01, 0x04, 0x0c, 0x00, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x46, 0x00, 0x03,
        0x00, 0x33, 0x00,
    ];

    #[test]
    fn el2004() {
        let g = GeneralRepr::parse(&dump(EL2004)).unwrap();
        assert_eq!(
            (g.group_idx, g.image_idx, g.order_idx, g.name_idx),
            (2, 0, 1, 4)
        );
        assert_eq!(g.ebus_current_ma, 100);
        assert_eq!(g.physical_ports.0, 0x0033);
        assert_eq!(g.physical_ports.port(0), PhysicalPort::Ebus);
        assert_eq!(g.physical_ports.port(1), PhysicalPort::Ebus);
        assert_eq!(g.physical_ports.port(2), PhysicalPort::NotUsed);
        assert_eq!(g.group_idx_dup, 3);
        let mut out = [0xa5u8; 32];
        g.emit(&mut out).unwrap();
        assert_eq!(out, dump(EL2004));
    }

    #[test]
    fn ek1100() {
        let g = GeneralRepr::parse(&dump(EK1100)).unwrap();
        assert_eq!(g.ebus_current_ma, -2000);
        assert_eq!(g.physical_ports.0, 0x0131);
        // RJ45 in, E-bus, RJ45 out.
        assert_eq!(g.physical_ports.port(0), PhysicalPort::Mii);
        assert_eq!(g.physical_ports.port(1), PhysicalPort::Ebus);
        assert_eq!(g.physical_ports.port(2), PhysicalPort::Mii);
        assert_eq!(g.physical_ports.port(3), PhysicalPort::NotUsed);
        let mut out = [0xa5u8; 32];
        g.emit(&mut out).unwrap();
        assert_eq!(out, dump(EK1100));
    }

    #[test]
    fn el2262() {
        let g = GeneralRepr::parse(&dump(EL2262)).unwrap();
        assert_eq!(g.sysman_class, 0x13);
        assert_eq!(g.ebus_current_ma, 0x46);
        assert_eq!(g.physical_ports.0, 0x0033);
        assert!(GeneralRepr::parse(&dump(EL2262)[..31]).is_err());
    }

    pub(crate) fn arb_general() -> impl Strategy<Value = GeneralRepr> {
        (
            proptest::array::uniform12(any::<u8>()),
            any::<i16>(),
            any::<u8>(),
            any::<u16>(),
            any::<u16>(),
        )
            .prop_map(|(b, cur, dup, ports, mem)| GeneralRepr {
                group_idx: b[0],
                image_idx: b[1],
                order_idx: b[2],
                name_idx: b[3],
                physical_layer_legacy: b[4],
                coe_details: CoeDetails(b[5]),
                foe_details: b[6],
                eoe_details: b[7],
                soe_channels: b[8],
                ds402_channels: b[9],
                sysman_class: b[10],
                flags: GeneralFlags(b[11]),
                ebus_current_ma: cur,
                group_idx_dup: dup,
                physical_ports: PhysicalPorts(ports),
                phys_memory_addr: mem,
            })
    }

    proptest! {
        #[test]
        fn round_trip(g in arb_general()) {
            let mut buf = [0u8; GENERAL_LEN];
            g.emit(&mut buf).unwrap();
            prop_assert_eq!(GeneralRepr::parse(&buf).unwrap(), g);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
            if let Ok(g) = GeneralRepr::parse(&bytes) {
                let _ = (g.to_string(), g.physical_ports.port(7));
            }
        }
    }
}
