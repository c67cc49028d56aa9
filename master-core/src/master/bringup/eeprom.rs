//! The SII EEPROM interface 0x0500–0x050F of one slave (spec-notes §esc.sii-if): read, write, reload,
//! and reading a whole image (ETG.2010, spec-notes §sii).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use tokio::time::Instant;

use crate::bus::BusHandle;
use crate::wire::register::address as reg;
use crate::wire::register::eeprom::{CONFIG_ECAT_ACCESS, CONFIG_FORCE_ECAT};
use crate::wire::register::{EepromCommand, EepromControl, EepromRequest, EepromRequestRepr};
use crate::wire::sii::CategoryType;
use crate::wire::sii::category::CATEGORY_HEADER_LEN;
use crate::wire::sii::fixed::{CATEGORY_START_WORD, FIXED_LEN};

use crate::master::access::datagram::{fprd, fpwr};
use crate::master::error::MasterError;

/// How often a command that reports a missing acknowledge (bit 13) is tried (SOEM: 3).
const NACK_TRIES: u32 = 3;

/// The interface registers read in one datagram: control/status (0x0502), address
/// (0x0504) and data (0x0508, 8 bytes; an ESC with 4-byte reads uses the first 4).
const INTERFACE_LEN: usize = (reg::EEPROM_DATA - reg::EEPROM_CONTROL) as usize + 8;

/// The interface as one read saw it.
struct Interface {
    status: EepromControl,
    data: [u8; 8],
}

/// One slave's EEPROM interface.
pub(crate) struct Eeprom<'a> {
    bus: &'a BusHandle,
    station: u16,
    poll: Duration,
    timeout: Duration,
    /// The last status this master read was idle without error, and nothing was written
    /// since: the next command needs no check first. An SII image is hundreds of reads, and
    /// the check was one frame round trip of four per read.
    idle: AtomicBool,
}

impl<'a> Eeprom<'a> {
    /// The interface of the slave at `station`, polled every `poll` while busy, for at most
    /// `timeout` per wait.
    pub fn new(bus: &'a BusHandle, station: u16, poll: Duration, timeout: Duration) -> Self {
        Eeprom {
            bus,
            station,
            poll,
            timeout,
            idle: AtomicBool::new(false),
        }
    }

    fn error(&self, reason: &'static str) -> MasterError {
        MasterError::Eeprom {
            station: self.station,
            reason,
        }
    }

    /// Takes the EEPROM away from the PDI and gives it to the master (SOEM: 0x02, then 0).
    pub async fn take(&self) -> Result<(), MasterError> {
        let what = "EEPROM owner";
        fpwr(
            self.bus,
            self.station,
            reg::EEPROM_CONFIG,
            [CONFIG_FORCE_ECAT],
            what,
        )
        .await?;
        fpwr(
            self.bus,
            self.station,
            reg::EEPROM_CONFIG,
            [CONFIG_ECAT_ACCESS],
            what,
        )
        .await
    }

    /// Reads status and data together: a finished read command's data come with
    /// the status that says they are there, one round trip instead of two.
    async fn interface(&self) -> Result<Interface, MasterError> {
        let bytes = fprd(
            self.bus,
            self.station,
            reg::EEPROM_CONTROL,
            INTERFACE_LEN,
            "EEPROM status",
        )
        .await?;
        let status = EepromControl::parse(&bytes).map_err(|_| self.error("status unreadable"))?;
        let at = usize::from(reg::EEPROM_DATA - reg::EEPROM_CONTROL);
        let Some(data) = bytes.get(at..at + 8) else {
            return Err(self.error("status unreadable"));
        };
        let mut interface = Interface {
            status,
            data: [0; 8],
        };
        interface.data.copy_from_slice(data);
        Ok(interface)
    }

    /// Polls until the interface is not busy.
    async fn not_busy(&self) -> Result<Interface, MasterError> {
        let deadline = Instant::now() + self.timeout;
        loop {
            let interface = self.interface().await?;
            if !interface.status.busy {
                self.idle
                    .store(!interface.status.has_error(), Ordering::Relaxed);
                return Ok(interface);
            }
            if Instant::now() >= deadline {
                return Err(self.error("stays busy"));
            }
            tokio::time::sleep(self.poll).await;
        }
    }

    /// Waits until idle and clears error bits left by an earlier command.
    async fn idle(&self) -> Result<(), MasterError> {
        if self.idle.load(Ordering::Relaxed) {
            return Ok(());
        }
        let status = self.not_busy().await?.status;
        if !status.has_error() {
            return Ok(());
        }
        let clear = [0u8; 2];
        fpwr(
            self.bus,
            self.station,
            reg::EEPROM_CONTROL,
            clear,
            "EEPROM clear",
        )
        .await?;
        self.not_busy().await.map(drop)
    }

    /// Issues `request` and waits for it to finish; returns the interface after it.
    async fn command(&self, request: EepromRequestRepr) -> Result<Interface, MasterError> {
        let mut bytes = [0u8; crate::wire::register::eeprom::REQUEST_LEN];
        request
            .emit(&mut EepromRequest::new_unchecked(&mut bytes[..]))
            .map_err(|_| self.error("request not encodable"))?;
        for _ in 0..NACK_TRIES {
            self.idle().await?;
            self.idle.store(false, Ordering::Relaxed);
            fpwr(
                self.bus,
                self.station,
                reg::EEPROM_CONTROL,
                bytes,
                "EEPROM command",
            )
            .await?;
            let interface = self.not_busy().await?;
            let status = &interface.status;
            if status.ack_error {
                tokio::time::sleep(self.poll).await;
                continue;
            }
            if status.write_enable_error {
                return Err(self.error("refused a write without write enable"));
            }
            // The checksum bit describes the configuration area, not this command.
            return Ok(interface);
        }
        Err(self.error("does not acknowledge"))
    }

    /// Reads the 2 or 4 words at `word` (as many as the slave returns per read).
    pub async fn read(&self, word: u16) -> Result<Vec<u16>, MasterError> {
        let interface = self.command(EepromRequestRepr::read(word)).await?;
        let data = &interface.data[..interface.status.read_size()];
        Ok(crate::wire::register::eeprom::data_words(data).collect())
    }

    /// Writes one word.
    pub async fn write(&self, word: u16, value: u16) -> Result<(), MasterError> {
        self.idle().await?;
        self.idle.store(false, Ordering::Relaxed);
        let data = value.to_le_bytes();
        fpwr(
            self.bus,
            self.station,
            reg::EEPROM_DATA,
            data,
            "EEPROM data",
        )
        .await?;
        self.command(EepromRequestRepr::write(word)).await.map(drop)
    }

    /// Makes the ESC load its configuration area (words 0-7: PDI settings, alias) again.
    pub async fn reload(&self) -> Result<(), MasterError> {
        let request = EepromRequestRepr {
            control: EepromControl::command(EepromCommand::Reload),
            address: 0,
        };
        let status = self.command(request).await?.status;
        if status.checksum_error {
            return Err(self.error("reload found a bad checksum"));
        }
        Ok(())
    }

    /// Reads the whole image: the fixed area, then the categories up to END (or the end of
    /// the EEPROM, or `max_words`), as SOEM and IgH walk it (ETG.2010, spec-notes §sii).
    pub async fn read_image(&self, max_words: u16) -> Result<Vec<u8>, MasterError> {
        let mut words: Vec<u16> = Vec::new();
        let fixed_words = (FIXED_LEN / 2) as u16;
        self.fill(&mut words, fixed_words).await?;
        // Size word 0x3E: (value + 1) Kbit = (value + 1) × 64 words.
        let size_word = words.get(0x3E).copied().unwrap_or(0);
        let limit = (u32::from(size_word) + 1)
            .saturating_mul(64)
            .min(u32::from(max_words)) as u16;
        let mut at = CATEGORY_START_WORD;
        let header_words = (CATEGORY_HEADER_LEN / 2) as u16;
        // Where the image ends: after the END marker (kept, so that a parser sees where
        // the list stops), or after the last category that fits the EEPROM.
        let mut stop = at;
        while let Some(header_end) = at.checked_add(header_words).filter(|&e| e <= limit) {
            self.fill(&mut words, header_end).await?;
            let kind = words.get(usize::from(at)).copied().unwrap_or(0xFFFF);
            if kind == u16::from(CategoryType::End) {
                stop = at + 1;
                break;
            }
            let size = words.get(usize::from(at) + 1).copied().unwrap_or(0);
            let end = header_end.saturating_add(size).min(limit);
            self.fill(&mut words, end).await?;
            at = end;
            stop = end;
            if end >= limit {
                break;
            }
        }
        // Reads come in chunks of 2 or 4 words: drop what lies beyond the image.
        words.truncate(usize::from(stop).max(FIXED_LEN / 2));
        Ok(words.iter().flat_map(|w| w.to_le_bytes()).collect())
    }

    /// Reads words until `words` holds at least `until` of them.
    async fn fill(&self, words: &mut Vec<u16>, until: u16) -> Result<(), MasterError> {
        while words.len() < usize::from(until) {
            let at = u16::try_from(words.len()).map_err(|_| self.error("image too large"))?;
            let chunk = self.read(at).await?;
            if chunk.is_empty() {
                return Err(self.error("returned no data"));
            }
            words.extend(chunk);
        }
        Ok(())
    }
}
