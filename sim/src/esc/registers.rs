//! Which register bits the master may write, and the values registers hold after power-on.
//!
//! Read-only registers (information block, DL status, AL status, SM status, ...) keep their
//! value when the master writes them; the write still counts in the working counter, as on
//! a real ESC (spec-notes §commands). Registers with write side effects (error counters, EEPROM
//! command, DC latch and system time, AL control) are handled by hooks in
//! [`super::physical`]; their mask here only says what is stored.

use std::sync::LazyLock;

use ecat_wire::register::address as reg;
use ecat_wire::register::al::{AlControl, AlState, AlStatus};
use ecat_wire::register::dc::SPEED_COUNTER_START_DEFAULT;
use ecat_wire::register::info::{EscInfo, EscInfoRepr};
use ecat_wire::register::sync_manager::{
    SM_LEN, SmActivate, SmControl, SmDirection, SmMode, SmPdiControl, SyncManager,
};

use super::config::EscConfig;
use super::memory::Memory;
use super::sync_manager::update_registers;

/// The parts of the configuration that decide which registers exist.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Layout {
    /// Implemented SyncManagers.
    pub sm_count: u8,
    /// Implemented FMMUs.
    pub fmmu_count: u8,
    /// Whether the DC registers exist.
    pub dc: bool,
}

impl Layout {
    /// The layout of `config`.
    pub fn of(config: &EscConfig) -> Self {
        Layout {
            sm_count: config.effective_sm_count(),
            fmmu_count: config.effective_fmmu_count(),
            dc: config.dc_supported(),
        }
    }
}

/// Watchdog divider reset value: (2498 + 2) × 40 ns = 100 µs per tick (spec-notes §esc.watchdog).
pub const WATCHDOG_DIVIDER_DEFAULT: u16 = 0x09C2;
/// Watchdog times reset value: 1000 ticks = 100 ms.
pub const WATCHDOG_TIME_DEFAULT: u16 = 1000;
/// DC system time difference filter depth after reset (KickCAT).
pub const TIME_FILTER_DEPTH_DEFAULT: u8 = 4;
/// DC speed counter filter depth after reset (KickCAT).
pub const SPEED_FILTER_DEPTH_DEFAULT: u8 = 12;
/// Watchdog status process data: bit 0 = 1 means active or disabled (not expired).
pub const WATCHDOG_STATUS_OK: u16 = 0x0001;

/// The bits of register byte `addr` that an ECAT write stores; 0 for read-only, reserved
/// and non-existent registers.
pub(crate) fn ecat_write_mask(addr: u32, layout: Layout) -> u8 {
    let Ok(addr) = u16::try_from(addr) else {
        return 0;
    };
    if let Some(mask) = channel_mask(addr, layout) {
        return mask;
    }
    match addr {
        // Station address (the alias 0x0012 is loaded from the EEPROM, read-only for ECAT).
        0x0010..=0x0011 => 0xFF,
        // Write (register) protection: stored, not enforced.
        0x0020..=0x0021 | 0x0030..=0x0031 => 0xFF,
        // ESC reset ECAT: the 'R' 'E' 'S' sequence is checked by a hook.
        0x0040 => 0xFF,
        // DL control and the physical read/write offset.
        0x0100..=0x0103 | 0x0108..=0x0109 => 0xFF,
        // AL control and the LED overrides.
        0x0120..=0x0121 | 0x0138..=0x0139 => 0xFF,
        // ECAT event mask (the AL event mask 0x0204 belongs to the PDI).
        0x0200..=0x0201 => 0xFF,
        // Watchdog divider and times.
        0x0400..=0x0401 | 0x0410..=0x0411 | 0x0420..=0x0421 => 0xFF,
        // EEPROM configuration: bit 0 assign to PDI, bit 1 force ECAT access.
        0x0500 => 0x03,
        // EEPROM control: bit 0 write enable, bits 8-10 command; the rest is status.
        0x0502 => 0x01,
        0x0503 => 0x07,
        // EEPROM address and data.
        0x0504..=0x050F => 0xFF,
        // MII management: stored only, there is no PHY.
        0x0510..=0x0515 => 0xFF,
        // DC offset, delay, speed counter start and filter depths.
        0x0920..=0x092B | 0x0930..=0x0931 if layout.dc => 0xFF,
        0x0934..=0x0935 if layout.dc => 0x0F,
        // DC cyclic unit control, activation, start time, cycle times, latch control.
        0x0980..=0x0981 | 0x0990..=0x0997 | 0x09A0..=0x09A7 if layout.dc => 0xFF,
        0x09A8..=0x09A9 if layout.dc => 0x03,
        // Digital and general-purpose outputs.
        0x0F00..=0x0F17 => 0xFF,
        _ => 0,
    }
}

/// The bits of one SM register set an ECAT write stores, laid out by wire's view: start,
/// length, control (all but reserved bit 7) and activate (enable, repeat request, latch
/// events). Status and PDI control are written by the ESC and the PDI only.
static SM_WRITE_MASK: LazyLock<[u8; SM_LEN]> = LazyLock::new(|| {
    let mut sm = SyncManager::new_unchecked([0; SM_LEN]);
    sm.set_start(u16::MAX);
    sm.set_length(u16::MAX);
    let control = SmControl {
        mode: SmMode::from(0x03),
        direction: SmDirection::from(0x03),
        ecat_irq: true,
        pdi_irq: true,
        watchdog: true,
    };
    // Mode and direction are 2-bit values: encoding cannot fail.
    sm.set_control_raw(control.encode().unwrap_or(0));
    let activate = SmActivate {
        enable: true,
        repeat_request: true,
        latch_ecat: true,
        latch_pdi: true,
    };
    sm.set_activate_raw(activate.encode());
    sm.into_inner()
});

/// Write mask inside the FMMU and SM register blocks, `None` outside them.
fn channel_mask(addr: u16, layout: Layout) -> Option<u8> {
    let fmmus = reg::FMMU_BASE..reg::FMMU_BASE + reg::FMMU_STRIDE * u16::from(reg::FMMU_MAX);
    if fmmus.contains(&addr) {
        let n = (addr - reg::FMMU_BASE) / reg::FMMU_STRIDE;
        let offset = (addr - reg::FMMU_BASE) % reg::FMMU_STRIDE;
        let mask = match offset {
            _ if n >= u16::from(layout.fmmu_count) => 0,
            // Logical start, length, physical start.
            0..=5 | 8..=9 => 0xFF,
            // Bit positions: bits 0-2.
            6 | 7 | 10 => 0x07,
            // Type (read/write) and activate.
            11 => 0x03,
            12 => 0x01,
            _ => 0,
        };
        return Some(mask);
    }
    let sms = reg::SM_BASE..reg::SM_BASE + reg::SM_STRIDE * u16::from(reg::SM_MAX);
    if sms.contains(&addr) {
        let n = (addr - reg::SM_BASE) / reg::SM_STRIDE;
        let offset = (addr - reg::SM_BASE) % reg::SM_STRIDE;
        let mask = if n < u16::from(layout.sm_count) {
            SM_WRITE_MASK.get(usize::from(offset)).copied().unwrap_or(0)
        } else {
            0
        };
        return Some(mask);
    }
    None
}

/// Puts the power-on values into `mem` (everything else becomes 0). The EEPROM-loaded
/// registers (0x0012, 0x0140-0x0153, 0x0982) are filled by the EEPROM load that follows.
pub(crate) fn load_reset_values(mem: &mut Memory, config: &EscConfig) {
    mem.clear();
    let info = EscInfoRepr {
        esc_type: config.esc_type,
        revision: config.revision,
        build: config.build,
        fmmu_count: config.effective_fmmu_count(),
        sm_count: config.effective_sm_count(),
        ram_kib: u8::try_from(config.effective_ram_size() / 1024).unwrap_or(u8::MAX),
        ports: config.ports,
        features: config.features,
    };
    if let Some(block) = mem.get_mut(u32::from(reg::TYPE), info.buffer_len()) {
        // The block has exactly buffer_len() bytes, so emit cannot fail.
        let _ = info.emit(&mut EscInfo::new_unchecked(block));
    }
    // AL control and status reset to INIT, without error or acknowledge flags.
    if let Some(control) = mem.get_mut(reg::AL_CONTROL.into(), AlControl::LEN) {
        // Two bytes and a state that fits its 4 bits: emit cannot fail.
        let _ = AlControl::request(AlState::Init).emit(control);
    }
    if let Some(status) = mem.get_mut(reg::AL_STATUS.into(), AlStatus::LEN) {
        let _ = AlStatus::new(AlState::Init).emit(status);
    }
    let deactivated = SmPdiControl {
        deactivate: true,
        repeat_ack: false,
    };
    for n in 0..config.effective_sm_count() {
        // SyncManagers start disabled by the PDI: the slave application enables them on the
        // state transitions that need them (ETG.1000.6, spec-notes §al).
        update_registers(mem, n, |sm| sm.set_pdi_control_raw(deactivated.encode()));
    }
    mem.set_u16(reg::WATCHDOG_DIVIDER.into(), WATCHDOG_DIVIDER_DEFAULT);
    mem.set_u16(reg::WATCHDOG_TIME_PDI.into(), WATCHDOG_TIME_DEFAULT);
    mem.set_u16(
        reg::WATCHDOG_TIME_PROCESS_DATA.into(),
        WATCHDOG_TIME_DEFAULT,
    );
    mem.set_u16(reg::WATCHDOG_STATUS_PROCESS_DATA.into(), WATCHDOG_STATUS_OK);
    if config.dc_supported() {
        mem.set_u16(
            reg::DC_SPEED_COUNTER_START.into(),
            SPEED_COUNTER_START_DEFAULT,
        );
        mem.set_u8(reg::DC_TIME_FILTER_DEPTH.into(), TIME_FILTER_DEPTH_DEFAULT);
        mem.set_u8(
            reg::DC_SPEED_FILTER_DEPTH.into(),
            SPEED_FILTER_DEPTH_DEFAULT,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout() -> Layout {
        Layout::of(&EscConfig::default())
    }

    #[test]
    fn read_only_registers_have_no_writable_bits() {
        for addr in [
            0x0000, 0x0008, 0x0012, 0x0110, 0x0130, 0x0134, 0x0140, 0x0210, 0x0805,
        ] {
            assert_eq!(ecat_write_mask(addr, layout()), 0, "{addr:#06x}");
        }
        for addr in [
            0x0010, 0x0101, 0x0120, 0x0800, 0x0806, 0x0600, 0x0920, 0x0504,
        ] {
            assert_ne!(ecat_write_mask(addr, layout()), 0, "{addr:#06x}");
        }
    }

    #[test]
    fn channels_beyond_the_count_do_not_exist() {
        let l = Layout {
            sm_count: 4,
            fmmu_count: 3,
            dc: false,
        };
        assert_eq!(ecat_write_mask(0x0820, l), 0, "SM4");
        assert_eq!(ecat_write_mask(0x0818, l), 0xFF, "SM3");
        assert_eq!(ecat_write_mask(0x0630, l), 0, "FMMU3");
        assert_eq!(ecat_write_mask(0x0920, l), 0, "no DC");
    }

    #[test]
    fn sm_register_bits_the_master_may_write() {
        // SM1: start and length whole, control without reserved bit 7, status none,
        // activate enable/repeat/latch bits, PDI control none.
        let masks: Vec<u8> = (0x0808..0x0810)
            .map(|addr| ecat_write_mask(addr, layout()))
            .collect();
        assert_eq!(masks, [0xFF, 0xFF, 0xFF, 0xFF, 0x7F, 0x00, 0xC3, 0x00]);
    }

    #[test]
    fn reset_values() {
        let config = EscConfig::default();
        let mut mem = Memory::new(config.effective_ram_size());
        load_reset_values(&mut mem, &config);
        assert_eq!(mem.u8(0x0000), 0x04);
        assert_eq!(mem.u8(0x0004), 8);
        assert_eq!(mem.u8(0x0005), 8);
        assert_eq!(mem.u8(0x0006), 8);
        assert_eq!(mem.u8(0x0007), 0x0F);
        assert_eq!(mem.u16(0x0008), 0x01CC);
        assert_eq!(mem.u16(0x0120), 0x0001);
        assert_eq!(mem.u16(0x0130), 0x0001);
        assert_eq!(mem.u16(0x0930), 0x1000);
        assert_eq!(mem.u8(0x0934), 4);
        assert_eq!(mem.u8(0x0935), 12);
        assert_eq!(mem.u16(0x0400), 0x09C2);
        assert_eq!(mem.u16(0x0420), 1000);
        assert_eq!(mem.u8(0x0807), 0x01);
        assert_eq!(mem.u8(0x080F), 0x01);
    }
}
