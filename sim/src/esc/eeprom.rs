//! The SII EEPROM and its register interface 0x0500-0x050F (spec-notes §esc.sii-if, §sii).
//!
//! Commands complete synchronously: a master never sees the busy bit. Reads return 4 or 8
//! bytes (0x0502 bit 6) and 0xFFFF for words beyond the image; a write needs the write
//! enable bit in the same register write (else error bit 14) and changes the image; a
//! reload re-applies the configuration area. On power-on and reload the ESC checks the
//! word-7 checksum: a bad one sets 0x0502 bit 11, loads nothing, and leaves the PDI
//! non-operational (DL status bit 0 = 0).

use ecat_wire::register::address as reg;
use ecat_wire::register::eeprom::{EepromCommand, EepromControl};
use ecat_wire::sii::checksum::checksum_ok;
use ecat_wire::sii::fixed::{SiiFixed, SiiFixedRepr, SiiMailboxArea};
use ecat_wire::sii::image::SiiImage;
use ecat_wire::sii::syncm::SyncmType;

use super::Esc;

/// EEPROMs up to 16 Kbit (2 KiB) take one address byte, larger ones two (0x0502 bit 7).
const ONE_ADDRESS_BYTE_LIMIT: usize = 2048;

/// What the slave firmware knows from its EEPROM: where the mailboxes are and which
/// SyncManagers carry process data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct SiiInfo {
    /// Standard receive mailbox (SM0 in PREOP and above).
    pub std_rx: SiiMailboxArea,
    /// Standard send mailbox (SM1).
    pub std_tx: SiiMailboxArea,
    /// Bootstrap receive mailbox (SM0 in BOOT).
    pub boot_rx: SiiMailboxArea,
    /// Bootstrap send mailbox (SM1 in BOOT).
    pub boot_tx: SiiMailboxArea,
    /// The SyncManager carrying outputs.
    pub outputs_sm: Option<u8>,
    /// The SyncManager carrying inputs.
    pub inputs_sm: Option<u8>,
}

impl SiiInfo {
    /// Reads the fixed area and the SYNCM category. Without a SYNCM category, process data
    /// uses SM2/SM3 when the slave has a mailbox and SM0/SM1 otherwise (the usual layouts).
    fn of(image: &[u8]) -> Self {
        let fixed = SiiFixed::new_checked(image)
            .ok()
            .and_then(|view| SiiFixedRepr::parse(&view).ok())
            .unwrap_or_default();
        let has_mailbox = fixed.std_rx_mailbox.is_present() || fixed.std_tx_mailbox.is_present();
        let (mut outputs_sm, mut inputs_sm) = if has_mailbox {
            (Some(2), Some(3))
        } else {
            (Some(0), Some(1))
        };
        if let Ok(sii) = SiiImage::parse(image)
            && !sii.syncm.is_empty()
        {
            let find = |ty: SyncmType| {
                sii.syncm
                    .iter()
                    .position(|e| e.effective_type() == ty)
                    .and_then(|n| u8::try_from(n).ok())
            };
            outputs_sm = find(SyncmType::Outputs);
            inputs_sm = find(SyncmType::Inputs);
        }
        SiiInfo {
            std_rx: fixed.std_rx_mailbox,
            std_tx: fixed.std_tx_mailbox,
            boot_rx: fixed.boot_rx_mailbox,
            boot_tx: fixed.boot_tx_mailbox,
            outputs_sm,
            inputs_sm,
        }
    }

    /// Whether the slave has a bootstrap mailbox, i.e. supports BOOT.
    pub fn boot_supported(&self) -> bool {
        self.boot_rx.is_present() && self.boot_tx.is_present()
    }
}

/// The EEPROM content and whether the ESC configuration was loaded from it.
#[derive(Debug, Clone)]
pub(crate) struct Eeprom {
    image: Vec<u8>,
    info: SiiInfo,
    loaded: bool,
}

impl Eeprom {
    /// An EEPROM holding `image` (an odd trailing byte is padded with 0xFF, like erased
    /// memory).
    pub fn new(mut image: Vec<u8>) -> Self {
        if !image.len().is_multiple_of(2) {
            image.push(0xFF);
        }
        Eeprom {
            info: SiiInfo::of(&image),
            image,
            loaded: false,
        }
    }

    /// The image.
    pub fn image(&self) -> &[u8] {
        &self.image
    }

    /// Firmware knowledge derived at the last load.
    pub fn info(&self) -> SiiInfo {
        self.info
    }

    /// Whether the configuration area was loaded (checksum good).
    pub fn loaded(&self) -> bool {
        self.loaded
    }

    /// Word `address`, 0xFFFF beyond the image.
    pub fn word(&self, address: u64) -> u16 {
        usize::try_from(address * 2)
            .ok()
            .and_then(|at| self.image.get(at..at + 2))
            .map_or(0xFFFF, |w| u16::from_le_bytes([w[0], w[1]]))
    }

    /// Writes word `address`; false beyond the image (the part does not acknowledge).
    pub fn set_word(&mut self, address: u64, value: u16) -> bool {
        let target = usize::try_from(address * 2)
            .ok()
            .and_then(|at| self.image.get_mut(at..at + 2));
        match target {
            Some(w) => {
                w.copy_from_slice(&value.to_le_bytes());
                true
            }
            None => false,
        }
    }
}

impl Esc {
    /// Whether 0x0500 bit 0 assigns the EEPROM to the PDI (ECAT commands are ignored).
    pub(crate) fn eeprom_assigned_to_pdi(&self) -> bool {
        self.mem.u8(reg::EEPROM_CONFIG.into()) & 0x01 != 0
    }

    fn eeprom_control(&self) -> EepromControl {
        EepromControl::decode(self.mem.u16(reg::EEPROM_CONTROL.into()))
    }

    fn set_eeprom_control(&mut self, control: EepromControl) {
        // Only NOP is ever stored as the command, so encoding cannot fail.
        if let Ok(raw) = control.encode() {
            self.mem.set_u16(reg::EEPROM_CONTROL.into(), raw);
        }
    }

    /// Loads the configuration area (power-on, reload): with a good checksum words 0-4 go
    /// to PDI control / ESC configuration, PDI configuration, SYNC pulse length, extended
    /// PDI configuration and station alias.
    pub(crate) fn load_eeprom_config(&mut self) {
        let image = self.eeprom.image();
        let ok = checksum_ok(image).unwrap_or(false);
        let mut control = self.eeprom_control();
        control.checksum_error = !ok;
        control.read_8_bytes = self.config.eeprom_read_8_bytes;
        control.two_address_bytes = image.len() > ONE_ADDRESS_BYTE_LIMIT;
        self.set_eeprom_control(control);
        if ok {
            let word = |n| self.eeprom.word(n);
            let (w0, w1, w2, w3, w4) = (word(0), word(1), word(2), word(3), word(4));
            self.mem.set_u16(reg::PDI_CONTROL.into(), w0);
            self.mem.set_u16(reg::PDI_CONFIG.into(), w1);
            if self.layout.dc {
                self.mem.set_u16(reg::DC_PULSE_LENGTH.into(), w2);
            }
            self.mem.set_u16(reg::PDI_CONFIG_EXT.into(), w3);
            self.mem.set_u16(reg::STATION_ALIAS.into(), w4);
        }
        self.eeprom.loaded = ok;
        self.eeprom.info = SiiInfo::of(self.eeprom.image());
        self.update_dl_status();
    }

    /// Executes the command just written to 0x0502 (ETG.1000.4, spec-notes §esc.sii-if).
    pub(crate) fn eeprom_command(&mut self) {
        let mut control = self.eeprom_control();
        let command = control.command;
        let write_enable = control.write_enable;
        control.command = EepromCommand::Nop;
        control.write_enable = false;
        control.busy = false;
        control.ack_error = false;
        control.write_enable_error = false;
        let address = u64::from(self.mem.u32(reg::EEPROM_ADDRESS.into()));
        match command {
            EepromCommand::Nop => {}
            EepromCommand::Read => {
                let words = control.read_size() / 2;
                for i in 0..words {
                    let value = self.eeprom.word(address + i as u64);
                    self.mem
                        .set_u16(u32::from(reg::EEPROM_DATA) + 2 * i as u32, value);
                }
            }
            EepromCommand::Write => {
                if !write_enable {
                    control.write_enable_error = true;
                } else {
                    let value = self.mem.u16(reg::EEPROM_DATA.into());
                    control.ack_error = !self.eeprom.set_word(address, value);
                }
            }
            EepromCommand::Reload => {}
            EepromCommand::Unknown(_) => control.ack_error = true,
        }
        self.set_eeprom_control(control);
        if command == EepromCommand::Reload {
            self.load_eeprom_config();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use ecat_wire::command::Command;

    fn read_word(esc: &mut super::Esc, dev: &mut TestDevice, word: u16) -> (Vec<u8>, u16) {
        let w = word.to_le_bytes();
        exec(
            esc,
            dev,
            Command::Apwr,
            0,
            0x0502,
            &[0x00, 0x01, w[0], w[1], 0, 0],
        );
        let status = exec(esc, dev, Command::Aprd, 0, 0x0502, &[0; 2]).data;
        let data = exec(esc, dev, Command::Aprd, 0, 0x0508, &[0; 8]).data;
        (data, u16::from_le_bytes([status[0], status[1]]))
    }

    #[test]
    fn reads_8_or_4_bytes_and_ffff_beyond_the_image() {
        let (mut esc, mut dev) = slave();
        let (data, status) = read_word(&mut esc, &mut dev, 0x0008);
        assert_eq!(&data[..4], &[0x02, 0, 0, 0], "vendor id 2");
        assert_eq!(&data[4..], &[0x34, 0x12, 0, 0], "product code");
        assert_eq!(status & 0x8000, 0, "never busy");
        assert_eq!(status & 0x0040, 0x0040, "8-byte reads");
        let len = esc.sii().len() as u16 / 2;
        let (data, _) = read_word(&mut esc, &mut dev, len - 1);
        assert_eq!(&data[2..], &[0xFF; 6]);

        let (mut esc, mut dev) = slave_with(|c| c.eeprom_read_8_bytes = false);
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0508, &[0xEE; 8]);
        let (data, status) = read_word(&mut esc, &mut dev, 0x0008);
        assert_eq!(status & 0x0040, 0);
        assert_eq!(data, vec![0x02, 0, 0, 0, 0xEE, 0xEE, 0xEE, 0xEE]);
    }

    #[test]
    fn write_needs_enable_in_the_same_write() {
        let (mut esc, mut dev) = slave();
        let before = esc.sii()[0x40..0x42].to_vec();
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0508, &[0x34, 0x12]);
        exec(
            &mut esc,
            &mut dev,
            Command::Apwr,
            0,
            0x0502,
            &[0x00, 0x02, 0x20, 0, 0, 0],
        );
        assert_eq!(esc.read_u16(0x0502) & 0x4000, 0x4000, "write enable error");
        assert_eq!(esc.sii()[0x40..0x42], before[..], "unchanged");
        exec(
            &mut esc,
            &mut dev,
            Command::Apwr,
            0,
            0x0502,
            &[0x01, 0x02, 0x20, 0, 0, 0],
        );
        let status = esc.read_u16(0x0502);
        assert_eq!(
            status & 0x7F01,
            0,
            "no error, enable self-cleared, command done"
        );
        assert_eq!(esc.sii()[0x40..0x42], [0x34, 0x12]);
        let beyond = (esc.sii().len() / 2) as u16;
        let b = beyond.to_le_bytes();
        exec(
            &mut esc,
            &mut dev,
            Command::Apwr,
            0,
            0x0502,
            &[0x01, 0x02, b[0], b[1], 0, 0],
        );
        assert_eq!(esc.read_u16(0x0502) & 0x2000, 0x2000, "no acknowledge");
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0502, &[0x00, 0x00]);
        assert_eq!(esc.read_u16(0x0502) & 0x7800, 0, "NOP clears errors");
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0502, &[0x00, 0x03]);
        assert_eq!(esc.read_u16(0x0502) & 0x2000, 0x2000, "invalid command");
    }

    #[test]
    fn igh_writes_command_address_and_data_in_one_datagram() {
        let (mut esc, mut dev) = slave();
        // 0x81: write enable + the (read-only) address-algorithm bit; 0x02: write.
        let r = exec(
            &mut esc,
            &mut dev,
            Command::Apwr,
            0,
            0x0502,
            &[0x81, 0x02, 0x21, 0, 0, 0, 0xEF, 0xBE],
        );
        assert_eq!(r.wkc, 1);
        assert_eq!(esc.sii()[0x42..0x44], [0xEF, 0xBE]);
        // IgH's read: 4 bytes at 0x0502, then 10 bytes from 0x0502 (status, address, data).
        exec(
            &mut esc,
            &mut dev,
            Command::Apwr,
            0,
            0x0502,
            &[0x80, 0x01, 0x21, 0x00],
        );
        let r = exec(&mut esc, &mut dev, Command::Aprd, 0, 0x0502, &[0; 10]);
        assert_eq!(r.data[1] & 0x87, 0, "not busy, command done");
        assert_eq!(r.data[6..8], [0xEF, 0xBE]);
    }

    #[test]
    fn alias_written_to_the_sii_applies_on_reload() {
        let (mut esc, mut dev) = slave();
        // Words 4 and 7: alias 0x0042 with a fresh checksum.
        let mut image = esc.sii().to_vec();
        ecat_wire::sii::set_alias(&mut image, 0x0042).unwrap();
        for word in [4u16, 7] {
            let at = usize::from(word) * 2;
            exec(
                &mut esc,
                &mut dev,
                Command::Apwr,
                0,
                0x0508,
                &image[at..at + 2],
            );
            exec(
                &mut esc,
                &mut dev,
                Command::Apwr,
                0,
                0x0502,
                &[0x01, 0x02, word as u8, 0, 0, 0],
            );
        }
        assert_eq!(esc.station_alias(), 0, "not before a reload");
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0502, &[0x00, 0x04]);
        assert_eq!(esc.station_alias(), 0x0042);
        assert_eq!(esc.read_u16(0x0502) & 0x0800, 0);
    }

    #[test]
    fn bad_checksum_loads_nothing() {
        let mut image = sii_image();
        image[8] = 0x99; // alias changed without fixing the checksum
        let (esc, _) = slave_with_image(image);
        assert_eq!(esc.read_u16(0x0502) & 0x0800, 0x0800);
        assert_eq!(esc.read_u16(0x0110) & 0x0001, 0, "PDI not operational");
        assert_eq!(esc.station_alias(), 0);
        assert!(!esc.pdi_operational());
    }

    #[test]
    fn pdi_owned_eeprom_ignores_ecat_commands() {
        let (mut esc, mut dev) = slave();
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0500, &[0x01]);
        let (data, _) = read_word(&mut esc, &mut dev, 0x0008);
        assert_eq!(data, vec![0; 8]);
    }
}
