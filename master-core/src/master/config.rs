//! How a master brings its segment up and watches it.

use std::time::Duration;

use crate::mailbox::MailboxConfig;

use super::bringup::dc_settings::DcSettings;
use crate::wire::register::AlState;

/// Settings of a [`Master`](super::Master).
///
/// Use struct update syntax for the fields you care about:
/// `MasterConfig { station_base: 0x1000, ..MasterConfig::default() }`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MasterConfig {
    /// Station address of the slave at position 0; position *p* gets `station_base + p`.
    /// Default 1001 (0x03E9), as IgH and the reference capture use (spec-notes §capture).
    pub station_base: u16,
    /// The state a scan brings every slave to, and the one the watch restores. Default OP.
    pub target_state: AlState,
    /// Longest wait for INIT → PREOP (and BOOT, and any step down). Default 3 s.
    pub preop_timeout: Duration,
    /// Longest wait for PREOP → SAFEOP; slaves check their process-data setup here, real
    /// ones may take seconds (IgH allows 10 s). Default 10 s.
    pub safeop_timeout: Duration,
    /// Longest wait for SAFEOP → OP. Default 10 s.
    pub op_timeout: Duration,
    /// Interval between two polls of AL status or of the EEPROM busy bit. Default 1 ms.
    pub poll_interval: Duration,
    /// Longest wait for one EEPROM command (real EEPROMs need a few ms per written word).
    /// Default 100 ms.
    pub eeprom_timeout: Duration,
    /// Largest SII image read, in words (IgH's `EC_MAX_SII_SIZE`). Default 4096.
    pub max_sii_words: u16,
    /// Period of the cyclic process-data exchange. Default 1 ms.
    pub cycle_period: Duration,
    /// How often the topology watch looks at the segment; `None`: no watch. Default 100 ms.
    pub watch_interval: Option<Duration>,
    /// Events kept for a subscriber that falls behind (older ones are dropped for it, and it
    /// is told how many). Default 256.
    pub event_capacity: usize,
    /// Settings of the mailbox engine that owns the slaves' mailboxes.
    pub mailbox: MailboxConfig,
    /// Map every mailbox slave's "mailbox full" bit (SM1 status 0x080D.3) into the cyclic
    /// frame through an FMMU, and let the mailbox engine read a mailbox when its bit is set
    /// instead of polling idle mailboxes: with this on, [`MailboxConfig::idle_poll`] is
    /// ignored (taken as `None`). Slaves without an FMMU to spare are then read only
    /// while a request waits for an answer. Default true.
    pub map_mailbox_status: bool,
    /// Distributed clocks: delays, offsets, the cyclic reference time, SYNC0.
    pub dc: DcSettings,
}

impl Default for MasterConfig {
    fn default() -> MasterConfig {
        MasterConfig {
            station_base: 1001,
            target_state: AlState::Op,
            preop_timeout: Duration::from_secs(3),
            safeop_timeout: Duration::from_secs(10),
            op_timeout: Duration::from_secs(10),
            poll_interval: Duration::from_millis(1),
            eeprom_timeout: Duration::from_millis(100),
            max_sii_words: 4096,
            cycle_period: crate::bus::DEFAULT_PERIOD,
            watch_interval: Some(Duration::from_millis(100)),
            event_capacity: 256,
            mailbox: MailboxConfig::default(),
            map_mailbox_status: true,
            dc: DcSettings::default(),
        }
    }
}

impl MasterConfig {
    /// The station address of ring position `position`, if it fits in 16 bits.
    pub fn station_of(&self, position: u16) -> Option<u16> {
        self.station_base.checked_add(position)
    }

    /// How long a change into `to` may take.
    pub fn timeout_for(&self, to: AlState) -> Duration {
        match to {
            AlState::SafeOp => self.safeop_timeout,
            AlState::Op => self.op_timeout,
            _ => self.preop_timeout,
        }
    }
}
