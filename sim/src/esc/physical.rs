//! Physical memory accesses: which bytes a datagram may touch, and the side effects of
//! register reads and writes.
//!
//! - An active SyncManager's range (RAM, or the digital I/O registers from 0x0F00): its
//!   rules apply ([`super::sync_manager`]).
//! - Register area (< 0x1000): always accessible; an access starting there is clipped at
//!   0x1000. Writes go through the per-bit write masks of [`super::registers`] (read-only
//!   bits keep their value, the access still counts), then through the hooks below.
//! - Process RAM outside every SyncManager: the access is plain memory if it comes through
//!   an FMMU or lies inside an enabled FMMU's physical range, and blocked otherwise
//!   (spec-notes §esc.emulation). Plain accesses are clipped at the next SyncManager so they never bypass its
//!   rules.
//! - Beyond the RAM: blocked.

use ecat_wire::register::address as reg;
use ecat_wire::register::dl::DlControl;
use ecat_wire::register::sync_manager::SM_LEN;

use crate::device::Device;

use super::Esc;
use super::memory::{REGISTER_END, overlaps};
use super::registers;
use super::sync_manager;

/// Where an access comes from: a physical command (APxx/FPxx/Bxx/xRMW) or an FMMU
/// translating a logical command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Origin {
    /// Physical addressing: plain RAM only inside an FMMU-mapped range.
    Physical,
    /// Through an FMMU: the mapping itself grants access to plain RAM.
    Fmmu,
}

/// The bytes of the ESC reset sequence written to 0x0040 (ETG.1000.4, spec-notes §esc.address).
const RESET_SEQUENCE: [u8; 3] = reg::ESC_RESET_SEQUENCE;

impl Esc {
    /// Reads `out.len()` bytes at `addr` under the access rules; bytes the access does not
    /// reach are left untouched. Returns whether the access took place (counts in the WKC).
    pub(crate) fn read_phys(
        &mut self,
        device: &mut dyn Device,
        addr: u32,
        out: &mut [u8],
        origin: Origin,
    ) -> bool {
        if let Some(n) = self.sm_at(addr) {
            let dev = self.pdi_device(n, device);
            return self.sms[n].ecat_read(&mut self.mem, addr, out, dev);
        }
        if addr < REGISTER_END {
            let n = out.len().min((REGISTER_END - addr) as usize);
            self.read_registers(addr, &mut out[..n]);
            return true;
        }
        if addr >= self.mem.end() {
            return false;
        }
        let n = self.plain_ram_len(addr, out.len());
        if origin == Origin::Fmmu || self.fmmu_covers(addr, n) {
            self.mem.read_into(addr, &mut out[..n]);
            true
        } else {
            false
        }
    }

    /// Writes `data` at `addr` under the access rules. Returns whether the access took place.
    pub(crate) fn write_phys(
        &mut self,
        device: &mut dyn Device,
        addr: u32,
        data: &[u8],
        origin: Origin,
    ) -> bool {
        if let Some(n) = self.sm_at(addr) {
            let dev = self.pdi_device(n, device);
            let written = self.sms[n].ecat_write(&mut self.mem, addr, data, dev);
            if written {
                self.watchdog_write(n);
            }
            return written;
        }
        if addr < REGISTER_END {
            let n = data.len().min((REGISTER_END - addr) as usize);
            self.write_registers(device, addr, &data[..n]);
            return true;
        }
        if addr >= self.mem.end() {
            return false;
        }
        let n = self.plain_ram_len(addr, data.len());
        if origin == Origin::Fmmu || self.fmmu_covers(addr, n) {
            self.mem.write_from(addr, &data[..n]);
            true
        } else {
            false
        }
    }

    /// What a read at `addr` would return, without side effects (bit-granular FMMU writes
    /// merge their bits into this).
    pub(crate) fn peek_phys(&self, addr: u32, out: &mut [u8]) {
        if let Some(n) = self.sm_at(addr) {
            self.sms[n].peek(&self.mem, addr, out);
        } else {
            self.mem.read_into(addr, out);
        }
    }

    /// The active SyncManager covering `addr`, if any (the lowest index wins on overlap,
    /// as SyncManager priority does on real ESCs).
    fn sm_at(&self, addr: u32) -> Option<usize> {
        self.sms.iter().position(|sm| sm.covers(addr))
    }

    /// The device, if SM `n` is the one its process data goes through.
    fn pdi_device<'d>(&self, n: usize, device: &'d mut dyn Device) -> Option<&'d mut dyn Device> {
        let info = self.eeprom.info();
        let n = u8::try_from(n).ok()?;
        (Some(n) == info.outputs_sm || Some(n) == info.inputs_sm).then_some(device)
    }

    /// How many of `len` bytes at RAM address `addr` are plain memory: up to the end of the
    /// RAM or the start of the next active SyncManager.
    fn plain_ram_len(&self, addr: u32, len: usize) -> usize {
        let mut end = self.mem.end();
        for sm in &self.sms {
            let c = sm.config();
            if c.active && u32::from(c.start) > addr {
                end = end.min(u32::from(c.start));
            }
        }
        len.min(end.saturating_sub(addr) as usize)
    }

    /// Register read with its side effects: dynamic registers are refreshed first, and
    /// reading AL status / DL status acknowledges the matching ECAT event.
    fn read_registers(&mut self, addr: u32, out: &mut [u8]) {
        let len = out.len();
        if overlaps(addr, len, reg::ECAT_EVENT_REQUEST.into(), 2) {
            let events = self.ecat_event_request();
            self.mem.set_u16(reg::ECAT_EVENT_REQUEST.into(), events);
        }
        if self.layout.dc && overlaps(addr, len, reg::DC_SYSTEM_TIME.into(), 8) {
            self.refresh_system_time();
        }
        self.mem.read_into(addr, out);
        if overlaps(addr, len, reg::AL_STATUS.into(), 2) {
            self.events.al_status = false;
        }
        if overlaps(addr, len, reg::DL_STATUS.into(), 2) {
            self.events.dl_status = false;
        }
    }

    /// Register write: masked store, then the hooks of the registers it touched.
    fn write_registers(&mut self, device: &mut dyn Device, addr: u32, data: &[u8]) {
        let eeprom_locked = self.eeprom_assigned_to_pdi();
        for (i, &byte) in data.iter().enumerate() {
            let a = addr + i as u32;
            // While the PDI owns the EEPROM, its control and data registers ignore ECAT.
            if eeprom_locked && (0x0502..0x0510).contains(&a) {
                continue;
            }
            let mask = registers::ecat_write_mask(a, self.layout);
            if mask != 0 {
                let old = self.mem.u8(a);
                self.mem.set_u8(a, (old & !mask) | (byte & mask));
            }
        }
        self.after_register_write(device, addr, data, eeprom_locked);
    }

    /// Side effects of a register write, in an order that lets one datagram configure and
    /// use a function (SyncManagers before AL control, EEPROM address before command).
    fn after_register_write(
        &mut self,
        device: &mut dyn Device,
        addr: u32,
        data: &[u8],
        eeprom_locked: bool,
    ) {
        let len = data.len();
        let touched = |start: u16, n: usize| overlaps(addr, len, start.into(), n);
        if touched(reg::ESC_RESET_ECAT, 1) {
            let byte = data[(u32::from(reg::ESC_RESET_ECAT) - addr) as usize];
            if self.reset_sequence_step(byte) {
                self.power_on(self.frame.port0_ns);
                return;
            }
        }
        self.clear_error_counters(addr, len);
        if touched(reg::DL_CONTROL, DlControl::LEN) {
            self.update_dl_status();
        }
        for n in 0..self.layout.sm_count {
            if overlaps(addr, len, sync_manager::base(n), SM_LEN) {
                self.sm_registers_written(n);
            }
        }
        if !eeprom_locked && touched(reg::EEPROM_CONTROL + 1, 1) {
            self.eeprom_command();
        }
        if self.layout.dc {
            if touched(reg::DC_RECEIVE_TIME_PORT0, 1) {
                self.latch_receive_times();
            }
            if touched(reg::DC_SYSTEM_TIME, 8) {
                self.system_time_written(addr, data);
            }
            if touched(reg::DC_SPEED_COUNTER_START, 2) {
                self.reset_dc_filter();
            }
        }
        if touched(reg::AL_CONTROL, 2) {
            self.al_control_written(device);
        }
    }

    /// Advances the 'R' 'E' 'S' sequence with one byte written to 0x0040; true when it is
    /// complete.
    fn reset_sequence_step(&mut self, byte: u8) -> bool {
        if RESET_SEQUENCE.get(self.reset_sequence) == Some(&byte) {
            self.reset_sequence += 1;
        } else if byte == RESET_SEQUENCE[0] {
            self.reset_sequence = 1;
        } else {
            self.reset_sequence = 0;
        }
        if self.reset_sequence == RESET_SEQUENCE.len() {
            self.reset_sequence = 0;
            return true;
        }
        false
    }

    /// The ECAT event request register 0x0210 (spec-notes §esc.events): bit 2 DL status change, bit 3
    /// AL status change, bits 4-11 SyncManager events of SMs with the ECAT IRQ enabled.
    pub(crate) fn ecat_event_request(&self) -> u16 {
        let mut events = 0u16;
        if self.events.dl_status {
            events |= 1 << 2;
        }
        if self.events.al_status {
            events |= 1 << 3;
        }
        for (n, sm) in self.sms.iter().enumerate().take(8) {
            if sm.config().active && sm.config().control().ecat_irq && sm.ecat_event() {
                events |= 1 << (4 + n);
            }
        }
        events
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use ecat_wire::command::Command;

    #[test]
    fn read_only_registers_ignore_writes_but_count() {
        let (mut esc, mut dev) = slave();
        let r = exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0000, &[0xFF; 10]);
        assert_eq!(r.wkc, 1);
        assert_eq!(esc.read_u8(0x0004), 8, "info block unchanged");
        let r = exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0130, &[0x08, 0]);
        assert_eq!(r.wkc, 1);
        assert_eq!(esc.read_u16(0x0130), 0x0001, "AL status unchanged");
    }

    #[test]
    fn register_access_is_clipped_at_0x1000() {
        let (mut esc, mut dev) = slave();
        let r = exec(&mut esc, &mut dev, Command::Aprd, 0, 0x0FFE, &[0xAA; 4]);
        assert_eq!(r.wkc, 1);
        assert_eq!(r.data, vec![0, 0, 0xAA, 0xAA], "RAM part untouched");
    }

    #[test]
    fn plain_ram_needs_an_fmmu() {
        let (mut esc, mut dev) = slave();
        let r = exec(&mut esc, &mut dev, Command::Apwr, 0, 0x1800, &[1, 2]);
        assert_eq!(r.wkc, 0, "unmapped RAM is blocked");
        // FMMU0: logical 0x10000, 2 bytes → physical 0x1800, read/write, enabled.
        let fmmu = [
            0x00, 0x00, 0x01, 0x00, 0x02, 0x00, 0x00, 0x07, 0x00, 0x18, 0x00, 0x03, 0x01, 0, 0, 0,
        ];
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0600, &fmmu);
        let r = exec(&mut esc, &mut dev, Command::Apwr, 0, 0x1800, &[1, 2]);
        assert_eq!(r.wkc, 1, "FMMU-mapped RAM is accessible");
        let r = exec(&mut esc, &mut dev, Command::Aprd, 0, 0x1800, &[0, 0, 0]);
        assert_eq!(r.wkc, 0, "not completely inside the mapping");
        let r = exec(&mut esc, &mut dev, Command::Aprd, 0, 0x3000, &[0]);
        assert_eq!(r.wkc, 0, "beyond the RAM");
    }

    #[test]
    fn esc_reset_sequence() {
        let (mut esc, mut dev) = slave();
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0010, &[0x01, 0x10]);
        for b in *b"RES" {
            exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0040, &[b]);
        }
        assert_eq!(esc.station_address(), 0, "reset to power-on values");
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0010, &[0x01, 0x10]);
        for b in *b"RXS" {
            exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0040, &[b]);
        }
        assert_eq!(esc.station_address(), 0x1001, "broken sequence");
    }
}
