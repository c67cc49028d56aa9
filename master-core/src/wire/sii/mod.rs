//! The SII / EEPROM image (digest §4): fixed area, checksum, categories, and a builder.

pub mod category;
pub mod checksum;
pub mod dc;
pub mod fixed;
pub mod fmmu;
pub mod general;
pub mod pdo;
pub mod strings;
pub mod syncm;
