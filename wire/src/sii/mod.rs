//! The SII / EEPROM image (ETG.2010, spec-notes §sii).
//!
//! [`checksum`] computes word 7; [`fixed`] is words 0x00–0x3F; [`category`] walks the
//! category list from word 0x40; [`strings`], [`general`], [`fmmu`], [`syncm`], [`pdo`] and
//! [`dc`] decode one category type each; [`image`] parses a whole image into typed parts and
//! [`builder`] emits one.

pub mod builder;
pub mod category;
pub mod checksum;
pub mod dc;
pub mod fixed;
pub mod fmmu;
pub mod general;
pub mod image;
pub mod pdo;
pub mod strings;
pub mod syncm;

pub use builder::SiiBuilder;
pub use category::{Category, CategoryIter, CategoryRepr, CategoryType};
pub use fixed::{MailboxProtocols, SiiFixed, SiiFixedRepr, SiiMailboxArea, set_alias};
pub use image::{SiiCategory, SiiImage};
