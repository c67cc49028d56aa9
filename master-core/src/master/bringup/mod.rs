//! Bringing slaves up and keeping them up: the scan of the whole segment (`scan`), one
//! slave's configuration and walk through the AL states (`configure`), the register reset
//! before it (`reset`), the SII EEPROM interface (`eeprom`), AL state requests (`al`),
//! distributed clocks (`dc`, its settings and results in `dc_settings`), the mailbox engine kept in step with the slaves' states
//! (`mailboxes`), the topology watch that repeats the bring-up for a slave that comes
//! back (`watch`), and the per-slave configuration checked and applied at every bring-up:
//! expected identities, start-up commands, DC (`slave_config`, applied by `startup`).

pub(super) mod al;
mod api;
pub(super) mod configure;
pub(super) mod dc;
pub(super) mod dc_settings;
pub(super) mod eeprom;
pub(super) mod mailboxes;
pub(super) mod reset;
pub(super) mod safe_state;
pub(super) mod scan;
pub(super) mod slave_config;
pub(super) mod startup;
pub(super) mod watch;
