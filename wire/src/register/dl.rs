//! DL control 0x0100 (u32) and DL status 0x0110 (u16) (ETG.1000.4, spec-notes §esc.dl).

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field;

/// Number of ports an ESC can have.
pub const PORT_COUNT: usize = 4;

mod bits {
    // DL control.
    pub const FORWARDING: u32 = 1 << 0;
    pub const TEMPORARY_LOOP: u32 = 1 << 1;
    pub const LOOP_SHIFT: u32 = 8;
    pub const RX_FIFO_SHIFT: u32 = 16;
    pub const RX_FIFO_MASK: u32 = 0x7;
    pub const EBUS_LOW_JITTER: u32 = 1 << 19;
    pub const EBUS_REMOTE_LINK_DOWN: u32 = 1 << 22;
    pub const ALIAS_ENABLE: u32 = 1 << 24;
    // DL status.
    pub const PDI_OPERATIONAL: u16 = 1 << 0;
    pub const PDI_WATCHDOG_OK: u16 = 1 << 1;
    pub const ENHANCED_LINK: u16 = 1 << 2;
    pub const LINK_SHIFT: u16 = 4;
    pub const PORT_SHIFT: u16 = 8;
}

/// Loop setting of one port in DL control (2 bits, ETG.1000.4, spec-notes §esc.dl).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum LoopMode {
    /// 00: open when link is up, close when it is lost.
    #[default]
    Auto,
    /// 01: close on link loss; re-open only when the master writes again.
    AutoClose,
    /// 10: always open.
    Open,
    /// 11: always closed.
    Closed,
}

impl LoopMode {
    /// Decodes the two low bits of `bits`.
    pub const fn from_bits(bits: u8) -> Self {
        match bits & 0x3 {
            0 => LoopMode::Auto,
            1 => LoopMode::AutoClose,
            2 => LoopMode::Open,
            _ => LoopMode::Closed,
        }
    }

    /// The 2-bit encoding.
    pub const fn bits(self) -> u8 {
        match self {
            LoopMode::Auto => 0,
            LoopMode::AutoClose => 1,
            LoopMode::Open => 2,
            LoopMode::Closed => 3,
        }
    }

    /// Lower-case name as in the datasheet convention.
    pub fn name(self) -> &'static str {
        match self {
            LoopMode::Auto => "auto",
            LoopMode::AutoClose => "auto-close",
            LoopMode::Open => "open",
            LoopMode::Closed => "closed",
        }
    }
}

/// DL control register 0x0100 (u32).
///
/// Bits not named here (2-7, 20-21, 23, 25-31) are dropped by [`DlControl::decode`] and
/// written as 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct DlControl {
    /// Bit 0: non-EtherCAT frames are destroyed (1) instead of forwarded (0).
    pub forwarding_destroy: bool,
    /// Bit 1: loop settings are temporary (~1 s).
    pub temporary_loop: bool,
    /// Bits 8-15: loop setting per port.
    pub loop_modes: [LoopMode; PORT_COUNT],
    /// Bits 16-18: RX FIFO size (0..=7).
    pub rx_fifo_size: u8,
    /// Bit 19: EBUS low jitter.
    pub ebus_low_jitter: bool,
    /// Bit 22: EBUS remote link down signalling time.
    pub ebus_remote_link_down: bool,
    /// Bit 24: station alias enable (FPxx also match 0x0012).
    pub alias_enable: bool,
}

impl DlControl {
    /// Size of the register.
    pub const LEN: usize = 4;

    /// Decodes a register value.
    pub fn decode(raw: u32) -> Self {
        let mut loop_modes = [LoopMode::Auto; PORT_COUNT];
        for (n, mode) in loop_modes.iter_mut().enumerate() {
            *mode = LoopMode::from_bits((raw >> (bits::LOOP_SHIFT + 2 * n as u32)) as u8);
        }
        DlControl {
            forwarding_destroy: raw & bits::FORWARDING != 0,
            temporary_loop: raw & bits::TEMPORARY_LOOP != 0,
            loop_modes,
            rx_fifo_size: ((raw >> bits::RX_FIFO_SHIFT) & bits::RX_FIFO_MASK) as u8,
            ebus_low_jitter: raw & bits::EBUS_LOW_JITTER != 0,
            ebus_remote_link_down: raw & bits::EBUS_REMOTE_LINK_DOWN != 0,
            alias_enable: raw & bits::ALIAS_ENABLE != 0,
        }
    }

    /// Encodes the register value; refuses an RX FIFO size above 7.
    pub fn encode(&self) -> Result<u32> {
        if u32::from(self.rx_fifo_size) > bits::RX_FIFO_MASK {
            return Err(WireError::Invalid {
                what: "DL control",
                reason: "RX FIFO size does not fit in 3 bits",
            });
        }
        let mut raw = u32::from(self.rx_fifo_size) << bits::RX_FIFO_SHIFT;
        for (n, mode) in self.loop_modes.iter().enumerate() {
            raw |= u32::from(mode.bits()) << (bits::LOOP_SHIFT + 2 * n as u32);
        }
        for (set, bit) in [
            (self.forwarding_destroy, bits::FORWARDING),
            (self.temporary_loop, bits::TEMPORARY_LOOP),
            (self.ebus_low_jitter, bits::EBUS_LOW_JITTER),
            (self.ebus_remote_link_down, bits::EBUS_REMOTE_LINK_DOWN),
            (self.alias_enable, bits::ALIAS_ENABLE),
        ] {
            if set {
                raw |= bit;
            }
        }
        Ok(raw)
    }

    /// Parses the register from the first 4 bytes of `buf`.
    pub fn parse(buf: &[u8]) -> Result<Self> {
        need("DL control", buf, Self::LEN)?;
        Ok(Self::decode(field::u32_le(buf, 0)))
    }

    /// Writes the register into the first 4 bytes of `buf`.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        room("DL control", buf, Self::LEN)?;
        let raw = self.encode()?;
        field::set_u32_le(buf, 0, raw);
        Ok(())
    }
}

impl fmt::Display for DlControl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "DL control loop")?;
        for (n, mode) in self.loop_modes.iter().enumerate() {
            write!(f, " {n}:{}", mode.name())?;
        }
        if self.forwarding_destroy {
            f.write_str(", destroy non-EtherCAT")?;
        }
        if self.alias_enable {
            f.write_str(", alias enabled")?;
        }
        Ok(())
    }
}

/// State of one port in DL status (ETG.1000.4, spec-notes §esc.dl).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct PortStatus {
    /// Physical link detected (bits 4-7).
    pub link: bool,
    /// Loop closed (bit 8 + 2n).
    pub loop_closed: bool,
    /// Communication established (bit 9 + 2n).
    pub communication: bool,
}

/// DL status register 0x0110 (u16, read-only for the master).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct DlStatus {
    /// Bit 0: PDI operational (EEPROM loaded).
    pub pdi_operational: bool,
    /// Bit 1: PDI watchdog reloaded (1) or expired (0).
    pub pdi_watchdog_ok: bool,
    /// Bit 2: enhanced link detection active.
    pub enhanced_link_detection: bool,
    /// Per-port link / loop / communication bits.
    pub ports: [PortStatus; PORT_COUNT],
}

impl DlStatus {
    /// Size of the register.
    pub const LEN: usize = 2;

    /// Decodes a register value; reserved bit 3 is ignored.
    pub fn decode(raw: u16) -> Self {
        let mut ports = [PortStatus::default(); PORT_COUNT];
        for (n, port) in ports.iter_mut().enumerate() {
            let n = n as u16;
            port.link = raw & (1 << (bits::LINK_SHIFT + n)) != 0;
            port.loop_closed = raw & (1 << (bits::PORT_SHIFT + 2 * n)) != 0;
            port.communication = raw & (1 << (bits::PORT_SHIFT + 2 * n + 1)) != 0;
        }
        DlStatus {
            pdi_operational: raw & bits::PDI_OPERATIONAL != 0,
            pdi_watchdog_ok: raw & bits::PDI_WATCHDOG_OK != 0,
            enhanced_link_detection: raw & bits::ENHANCED_LINK != 0,
            ports,
        }
    }

    /// Encodes the register value (an emulated ESC writes this).
    pub fn encode(&self) -> u16 {
        let mut raw = 0u16;
        for (set, bit) in [
            (self.pdi_operational, bits::PDI_OPERATIONAL),
            (self.pdi_watchdog_ok, bits::PDI_WATCHDOG_OK),
            (self.enhanced_link_detection, bits::ENHANCED_LINK),
        ] {
            if set {
                raw |= bit;
            }
        }
        for (n, port) in self.ports.iter().enumerate() {
            let n = n as u16;
            if port.link {
                raw |= 1 << (bits::LINK_SHIFT + n);
            }
            if port.loop_closed {
                raw |= 1 << (bits::PORT_SHIFT + 2 * n);
            }
            if port.communication {
                raw |= 1 << (bits::PORT_SHIFT + 2 * n + 1);
            }
        }
        raw
    }

    /// Parses the register from the first 2 bytes of `buf`.
    pub fn parse(buf: &[u8]) -> Result<Self> {
        need("DL status", buf, Self::LEN)?;
        Ok(Self::decode(field::u16_le(buf, 0)))
    }

    /// Writes the register into the first 2 bytes of `buf`.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        room("DL status", buf, Self::LEN)?;
        field::set_u16_le(buf, 0, self.encode());
        Ok(())
    }

    /// SOEM's rule: port `n` is active when its loop is open **and** communication is
    /// established (`(dl >> (8 + 2n)) & 3 == 2`). `false` for `n >= 4`.
    pub fn port_active(&self, n: usize) -> bool {
        self.ports
            .get(n)
            .is_some_and(|p| !p.loop_closed && p.communication)
    }

    /// Bit mask of active ports (bit n = port n).
    pub fn active_port_mask(&self) -> u8 {
        (0..PORT_COUNT)
            .filter(|&n| self.port_active(n))
            .fold(0, |mask, n| mask | (1 << n))
    }

    /// Number of active ports: 1 = end of line, 2 = line, 3-4 = branch.
    pub fn active_ports(&self) -> u8 {
        self.active_port_mask().count_ones() as u8
    }
}

impl fmt::Display for DlStatus {
    /// Per port in Wireshark's words: "loop open/closed, (no) link".
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "DL status PDI {}",
            if self.pdi_operational { "op" } else { "not op" }
        )?;
        for (n, p) in self.ports.iter().enumerate() {
            write!(
                f,
                ", port {n}: loop {}, {}{}",
                if p.loop_closed { "closed" } else { "open" },
                if p.link { "link" } else { "no link" },
                if p.communication { ", comm" } else { "" }
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn soem_reset_writes() {
        // spec-notes §esc.reset: SOEM writes 0x00 to 0x0101 (all loops auto) and 0x00 to 0x0103 (alias off).
        let c = DlControl::parse(&[0x01, 0x00, 0x00, 0x00]).unwrap();
        assert!(c.forwarding_destroy);
        assert_eq!(c.loop_modes, [LoopMode::Auto; 4]);
        assert!(!c.alias_enable);
        // Alias enable is byte 0x0103 bit 0 = bit 24.
        assert!(DlControl::parse(&[0, 0, 0, 0x01]).unwrap().alias_enable);
        // Byte 0x0101 = 0b11_10_01_00: port 0 auto, 1 auto-close, 2 open, 3 closed.
        let c = DlControl::parse(&[0x00, 0xE4, 0x00, 0x00]).unwrap();
        assert_eq!(
            c.loop_modes,
            [
                LoopMode::Auto,
                LoopMode::AutoClose,
                LoopMode::Open,
                LoopMode::Closed
            ]
        );
        let mut buf = [0xa5; 4];
        c.emit(&mut buf).unwrap();
        assert_eq!(buf, [0x00, 0xE4, 0x00, 0x00]);
    }

    #[test]
    fn line_topology_middle_slave() {
        // PDI op, watchdog ok, link 0+1, port 0 open+comm, port 1 open+comm, ports 2/3 closed.
        // low byte 0b0011_0011 = 0x33; high byte: p0 = 10, p1 = 10, p2 = 01, p3 = 01 → 0x5A.
        let s = DlStatus::parse(&[0x33, 0x5A]).unwrap();
        assert!(s.pdi_operational && s.pdi_watchdog_ok);
        assert!(s.port_active(0) && s.port_active(1));
        assert!(!s.port_active(2) && !s.port_active(3) && !s.port_active(9));
        assert_eq!(s.active_ports(), 2);
        assert_eq!(s.active_port_mask(), 0b0011);
        let mut buf = [0xa5; 2];
        s.emit(&mut buf).unwrap();
        assert_eq!(buf, [0x33, 0x5A]);
    }

    #[test]
    fn errors() {
        assert!(DlStatus::parse(&[0x33]).is_err());
        assert!(DlControl::parse(&[0, 0, 0]).is_err());
        let bad = DlControl {
            rx_fifo_size: 8,
            ..Default::default()
        };
        let mut buf = [0xa5; 4];
        assert!(bad.emit(&mut buf).is_err());
        assert_eq!(buf, [0xa5; 4]);
    }

    fn arb_loop() -> impl Strategy<Value = LoopMode> {
        (0u8..4).prop_map(LoopMode::from_bits)
    }

    proptest! {
        #[test]
        fn control_round_trip(
            b in proptest::array::uniform5(any::<bool>()),
            modes in proptest::array::uniform4(arb_loop()),
            fifo in 0u8..8,
        ) {
            let c = DlControl {
                forwarding_destroy: b[0],
                temporary_loop: b[1],
                loop_modes: modes,
                rx_fifo_size: fifo,
                ebus_low_jitter: b[2],
                ebus_remote_link_down: b[3],
                alias_enable: b[4],
            };
            let mut buf = [0u8; 4];
            c.emit(&mut buf).unwrap();
            prop_assert_eq!(DlControl::parse(&buf).unwrap(), c);
        }

        #[test]
        fn status_round_trip(raw in any::<u16>()) {
            // Every bit but reserved bit 3 is named, so decode/encode is lossless on the rest.
            let s = DlStatus::decode(raw);
            prop_assert_eq!(s.encode(), raw & !0x0008);
            prop_assert_eq!(DlStatus::decode(s.encode()), s);
            // SOEM's formula.
            for n in 0..4 {
                prop_assert_eq!(s.port_active(n), (raw >> (8 + 2 * n)) & 3 == 2);
            }
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..6)) {
            let _ = DlControl::parse(&bytes).map(|c| c.to_string());
            let _ = DlStatus::parse(&bytes).map(|s| s.to_string());
        }
    }
}
