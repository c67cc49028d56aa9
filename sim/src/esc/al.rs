//! The AL state machine (ETG.1000.6, spec-notes §al): requests arrive in AL control 0x0120 and are
//! answered at once in AL status 0x0130 and AL status code 0x0134.
//!
//! The ESC runs the checks every slave firmware runs (mailbox SyncManagers on INIT →
//! PREOP/BOOT, process-data SyncManagers on PREOP → SAFEOP, valid outputs on SAFEOP → OP)
//! and then asks the device ([`Device::state_change`]), which may refuse with its own code.
//! Transitions to INIT always succeed. A refusal keeps the current state with the error
//! bit set; the error is held until a request with the acknowledge bit (0x10), or any INIT
//! request, clears it.

use ecat_wire::register::address as reg;
use ecat_wire::register::al::{AlControl, AlState, AlStatus};
use ecat_wire::register::al_status_code::AlStatusCode;
use ecat_wire::register::sync_manager::{SmActivate, SmControl, SmPdiControl};
use ecat_wire::sii::fixed::SiiMailboxArea;

use crate::device::{Device, ProcessDataSizes};

use super::Esc;
use super::mailbox::{MAILBOX_IN_SM, MAILBOX_OUT_SM};
use super::memory::SM_AREA_START;
use super::sync_manager::{self, SmConfig};

impl Esc {
    /// AL control was written: process the request.
    pub(crate) fn al_control_written(&mut self, device: &mut dyn Device) {
        if !self.eeprom.loaded() {
            // No EEPROM, no firmware: nobody answers.
            return;
        }
        let control = AlControl::decode(self.mem.u16(reg::AL_CONTROL.into()));
        let status = self.al_status();
        let acknowledged = control.ack || control.state == AlState::Init;
        if status.error {
            if !acknowledged {
                return;
            }
            self.set_al_status(status.state, false, AlStatusCode::NoError);
        }
        let current = status.state;
        if control.state == current {
            return;
        }
        if let AlState::Unknown(_) = control.state {
            self.set_al_status(current, true, AlStatusCode::UnknownRequestedState);
            return;
        }
        match self.transition(device, current, control.state) {
            Ok(()) => self.set_al_status(control.state, false, AlStatusCode::NoError),
            Err(code) => self.set_al_status(current, true, code),
        }
    }

    /// Writes AL status and code, raising the AL status change event when they change.
    pub(crate) fn set_al_status(&mut self, state: AlState, error: bool, code: AlStatusCode) {
        let status = AlStatus {
            state,
            error,
            id_loaded: false,
        };
        // States come from AlState values that fit 4 bits, so encoding cannot fail.
        let raw = status.encode().unwrap_or(u16::from(u8::from(state)) & 0x0F);
        let old = (
            self.mem.u16(reg::AL_STATUS.into()),
            self.mem.u16(reg::AL_STATUS_CODE.into()),
        );
        self.mem.set_u16(reg::AL_STATUS.into(), raw);
        self.mem
            .set_u16(reg::AL_STATUS_CODE.into(), u16::from(code));
        if old != (raw, u16::from(code)) {
            self.events.al_status = true;
        }
    }

    /// Checks and performs `from` → `to` (with `from` ≠ `to`, both known states).
    fn transition(
        &mut self,
        device: &mut dyn Device,
        from: AlState,
        to: AlState,
    ) -> Result<(), AlStatusCode> {
        use AlState::{Boot, Init, Op, PreOp, SafeOp};
        let info = self.eeprom.info();
        let mailbox_sms = [MAILBOX_OUT_SM, MAILBOX_IN_SM];
        let pd_sms: Vec<u8> = [info.outputs_sm, info.inputs_sm]
            .into_iter()
            .flatten()
            .collect();
        match (from, to) {
            (_, Init) => {
                // Going down to INIT cannot be refused; the device is told anyway.
                let _ = self.ask_device(device, from, to);
                self.watchdog_trigger = None;
                let all: Vec<u8> = (0..self.layout.sm_count).collect();
                self.set_sm_pdi_enabled(&all, false);
                self.mailbox.clear();
                Ok(())
            }
            (Init, PreOp) => {
                self.check_mailbox(info.std_rx, info.std_tx)
                    .map_err(|()| AlStatusCode::InvalidMailboxConfigPreop)?;
                // A slave without a mailbox has no mailbox SyncManagers to enable (its SM0/SM1
                // may carry process data, enabled on PREOP → SAFEOP).
                let has_mailbox = info.std_rx.is_present() || info.std_tx.is_present();
                let sms: &[u8] = if has_mailbox { &mailbox_sms } else { &[] };
                self.enable_then_ask(device, from, to, sms)
            }
            (Init, Boot) => {
                if !info.boot_supported() {
                    return Err(AlStatusCode::BootstrapNotSupported);
                }
                self.check_mailbox(info.boot_rx, info.boot_tx)
                    .map_err(|()| AlStatusCode::InvalidMailboxConfigBoot)?;
                self.enable_then_ask(device, from, to, &mailbox_sms)
            }
            (PreOp, SafeOp) => {
                self.check_process_data(device.process_data_sizes())?;
                self.enable_then_ask(device, from, to, &pd_sms)
            }
            (SafeOp, Op) => {
                let outputs = device.process_data_sizes().outputs;
                let written = info
                    .outputs_sm
                    .and_then(|n| self.sms.get(usize::from(n)))
                    .is_some_and(|sm| sm.has_complete_buffer());
                if outputs > 0 && !written {
                    return Err(AlStatusCode::NoValidOutputs);
                }
                self.ask_device(device, from, to)
            }
            (Op, SafeOp) => self.ask_device(device, from, to),
            (SafeOp | Op, PreOp) => {
                self.ask_device(device, from, to)?;
                self.set_sm_pdi_enabled(&pd_sms, false);
                // Without process data the watchdog has nothing to watch.
                self.watchdog_trigger = None;
                Ok(())
            }
            _ => Err(AlStatusCode::InvalidStateChange),
        }
    }

    /// Enables SyncManagers `sms` on the PDI side, then asks the device; a refusal disables
    /// them again.
    fn enable_then_ask(
        &mut self,
        device: &mut dyn Device,
        from: AlState,
        to: AlState,
        sms: &[u8],
    ) -> Result<(), AlStatusCode> {
        self.set_sm_pdi_enabled(sms, true);
        let answer = self.ask_device(device, from, to);
        if answer.is_err() {
            self.set_sm_pdi_enabled(sms, false);
        }
        answer
    }

    fn ask_device(
        &mut self,
        device: &mut dyn Device,
        from: AlState,
        to: AlState,
    ) -> Result<(), AlStatusCode> {
        let ctx = self.device_context();
        device.state_change(from, to, &ctx)
    }

    /// Sets or clears the PDI's "deactivate" bit (0x0807 + 8n bit 0) of SyncManagers `sms`.
    fn set_sm_pdi_enabled(&mut self, sms: &[u8], enabled: bool) {
        for &n in sms {
            if n >= self.layout.sm_count {
                continue;
            }
            sync_manager::update_registers(&mut self.mem, n, |sm| {
                let mut pdi = SmPdiControl::decode(sm.pdi_control_raw());
                pdi.deactivate = !enabled;
                sm.set_pdi_control_raw(pdi.encode());
            });
            self.sm_registers_written(n);
        }
    }

    /// The master's SM `n` settings, independent of the PDI's deactivate bit.
    fn master_sm(&self, n: u8) -> (SmConfig, bool) {
        let sm = sync_manager::registers(&self.mem, n);
        let config = SmConfig {
            start: sm.start(),
            length: sm.length(),
            control: sm.control_raw(),
            active: false,
        };
        let enabled = n < self.layout.sm_count && SmActivate::decode(sm.activate_raw()).enable;
        (config, enabled)
    }

    /// Whether SM `n` is enabled by the master with exactly `start`/`length`, the mode and
    /// direction of `kind` (its interrupt and watchdog bits are the master's choice) and a
    /// range the ESC can serve (digital I/O registers or RAM).
    fn sm_matches(&self, n: u8, start: u16, length: u16, kind: SmControl) -> bool {
        let (c, enabled) = self.master_sm(n);
        let control = c.control();
        enabled
            && c.start == start
            && c.length == length
            && control.mode == kind.mode
            && control.direction == kind.direction
            && u32::from(c.start) >= SM_AREA_START
            && c.end() <= self.mem.end()
    }

    /// INIT → PREOP/BOOT: SM0/SM1 must match the SII mailbox (spec-notes §mbx.handshake). A slave without
    /// a mailbox needs nothing.
    fn check_mailbox(&self, rx: SiiMailboxArea, tx: SiiMailboxArea) -> Result<(), ()> {
        if !rx.is_present() && !tx.is_present() {
            return Ok(());
        }
        let ok = self.sm_matches(MAILBOX_OUT_SM, rx.offset, rx.size, SmControl::MAILBOX_OUT)
            && self.sm_matches(MAILBOX_IN_SM, tx.offset, tx.size, SmControl::MAILBOX_IN);
        if ok { Ok(()) } else { Err(()) }
    }

    /// PREOP → SAFEOP: the process-data SyncManagers must be enabled, buffered, in the
    /// right direction and exactly as long as the device's process data; a device without
    /// outputs (inputs) accepts its SM only disabled or empty.
    fn check_process_data(&self, sizes: ProcessDataSizes) -> Result<(), AlStatusCode> {
        let info = self.eeprom.info();
        let check = |sm: Option<u8>, size: u16, kind: SmControl| -> bool {
            match sm {
                Some(n) if size > 0 => {
                    let (c, _) = self.master_sm(n);
                    self.sm_matches(n, c.start, size, kind)
                }
                Some(n) => {
                    let (c, enabled) = self.master_sm(n);
                    !enabled || c.length == 0
                }
                None => size == 0,
            }
        };
        if !check(info.outputs_sm, sizes.outputs, SmControl::OUTPUTS) {
            return Err(AlStatusCode::InvalidOutputConfig);
        }
        if !check(info.inputs_sm, sizes.inputs, SmControl::INPUTS) {
            return Err(AlStatusCode::InvalidInputConfig);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use super::*;
    use ecat_wire::command::Command;

    #[test]
    fn init_to_preop_checks_the_mailbox_sync_managers() {
        let (mut esc, mut dev) = slave();
        assert_eq!(request(&mut esc, &mut dev, 0x0002), (0x0011, 0x0016), "C.5");
        assert_eq!(
            request(&mut esc, &mut dev, 0x0002),
            (0x0011, 0x0016),
            "held"
        );
        configure_mailbox(&mut esc, &mut dev);
        assert_eq!(
            request(&mut esc, &mut dev, 0x0002),
            (0x0011, 0x0016),
            "no ack: ignored"
        );
        assert_eq!(
            request(&mut esc, &mut dev, 0x0012),
            (0x0002, 0),
            "ack + PREOP"
        );
        assert_eq!(dev.transitions, vec![(AlState::Init, AlState::PreOp)]);
        assert_eq!(esc.read_u8(0x0807) & 1, 0, "SM0 enabled by the PDI");
        assert_eq!(esc.read_u16(0x0120), 0x0012, "AL control reads back");
    }

    #[test]
    fn wrong_mailbox_settings_are_refused() {
        let (mut esc, mut dev) = slave();
        let mut sms = MAILBOX_SMS;
        sms[2] = 0x40; // SM0 length 64 instead of 128
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0800, &sms);
        assert_eq!(request(&mut esc, &mut dev, 0x0002), (0x0011, 0x0016));
        let mut sms = MAILBOX_SMS;
        sms[4] = 0x22; // SM0 in the wrong direction
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0800, &sms);
        assert_eq!(request(&mut esc, &mut dev, 0x0012), (0x0011, 0x0016));
        let mut sms = MAILBOX_SMS;
        sms[14] = 0; // SM1 not enabled
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0800, &sms);
        assert_eq!(request(&mut esc, &mut dev, 0x0012), (0x0011, 0x0016));
    }

    #[test]
    fn invalid_and_unknown_requests() {
        let (mut esc, mut dev) = slave();
        assert_eq!(
            request(&mut esc, &mut dev, 0x0004),
            (0x0011, 0x0011),
            "INIT → SAFEOP"
        );
        assert_eq!(
            request(&mut esc, &mut dev, 0x0018),
            (0x0011, 0x0011),
            "INIT → OP"
        );
        assert_eq!(
            request(&mut esc, &mut dev, 0x0015),
            (0x0011, 0x0012),
            "state 5"
        );
        assert_eq!(
            request(&mut esc, &mut dev, 0x0010),
            (0x0011, 0x0012),
            "state 0"
        );
        assert_eq!(
            request(&mut esc, &mut dev, 0x0013),
            (0x0011, 0x0013),
            "no BOOT"
        );
        assert_eq!(
            request(&mut esc, &mut dev, 0x0001),
            (0x0001, 0),
            "INIT acks"
        );
        bring_to_preop(&mut esc, &mut dev);
        assert_eq!(
            request(&mut esc, &mut dev, 0x0008),
            (0x0012, 0x0011),
            "PREOP → OP"
        );
        assert_eq!(
            request(&mut esc, &mut dev, 0x0013),
            (0x0012, 0x0011),
            "PREOP → BOOT"
        );
    }

    fn boot_image() -> Vec<u8> {
        let mut b = ecat_wire::sii::SiiBuilder::new(SiiFixedRepr {
            boot_rx_mailbox: SiiMailboxArea {
                offset: 0x1000,
                size: 244,
            },
            boot_tx_mailbox: SiiMailboxArea {
                offset: 0x1100,
                size: 244,
            },
            ..fixed()
        });
        b.syncm = syncm();
        b.build().unwrap()
    }

    use ecat_wire::sii::fixed::SiiFixedRepr;

    #[test]
    fn bootstrap() {
        let (mut esc, mut dev) = slave_with_image(boot_image());
        configure_mailbox(&mut esc, &mut dev);
        assert_eq!(
            request(&mut esc, &mut dev, 0x0003),
            (0x0011, 0x0015),
            "standard SMs"
        );
        let sms = [
            0x00, 0x10, 0xF4, 0x00, 0x26, 0x00, 0x01, 0x00, 0x00, 0x11, 0xF4, 0x00, 0x22, 0x00,
            0x01, 0x00,
        ];
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0800, &sms);
        assert_eq!(request(&mut esc, &mut dev, 0x0013), (0x0003, 0));
        assert_eq!(
            request(&mut esc, &mut dev, 0x0002),
            (0x0013, 0x0011),
            "BOOT → PREOP"
        );
        assert_eq!(
            request(&mut esc, &mut dev, 0x0004),
            (0x0013, 0x0011),
            "held, no ack"
        );
        assert_eq!(
            request(&mut esc, &mut dev, 0x0001),
            (0x0001, 0),
            "BOOT → INIT"
        );
    }

    #[test]
    fn preop_to_safeop_checks_process_data() {
        let (mut esc, mut dev) = slave();
        dev.sizes = ProcessDataSizes {
            outputs: 2,
            inputs: 1,
        };
        bring_to_preop(&mut esc, &mut dev);
        assert_eq!(
            request(&mut esc, &mut dev, 0x0004),
            (0x0012, 0x001D),
            "no SM2"
        );
        configure_process_data(&mut esc, &mut dev, 2, 0);
        assert_eq!(
            request(&mut esc, &mut dev, 0x0014),
            (0x0012, 0x001E),
            "no SM3"
        );
        configure_process_data(&mut esc, &mut dev, 3, 1);
        assert_eq!(
            request(&mut esc, &mut dev, 0x0014),
            (0x0012, 0x001D),
            "wrong length"
        );
        configure_process_data(&mut esc, &mut dev, 2, 1);
        assert_eq!(request(&mut esc, &mut dev, 0x0014), (0x0004, 0));
        assert_eq!(esc.read_u8(0x0817) & 1, 0, "SM2 enabled by the PDI");
        assert_eq!(
            request(&mut esc, &mut dev, 0x0008),
            (0x0014, 0x0019),
            "no outputs yet"
        );
        assert_eq!(
            exec(&mut esc, &mut dev, Command::Apwr, 0, 0x1100, &[1, 2]).wkc,
            1
        );
        assert_eq!(dev.outputs, vec![vec![1, 2]]);
        assert_eq!(request(&mut esc, &mut dev, 0x0018), (0x0008, 0));
        assert_eq!(
            request(&mut esc, &mut dev, 0x0004),
            (0x0004, 0),
            "OP → SAFEOP"
        );
        assert_eq!(
            request(&mut esc, &mut dev, 0x0002),
            (0x0002, 0),
            "SAFEOP → PREOP"
        );
        assert_eq!(esc.read_u8(0x0817) & 1, 1, "SM2 disabled again");
        assert_eq!(
            exec(&mut esc, &mut dev, Command::Apwr, 0, 0x1100, &[1, 2]).wkc,
            0
        );
    }

    #[test]
    fn device_without_process_data_accepts_empty_sms() {
        let (mut esc, mut dev) = slave();
        bring_to_preop(&mut esc, &mut dev);
        assert_eq!(request(&mut esc, &mut dev, 0x0004), (0x0004, 0));
        assert_eq!(request(&mut esc, &mut dev, 0x0008), (0x0008, 0));
        assert_eq!(
            request(&mut esc, &mut dev, 0x0001),
            (0x0001, 0),
            "OP → INIT"
        );
        assert_eq!(esc.read_u8(0x0807) & 1, 1, "mailbox SMs disabled");
    }

    #[test]
    fn device_refusal_keeps_the_state() {
        let (mut esc, mut dev) = slave();
        dev.refuse = Some((AlState::SafeOp, AlStatusCode::InconsistentSettings));
        bring_to_preop(&mut esc, &mut dev);
        assert_eq!(request(&mut esc, &mut dev, 0x0004), (0x0012, 0x0026));
        dev.refuse = None;
        assert_eq!(request(&mut esc, &mut dev, 0x0014), (0x0004, 0));
    }

    #[test]
    fn without_eeprom_nobody_answers() {
        let mut image = sii_image();
        image[14] ^= 0xFF;
        let (mut esc, mut dev) = slave_with_image(image);
        configure_mailbox(&mut esc, &mut dev);
        assert_eq!(request(&mut esc, &mut dev, 0x0002), (0x0001, 0));
    }
}
