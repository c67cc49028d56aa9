//! The emulated EtherCAT slave controller: commands, AL states, the EEPROM, mailboxes,
//! process data, DC, a whole segment and the quirks of other masters.

#[path = "../segment_support/mod.rs"]
mod segment_support;

mod al;
mod commands;
mod dc;
mod eeprom;
mod mailbox;
mod master_quirks;
mod process_data;
mod segment;
