//! The process-data watchdog (spec-notes §esc.watchdog, §esc.emulation): ECAT writes to a SyncManager with the
//! watchdog-trigger bit (control bit 6) restart it; when it runs out while the slave is in
//! OP, the slave falls back to SAFEOP with error 0x001B, 0x0440 bit 0 drops to 0 and the
//! expiry counter 0x0442 counts up.
//!
//! Expiry is noticed when a frame passes, at that frame's time-base instant, and also
//! between frames ([`Esc::idle`]): a real ESC counts its watchdog in hardware, so a slave
//! behind a cut cable, which sees no frame at all, still falls back to SAFEOP on time.

use ecat_wire::register::address as reg;
use ecat_wire::register::al::AlState;
use ecat_wire::register::al_status_code::AlStatusCode;

use crate::device::Device;

use super::Esc;

/// One watchdog tick is (divider + 2) × 40 ns (a 25 MHz clock, spec-notes §esc.watchdog).
const TICK_BASE_NS: u64 = 40;

impl Esc {
    /// An ECAT write reached SM `n`: restart the watchdog if the SM triggers it.
    pub(crate) fn watchdog_write(&mut self, n: usize) {
        let triggers = self
            .sms
            .get(n)
            .is_some_and(|sm| sm.config().control().watchdog);
        if triggers {
            self.watchdog_trigger = Some(self.frame.port0_ns);
            self.mem
                .set_u16(reg::WATCHDOG_STATUS_PROCESS_DATA.into(), 1);
        }
    }

    /// The process-data watchdog time in ns; `None` when disabled (time 0).
    fn watchdog_timeout_ns(&self) -> Option<u64> {
        let divider = u64::from(self.mem.u16(reg::WATCHDOG_DIVIDER.into()));
        let ticks = u64::from(self.mem.u16(reg::WATCHDOG_TIME_PROCESS_DATA.into()));
        (ticks > 0).then(|| (divider + 2) * TICK_BASE_NS * ticks)
    }

    /// Time passes at `now_ns` without a frame: the watchdog runs out as it would in the
    /// ESC's hardware. The segment calls this for slaves no frame reaches, and the
    /// simulator's frame loop when the wire is silent.
    pub fn idle(&mut self, now_ns: u64, device: &mut dyn Device) {
        self.check_watchdog(now_ns, device);
    }

    /// At `now_ns` (a frame's arrival, or an idle instant): has the watchdog run out?
    pub(crate) fn check_watchdog(&mut self, now_ns: u64, device: &mut dyn Device) {
        let Some(timeout) = self.watchdog_timeout_ns() else {
            return;
        };
        let Some(last) = self.watchdog_trigger else {
            return;
        };
        if now_ns.saturating_sub(last) <= timeout {
            return;
        }
        self.watchdog_trigger = None;
        self.mem
            .set_u16(reg::WATCHDOG_STATUS_PROCESS_DATA.into(), 0);
        let counter = u32::from(reg::WATCHDOG_COUNTER_PROCESS_DATA);
        let count = self.mem.u8(counter).saturating_add(1);
        self.mem.set_u8(counter, count);
        if self.al_state() == AlState::Op {
            let ctx = self.device_context();
            // The fall-back is not the device's choice; its answer does not matter.
            let _ = device.state_change(AlState::Op, AlState::SafeOp, &ctx);
            self.set_al_status(AlState::SafeOp, true, AlStatusCode::SmWatchdog);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::FrameTiming;
    use super::super::test_support::*;
    use ecat_wire::command::Command;

    fn at(esc: &mut super::Esc, dev: &mut TestDevice, ns: u64) {
        let timing = FrameTiming {
            port0_ns: ns,
            port1_ns: None,
        };
        esc.process_frame(&mut [], dev, timing);
    }

    #[test]
    fn missing_outputs_drop_op_to_safeop() {
        let (mut esc, mut dev) = slave();
        dev.sizes.outputs = 1;
        bring_to_preop(&mut esc, &mut dev);
        configure_process_data(&mut esc, &mut dev, 1, 0);
        assert_eq!(request(&mut esc, &mut dev, 0x0004), (0x0004, 0));
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x1100, &[1]);
        assert_eq!(request(&mut esc, &mut dev, 0x0008), (0x0008, 0));
        at(&mut esc, &mut dev, 100_000_000);
        assert_eq!(esc.read_u16(0x0130), 0x0008, "exactly 100 ms: still fine");
        at(&mut esc, &mut dev, 100_000_001);
        assert_eq!(esc.read_u16(0x0130), 0x0014);
        assert_eq!(esc.read_u16(0x0134), 0x001B);
        assert_eq!(esc.read_u16(0x0440) & 1, 0);
        assert_eq!(esc.read_u8(0x0442), 1);
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x1100, &[2]);
        assert_eq!(esc.read_u16(0x0440) & 1, 1, "running again");
    }

    #[test]
    fn disabled_watchdog_never_expires() {
        let (mut esc, mut dev) = slave();
        dev.sizes.outputs = 1;
        bring_to_preop(&mut esc, &mut dev);
        configure_process_data(&mut esc, &mut dev, 1, 0);
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0420, &[0, 0]);
        request(&mut esc, &mut dev, 0x0004);
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x1100, &[1]);
        request(&mut esc, &mut dev, 0x0008);
        at(&mut esc, &mut dev, u64::MAX);
        assert_eq!(esc.read_u16(0x0130), 0x0008);
    }

    #[test]
    fn the_watchdog_runs_out_without_a_frame() {
        let (mut esc, mut dev) = slave();
        dev.sizes.outputs = 1;
        bring_to_preop(&mut esc, &mut dev);
        configure_process_data(&mut esc, &mut dev, 1, 0);
        request(&mut esc, &mut dev, 0x0004);
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x1100, &[1]);
        request(&mut esc, &mut dev, 0x0008);
        esc.idle(100_000_000, &mut dev);
        assert_eq!(esc.read_u16(0x0130), 0x0008, "exactly 100 ms: still fine");
        esc.idle(100_000_001, &mut dev);
        assert_eq!(esc.read_u16(0x0130), 0x0014);
        assert_eq!(esc.read_u16(0x0134), 0x001B);
        assert_eq!(esc.read_u8(0x0442), 1);
        esc.idle(200_000_000, &mut dev);
        assert_eq!(esc.read_u8(0x0442), 1, "an expired watchdog counts once");
    }
}
