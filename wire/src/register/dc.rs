//! Distributed-clock registers 0x0900–0x09FF: typed helpers (ETG.1000.4, spec-notes §esc.dc, §dc).
//!
//! Most DC registers are plain integers read or written at the addresses in
//! [`super::address`]; only the ones with structure get a type here.

use core::fmt;

use crate::error::{Result, need, room};
use crate::field::{self, Field};

mod fields {
    use super::Field;
    /// Receive times of ports 0-3, u32 each (one 16-byte FPRD of 0x0900).
    pub const PORT_TIMES: Field = 0..16;
    /// System time offset (i64) + system time delay (u32): IgH's 12-byte write at 0x0920.
    pub const OFFSET: Field = 0..8;
    pub const DELAY: Field = 8..12;
    /// SYNC0 / SYNC1 cycle times (8 bytes at 0x09A0).
    pub const SYNC0_CYCLE: Field = 0..4;
    pub const SYNC1_CYCLE: Field = 4..8;
}

/// Reset value of the speed counter start register 0x0930.
pub const SPEED_COUNTER_START_DEFAULT: u16 = 0x1000;
/// Value SOEM writes to 0x0934 as a u16: time filter depth 0, speed filter depth 12.
pub const FILTER_DEPTHS_SOEM: u16 = 0x0C00;

/// Seconds from the Unix epoch to the EtherCAT epoch 2000-01-01 00:00:00 (spec-notes §dc).
pub const ECAT_EPOCH_UNIX_SECS: u64 = 946_684_800;

/// Reads a DC time register that is 64 bits wide on 64-bit DC and 32 bits wide otherwise
/// (0x0910, 0x0918, 0x0920, 0x0990; spec-notes §dc): 8 bytes if present, else 4 zero-extended.
pub fn read_time(buf: &[u8]) -> Result<u64> {
    if buf.len() >= 8 {
        Ok(field::u64_le(buf, 0))
    } else {
        need("DC time", buf, 4)?;
        Ok(u64::from(field::u32_le(buf, 0)))
    }
}

/// System time offset 0x0920 (treated as signed, as ethercrab does) and system time delay
/// 0x0928, written together as 12 bytes from 0x0920 (ETG.1000.4, spec-notes §dc step 5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct OffsetDelay {
    /// 0x0920: local time + offset = system time (ns).
    pub offset: i64,
    /// 0x0928: propagation delay from the reference clock (ns).
    pub delay: u32,
}

impl OffsetDelay {
    /// Size of the block.
    pub const LEN: usize = fields::DELAY.end;

    /// Parses the 12 bytes.
    pub fn parse(buf: &[u8]) -> Result<Self> {
        need("DC offset/delay", buf, Self::LEN)?;
        Ok(OffsetDelay {
            offset: field::u64_le(buf, fields::OFFSET.start) as i64,
            delay: field::u32_le(buf, fields::DELAY.start),
        })
    }

    /// Writes the 12 bytes.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        room("DC offset/delay", buf, Self::LEN)?;
        field::set_u64_le(buf, fields::OFFSET.start, self.offset as u64);
        field::set_u32_le(buf, fields::DELAY.start, self.delay);
        Ok(())
    }
}

/// Bit 31 of 0x092C: the sign of the system time difference.
const DIFF_SIGN: u32 = 1 << 31;

/// System time difference 0x092C (u32, sign/magnitude, ETG.1000.4, spec-notes §esc.dc).
///
/// Bit 31 set means the local copy is ahead of (≥) the received reference time, following
/// KickCAT (spec-notes §esc.dc); bits 0-30 are the saturated magnitude in ns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SystemTimeDifference {
    /// Bit 31: local system time ≥ received reference time.
    pub local_ahead: bool,
    /// Bits 0-30: magnitude in ns.
    pub magnitude: u32,
}

impl SystemTimeDifference {
    /// Decodes the register value.
    pub const fn decode(raw: u32) -> Self {
        SystemTimeDifference {
            local_ahead: raw & DIFF_SIGN != 0,
            magnitude: raw & !DIFF_SIGN,
        }
    }

    /// Encodes the register value, saturating the magnitude at 2³¹ − 1 as the ESC does.
    pub const fn encode(&self) -> u32 {
        let magnitude = if self.magnitude > !DIFF_SIGN {
            !DIFF_SIGN
        } else {
            self.magnitude
        };
        if self.local_ahead {
            magnitude | DIFF_SIGN
        } else {
            magnitude
        }
    }

    /// From a signed difference local − reference in ns (saturating).
    pub fn from_ns(diff: i64) -> Self {
        SystemTimeDifference {
            local_ahead: diff >= 0,
            magnitude: u32::try_from(diff.unsigned_abs())
                .unwrap_or(u32::MAX)
                .min(!DIFF_SIGN),
        }
    }

    /// Signed difference local − reference in ns.
    pub fn as_ns(&self) -> i64 {
        let m = i64::from(self.magnitude & !DIFF_SIGN);
        if self.local_ahead { m } else { -m }
    }

    /// Parses the register from the first 4 bytes of `buf`.
    pub fn parse(buf: &[u8]) -> Result<Self> {
        need("DC system time difference", buf, 4)?;
        Ok(Self::decode(field::u32_le(buf, 0)))
    }

    /// Writes the register into the first 4 bytes of `buf`.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        room("DC system time difference", buf, 4)?;
        field::set_u32_le(buf, 0, self.encode());
        Ok(())
    }
}

impl fmt::Display for SystemTimeDifference {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "system time difference {} ns", self.as_ns())
    }
}

/// The four port receive times 0x0900–0x090F (u32 each), latched by a write to 0x0900.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct PortReceiveTimes(pub [u32; 4]);

impl PortReceiveTimes {
    /// Size of the block.
    pub const LEN: usize = fields::PORT_TIMES.end;

    /// Parses the 16 bytes read from 0x0900.
    pub fn parse(buf: &[u8]) -> Result<Self> {
        need("DC port receive times", buf, Self::LEN)?;
        let mut times = [0u32; 4];
        for (n, t) in times.iter_mut().enumerate() {
            *t = field::u32_le(buf, fields::PORT_TIMES.start + 4 * n);
        }
        Ok(PortReceiveTimes(times))
    }

    /// Writes the 16 bytes.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        room("DC port receive times", buf, Self::LEN)?;
        for (n, t) in self.0.iter().enumerate() {
            field::set_u32_le(buf, fields::PORT_TIMES.start + 4 * n, *t);
        }
        Ok(())
    }

    /// `T(to) − T(from)` with 32-bit wrapping arithmetic (spec-notes §dc); `None` for a port ≥ 4.
    pub fn span(&self, from: usize, to: usize) -> Option<u32> {
        Some(self.0.get(to)?.wrapping_sub(*self.0.get(from)?))
    }
}

/// Cyclic unit control 0x0980 (u8).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct CyclicUnitControl {
    /// Bit 0: SYNC-out unit controlled by PDI (else ECAT).
    pub sync_out_pdi: bool,
    /// Bit 4: latch-in unit 0 controlled by PDI.
    pub latch0_pdi: bool,
    /// Bit 5: latch-in unit 1 controlled by PDI.
    pub latch1_pdi: bool,
}

impl CyclicUnitControl {
    /// Decodes the register (reserved bits ignored).
    pub const fn decode(raw: u8) -> Self {
        CyclicUnitControl {
            sync_out_pdi: raw & 0x01 != 0,
            latch0_pdi: raw & 0x10 != 0,
            latch1_pdi: raw & 0x20 != 0,
        }
    }

    /// Encodes the register.
    pub const fn encode(&self) -> u8 {
        (self.sync_out_pdi as u8) | ((self.latch0_pdi as u8) << 4) | ((self.latch1_pdi as u8) << 5)
    }
}

/// Activation register 0x0981 (u8).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct DcActivation {
    /// Bit 0: cyclic operation active.
    pub cyclic: bool,
    /// Bit 1: generate SYNC0.
    pub sync0: bool,
    /// Bit 2: generate SYNC1.
    pub sync1: bool,
    /// Bit 3: auto-activation by writing the start time.
    pub auto_activation: bool,
    /// Bit 4: extend a 32-bit start time to 64 bits.
    pub start_time_extension: bool,
    /// Bit 5: start time plausibility check.
    pub start_time_check: bool,
    /// Bit 6: near-future configuration.
    pub near_future: bool,
    /// Bit 7: debug pulse.
    pub debug_pulse: bool,
}

impl DcActivation {
    /// Decodes the register (all 8 bits are named).
    pub const fn decode(raw: u8) -> Self {
        DcActivation {
            cyclic: raw & 0x01 != 0,
            sync0: raw & 0x02 != 0,
            sync1: raw & 0x04 != 0,
            auto_activation: raw & 0x08 != 0,
            start_time_extension: raw & 0x10 != 0,
            start_time_check: raw & 0x20 != 0,
            near_future: raw & 0x40 != 0,
            debug_pulse: raw & 0x80 != 0,
        }
    }

    /// Encodes the register.
    pub const fn encode(&self) -> u8 {
        (self.cyclic as u8)
            | ((self.sync0 as u8) << 1)
            | ((self.sync1 as u8) << 2)
            | ((self.auto_activation as u8) << 3)
            | ((self.start_time_extension as u8) << 4)
            | ((self.start_time_check as u8) << 5)
            | ((self.near_future as u8) << 6)
            | ((self.debug_pulse as u8) << 7)
    }
}

/// IgH's "AssignActivate" u16: 0x0980 in the low byte, 0x0981 in the high byte
/// (e.g. 0x0300 = SYNC0 on, 0x0700 = SYNC0 + SYNC1); the SII DC category stores it too.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct AssignActivate {
    /// Low byte → 0x0980.
    pub control: CyclicUnitControl,
    /// High byte → 0x0981.
    pub activation: DcActivation,
}

impl AssignActivate {
    /// Decodes the u16.
    pub const fn decode(raw: u16) -> Self {
        AssignActivate {
            control: CyclicUnitControl::decode(raw as u8),
            activation: DcActivation::decode((raw >> 8) as u8),
        }
    }

    /// Encodes the u16.
    pub const fn encode(&self) -> u16 {
        (self.control.encode() as u16) | ((self.activation.encode() as u16) << 8)
    }
}

/// SYNC0 / SYNC1 cycle times, 8 bytes at 0x09A0 (ns).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SyncCycleTimes {
    /// 0x09A0: SYNC0 cycle time, 0 = single shot.
    pub sync0: u32,
    /// 0x09A4: SYNC1 cycle time.
    pub sync1: u32,
}

impl SyncCycleTimes {
    /// Size of the block.
    pub const LEN: usize = fields::SYNC1_CYCLE.end;

    /// Parses the 8 bytes.
    pub fn parse(buf: &[u8]) -> Result<Self> {
        need("DC SYNC cycle times", buf, Self::LEN)?;
        Ok(SyncCycleTimes {
            sync0: field::u32_le(buf, fields::SYNC0_CYCLE.start),
            sync1: field::u32_le(buf, fields::SYNC1_CYCLE.start),
        })
    }

    /// Writes the 8 bytes.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        room("DC SYNC cycle times", buf, Self::LEN)?;
        field::set_u32_le(buf, fields::SYNC0_CYCLE.start, self.sync0);
        field::set_u32_le(buf, fields::SYNC1_CYCLE.start, self.sync1);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn difference_sign_magnitude() {
        let d = SystemTimeDifference::decode(0x8000_0064);
        assert!(d.local_ahead);
        assert_eq!(d.magnitude, 100);
        assert_eq!(d.as_ns(), 100);
        assert_eq!(SystemTimeDifference::decode(0x0000_0064).as_ns(), -100);
        assert_eq!(SystemTimeDifference::from_ns(-100).encode(), 0x0000_0064);
        assert_eq!(
            SystemTimeDifference::from_ns(i64::MAX).encode(),
            0xFFFF_FFFF
        );
        assert!(SystemTimeDifference::parse(&[0; 3]).is_err());
    }

    #[test]
    fn offset_delay_and_times() {
        // Offset −1 ns, delay 0x1234 ns, laid out by hand.
        let bytes = [
            0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x34, 0x12, 0x00, 0x00,
        ];
        let od = OffsetDelay::parse(&bytes).unwrap();
        assert_eq!(
            od,
            OffsetDelay {
                offset: -1,
                delay: 0x1234
            }
        );
        let mut out = [0xa5u8; 12];
        od.emit(&mut out).unwrap();
        assert_eq!(out, bytes);
        assert!(OffsetDelay::parse(&bytes[..11]).is_err());
        assert_eq!(read_time(&[1, 0, 0, 0]), Ok(1));
        assert_eq!(
            read_time(&[1, 0, 0, 0, 0, 0, 0, 1]),
            Ok(0x0100_0000_0000_0001)
        );
        assert!(read_time(&[1, 0, 0]).is_err());
    }

    #[test]
    fn assign_activate_igh_values() {
        // 0x0300 = cyclic + SYNC0; 0x0700 = + SYNC1.
        let a = AssignActivate::decode(0x0300);
        assert!(a.activation.cyclic && a.activation.sync0 && !a.activation.sync1);
        assert!(AssignActivate::decode(0x0700).activation.sync1);
        assert_eq!(a.encode(), 0x0300);
    }

    #[test]
    fn port_times_wrap() {
        let mut bytes = [0u8; 16];
        bytes[0..4].copy_from_slice(&0xFFFF_FFF0u32.to_le_bytes());
        bytes[4..8].copy_from_slice(&0x0000_0010u32.to_le_bytes());
        let t = PortReceiveTimes::parse(&bytes).unwrap();
        assert_eq!(t.span(0, 1), Some(0x20));
        assert_eq!(t.span(0, 4), None);
        assert!(PortReceiveTimes::parse(&bytes[..15]).is_err());
    }

    proptest! {
        #[test]
        fn round_trips(raw in any::<u32>(), t in proptest::array::uniform4(any::<u32>()),
                       c in any::<u8>(), aa in any::<u16>()) {
            prop_assert_eq!(SystemTimeDifference::decode(raw).encode(), raw);
            let mut buf = [0u8; 16];
            PortReceiveTimes(t).emit(&mut buf).unwrap();
            prop_assert_eq!(PortReceiveTimes::parse(&buf).unwrap(), PortReceiveTimes(t));
            let s = SyncCycleTimes { sync0: t[0], sync1: t[1] };
            s.emit(&mut buf).unwrap();
            prop_assert_eq!(SyncCycleTimes::parse(&buf).unwrap(), s);
            prop_assert_eq!(DcActivation::decode(c).encode(), c);
            prop_assert_eq!(AssignActivate::decode(aa).encode(), aa & 0xFF31);
            let od = OffsetDelay { offset: i64::from(raw as i32) * 3, delay: t[2] };
            od.emit(&mut buf).unwrap();
            prop_assert_eq!(OffsetDelay::parse(&buf).unwrap(), od);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..20)) {
            let _ = SystemTimeDifference::parse(&bytes).map(|d| d.to_string());
            let _ = PortReceiveTimes::parse(&bytes).map(|t| t.span(3, 0));
            let _ = SyncCycleTimes::parse(&bytes);
            let _ = OffsetDelay::parse(&bytes);
            let _ = read_time(&bytes);
        }
    }
}
