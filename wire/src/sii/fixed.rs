//! The SII fixed area, words 0x00–0x3F = bytes 0–127 (ETG.2010, spec-notes §sii.fixed).
//!
//! ```text
//! word 0x00 PDI control        0x01 PDI config       0x02 SYNC impulse   0x03 PDI config 2
//! word 0x04 station alias      0x05-0x06 reserved    0x07 checksum (spec-notes §sii.fixed)
//! word 0x08 vendor (u32)       0x0A product (u32)    0x0C revision (u32) 0x0E serial (u32)
//! word 0x10 execution delay    0x11 port 0 delay     0x12 port 1 delay   0x13 reserved
//! word 0x14/0x15 bootstrap rx mailbox offset/size    0x16/0x17 bootstrap tx mailbox
//! word 0x18/0x19 standard rx mailbox offset/size     0x1A/0x1B standard tx mailbox
//! word 0x1C mailbox protocols  0x1D-0x3D reserved    0x3E size           0x3F version
//! ```

use core::fmt;

use super::checksum::{self, CHECKSUM_OFFSET};
use crate::error::{Result, need, room};
use crate::field::{self, Field};
use crate::mailbox::MailboxType;

mod fields {
    use super::Field;
    pub const PDI_CONTROL: Field = 0..2;
    pub const PDI_CONFIG: Field = 2..4;
    pub const SYNC_IMPULSE: Field = 4..6;
    pub const PDI_CONFIG2: Field = 6..8;
    pub const ALIAS: Field = 8..10;
    pub const RESERVED_5_6: Field = 10..14;
    pub const CHECKSUM: Field = 14..16;
    pub const VENDOR: Field = 16..20;
    pub const PRODUCT: Field = 20..24;
    pub const REVISION: Field = 24..28;
    pub const SERIAL: Field = 28..32;
    pub const EXECUTION_DELAY: Field = 32..34;
    pub const PORT0_DELAY: Field = 34..36;
    pub const PORT1_DELAY: Field = 36..38;
    pub const RESERVED_13: Field = 38..40;
    pub const BOOT_RX_MAILBOX: Field = 40..44;
    pub const BOOT_TX_MAILBOX: Field = 44..48;
    pub const STD_RX_MAILBOX: Field = 48..52;
    pub const STD_TX_MAILBOX: Field = 52..56;
    pub const MAILBOX_PROTOCOLS: Field = 56..58;
    pub const RESERVED_1D_3D: Field = 58..124;
    pub const SIZE: Field = 124..126;
    pub const VERSION: Field = 126..128;
}

/// Size of the fixed area in bytes (64 words).
pub const FIXED_LEN: usize = fields::VERSION.end;
/// Word address where the category list starts.
pub const CATEGORY_START_WORD: u16 = 0x40;
/// Word address of the station alias.
pub const ALIAS_WORD: u16 = 4;

/// Mailbox protocols supported, word 0x1C (spec-notes §sii.fixed). Only the low byte is used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct MailboxProtocols(pub u16);

impl MailboxProtocols {
    /// ADS over EtherCAT.
    pub const AOE: u16 = 0x0001;
    /// Ethernet over EtherCAT.
    pub const EOE: u16 = 0x0002;
    /// CANopen over EtherCAT.
    pub const COE: u16 = 0x0004;
    /// File access over EtherCAT.
    pub const FOE: u16 = 0x0008;
    /// Servo profile over EtherCAT.
    pub const SOE: u16 = 0x0010;
    /// Vendor specific over EtherCAT.
    pub const VOE: u16 = 0x0020;

    const NAMES: [(u16, &'static str); 6] = [
        (Self::AOE, "AoE"),
        (Self::EOE, "EoE"),
        (Self::COE, "CoE"),
        (Self::FOE, "FoE"),
        (Self::SOE, "SoE"),
        (Self::VOE, "VoE"),
    ];

    /// Whether all bits of `flag` are set.
    pub fn contains(self, flag: u16) -> bool {
        self.0 & flag == flag
    }

    /// CoE supported.
    pub fn coe(self) -> bool {
        self.contains(Self::COE)
    }
    /// EoE supported.
    pub fn eoe(self) -> bool {
        self.contains(Self::EOE)
    }
    /// FoE supported.
    pub fn foe(self) -> bool {
        self.contains(Self::FOE)
    }
    /// SoE supported.
    pub fn soe(self) -> bool {
        self.contains(Self::SOE)
    }
    /// AoE supported.
    pub fn aoe(self) -> bool {
        self.contains(Self::AOE)
    }
    /// VoE supported.
    pub fn voe(self) -> bool {
        self.contains(Self::VOE)
    }

    /// Every protocol (for a slave whose SII was not read).
    pub const ALL: MailboxProtocols = MailboxProtocols(0x3F);

    /// The bit of the mailbox type `protocol` in this word; 0 for the error type and unknown
    /// types.
    pub const fn bit(protocol: MailboxType) -> u16 {
        match protocol {
            MailboxType::Aoe => Self::AOE,
            MailboxType::Eoe => Self::EOE,
            MailboxType::Coe => Self::COE,
            MailboxType::Foe => Self::FOE,
            MailboxType::Soe => Self::SOE,
            MailboxType::Voe => Self::VOE,
            MailboxType::Error | MailboxType::Unknown(_) => 0,
        }
    }

    /// Whether the slave announces the mailbox type `protocol`.
    pub const fn supports(self, protocol: MailboxType) -> bool {
        let bit = Self::bit(protocol);
        bit != 0 && self.0 & bit == bit
    }
}

impl fmt::Display for MailboxProtocols {
    /// `CoE FoE`, or `none`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut first = true;
        for (bit, name) in Self::NAMES {
            if self.0 & bit != 0 {
                if !first {
                    f.write_str(" ")?;
                }
                f.write_str(name)?;
                first = false;
            }
        }
        if first {
            f.write_str("none")?;
        }
        Ok(())
    }
}

/// A mailbox area (offset + size in bytes) from the fixed area.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SiiMailboxArea {
    /// Physical start address (the SM start).
    pub offset: u16,
    /// Size in bytes (the SM length).
    pub size: u16,
}

impl SiiMailboxArea {
    /// Whether the area is configured (non-zero size).
    pub fn is_present(&self) -> bool {
        self.size != 0
    }
}

/// View of the 128-byte fixed area (or a whole image: only the first 128 bytes are read).
#[derive(Debug, Clone)]
pub struct SiiFixed<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> SiiFixed<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        SiiFixed { buffer }
    }

    /// Wraps a buffer and checks that the 128 bytes are present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let view = Self::new_unchecked(buffer);
        view.check_len()?;
        Ok(view)
    }

    /// Checks that the 128 bytes are present.
    pub fn check_len(&self) -> Result<()> {
        need("SII fixed area", self.buffer.as_ref(), FIXED_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    fn u16_at(&self, f: Field) -> u16 {
        field::u16_le(self.buffer.as_ref(), f.start)
    }

    fn u32_at(&self, f: Field) -> u32 {
        field::u32_le(self.buffer.as_ref(), f.start)
    }

    fn area_at(&self, f: Field) -> SiiMailboxArea {
        SiiMailboxArea {
            offset: field::u16_le(self.buffer.as_ref(), f.start),
            size: field::u16_le(self.buffer.as_ref(), f.start + 2),
        }
    }

    /// Word 0: PDI control (low byte → 0x0140, high byte → 0x0141).
    pub fn pdi_control(&self) -> u16 {
        self.u16_at(fields::PDI_CONTROL)
    }
    /// Word 1: PDI configuration.
    pub fn pdi_config(&self) -> u16 {
        self.u16_at(fields::PDI_CONFIG)
    }
    /// Word 2: SYNC impulse length (10 ns units).
    pub fn sync_impulse_len(&self) -> u16 {
        self.u16_at(fields::SYNC_IMPULSE)
    }
    /// Word 3: extended PDI configuration.
    pub fn pdi_config2(&self) -> u16 {
        self.u16_at(fields::PDI_CONFIG2)
    }
    /// Word 4: configured station alias.
    pub fn alias(&self) -> u16 {
        self.u16_at(fields::ALIAS)
    }
    /// Word 7: the stored checksum word.
    pub fn checksum_word(&self) -> u16 {
        self.u16_at(fields::CHECKSUM)
    }
    /// Whether the stored checksum matches words 0-6 (ETG.2010, spec-notes §sii.fixed).
    pub fn checksum_ok(&self) -> bool {
        checksum::checksum_ok(self.buffer.as_ref()).unwrap_or(false)
    }
    /// Vendor ID.
    pub fn vendor_id(&self) -> u32 {
        self.u32_at(fields::VENDOR)
    }
    /// Product code.
    pub fn product_code(&self) -> u32 {
        self.u32_at(fields::PRODUCT)
    }
    /// Revision number.
    pub fn revision(&self) -> u32 {
        self.u32_at(fields::REVISION)
    }
    /// Serial number.
    pub fn serial(&self) -> u32 {
        self.u32_at(fields::SERIAL)
    }
    /// Word 0x10: execution delay.
    pub fn execution_delay(&self) -> u16 {
        self.u16_at(fields::EXECUTION_DELAY)
    }
    /// Word 0x11: port 0 delay.
    pub fn port0_delay(&self) -> u16 {
        self.u16_at(fields::PORT0_DELAY)
    }
    /// Word 0x12: port 1 delay.
    pub fn port1_delay(&self) -> u16 {
        self.u16_at(fields::PORT1_DELAY)
    }
    /// Words 0x14/0x15: bootstrap receive mailbox (master → slave).
    pub fn boot_rx_mailbox(&self) -> SiiMailboxArea {
        self.area_at(fields::BOOT_RX_MAILBOX)
    }
    /// Words 0x16/0x17: bootstrap send mailbox (slave → master).
    pub fn boot_tx_mailbox(&self) -> SiiMailboxArea {
        self.area_at(fields::BOOT_TX_MAILBOX)
    }
    /// Words 0x18/0x19: standard receive mailbox (SM0).
    pub fn std_rx_mailbox(&self) -> SiiMailboxArea {
        self.area_at(fields::STD_RX_MAILBOX)
    }
    /// Words 0x1A/0x1B: standard send mailbox (SM1).
    pub fn std_tx_mailbox(&self) -> SiiMailboxArea {
        self.area_at(fields::STD_TX_MAILBOX)
    }
    /// Word 0x1C: mailbox protocols.
    pub fn mailbox_protocols(&self) -> MailboxProtocols {
        MailboxProtocols(self.u16_at(fields::MAILBOX_PROTOCOLS))
    }
    /// Word 0x3E: EEPROM size word ((value + 1) Kbit).
    pub fn size_word(&self) -> u16 {
        self.u16_at(fields::SIZE)
    }
    /// Word 0x3F: version.
    pub fn version(&self) -> u16 {
        self.u16_at(fields::VERSION)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> SiiFixed<T> {
    fn set_u16_at(&mut self, f: Field, v: u16) {
        field::set_u16_le(self.buffer.as_mut(), f.start, v)
    }

    fn set_u32_at(&mut self, f: Field, v: u32) {
        field::set_u32_le(self.buffer.as_mut(), f.start, v)
    }

    fn set_area_at(&mut self, f: Field, a: SiiMailboxArea) {
        field::set_u16_le(self.buffer.as_mut(), f.start, a.offset);
        field::set_u16_le(self.buffer.as_mut(), f.start + 2, a.size);
    }

    /// Sets the station alias (word 4) and recomputes the checksum (word 7).
    pub fn set_alias(&mut self, alias: u16) {
        self.set_u16_at(fields::ALIAS, alias);
        self.update_checksum();
    }

    /// Recomputes word 7 from words 0-6 (low byte = CRC, high byte = 0).
    pub fn update_checksum(&mut self) {
        let crc = checksum::crc8(&self.buffer.as_ref()[..checksum::CHECKSUM_SPAN]);
        self.set_u16_at(fields::CHECKSUM, u16::from(crc));
    }
}

/// The parsed fixed area.
///
/// The checksum is not a field: [`SiiFixedRepr::emit`] computes it, and the view's
/// [`SiiFixed::checksum_ok`] reports whether a read image carries a valid one. Reserved
/// words are dropped on parse and written as 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SiiFixedRepr {
    /// Word 0: PDI control / ESC configuration.
    pub pdi_control: u16,
    /// Word 1: PDI configuration.
    pub pdi_config: u16,
    /// Word 2: SYNC impulse length.
    pub sync_impulse_len: u16,
    /// Word 3: extended PDI configuration.
    pub pdi_config2: u16,
    /// Word 4: station alias.
    pub alias: u16,
    /// Vendor ID.
    pub vendor_id: u32,
    /// Product code.
    pub product_code: u32,
    /// Revision number.
    pub revision: u32,
    /// Serial number.
    pub serial: u32,
    /// Execution delay.
    pub execution_delay: u16,
    /// Port 0 delay.
    pub port0_delay: u16,
    /// Port 1 delay.
    pub port1_delay: u16,
    /// Bootstrap receive mailbox (master → slave).
    pub boot_rx_mailbox: SiiMailboxArea,
    /// Bootstrap send mailbox (slave → master).
    pub boot_tx_mailbox: SiiMailboxArea,
    /// Standard receive mailbox (SM0, master → slave).
    pub std_rx_mailbox: SiiMailboxArea,
    /// Standard send mailbox (SM1, slave → master).
    pub std_tx_mailbox: SiiMailboxArea,
    /// Mailbox protocols.
    pub mailbox_protocols: MailboxProtocols,
    /// EEPROM size word: (value + 1) Kbit.
    pub size_word: u16,
    /// Version (1).
    pub version: u16,
}

impl SiiFixedRepr {
    /// EEPROM size in bytes from the size word: (value + 1) Kbit = (value + 1) × 128 bytes.
    pub fn size_bytes(&self) -> usize {
        (usize::from(self.size_word) + 1) * 128
    }

    /// The size word for an EEPROM of `bytes` bytes (rounded up to whole Kbit, at least 1),
    /// or `None` beyond what the word can express.
    pub fn size_word_for(bytes: usize) -> Option<u16> {
        let kbit = bytes.div_ceil(128).max(1);
        u16::try_from(kbit - 1).ok()
    }

    /// ethercrab's rule: a mailbox exists if protocols are announced and both standard
    /// mailbox sizes are non-zero.
    pub fn has_mailbox(&self) -> bool {
        self.mailbox_protocols.0 != 0
            && self.std_rx_mailbox.is_present()
            && self.std_tx_mailbox.is_present()
    }

    /// Parses a checked view. A wrong checksum is not an error (see [`SiiFixed::checksum_ok`]).
    pub fn parse<T: AsRef<[u8]>>(view: &SiiFixed<T>) -> Result<Self> {
        view.check_len()?;
        Ok(SiiFixedRepr {
            pdi_control: view.pdi_control(),
            pdi_config: view.pdi_config(),
            sync_impulse_len: view.sync_impulse_len(),
            pdi_config2: view.pdi_config2(),
            alias: view.alias(),
            vendor_id: view.vendor_id(),
            product_code: view.product_code(),
            revision: view.revision(),
            serial: view.serial(),
            execution_delay: view.execution_delay(),
            port0_delay: view.port0_delay(),
            port1_delay: view.port1_delay(),
            boot_rx_mailbox: view.boot_rx_mailbox(),
            boot_tx_mailbox: view.boot_tx_mailbox(),
            std_rx_mailbox: view.std_rx_mailbox(),
            std_tx_mailbox: view.std_tx_mailbox(),
            mailbox_protocols: view.mailbox_protocols(),
            size_word: view.size_word(),
            version: view.version(),
        })
    }

    /// Bytes written by [`Self::emit`].
    pub const fn buffer_len(&self) -> usize {
        FIXED_LEN
    }

    /// Writes the 128 bytes, reserved words 0, and the checksum in word 7.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, view: &mut SiiFixed<T>) -> Result<()> {
        room("SII fixed area", view.buffer.as_ref(), FIXED_LEN)?;
        view.set_u16_at(fields::PDI_CONTROL, self.pdi_control);
        view.set_u16_at(fields::PDI_CONFIG, self.pdi_config);
        view.set_u16_at(fields::SYNC_IMPULSE, self.sync_impulse_len);
        view.set_u16_at(fields::PDI_CONFIG2, self.pdi_config2);
        view.set_u16_at(fields::ALIAS, self.alias);
        view.buffer.as_mut()[fields::RESERVED_5_6].fill(0);
        view.set_u32_at(fields::VENDOR, self.vendor_id);
        view.set_u32_at(fields::PRODUCT, self.product_code);
        view.set_u32_at(fields::REVISION, self.revision);
        view.set_u32_at(fields::SERIAL, self.serial);
        view.set_u16_at(fields::EXECUTION_DELAY, self.execution_delay);
        view.set_u16_at(fields::PORT0_DELAY, self.port0_delay);
        view.set_u16_at(fields::PORT1_DELAY, self.port1_delay);
        view.buffer.as_mut()[fields::RESERVED_13].fill(0);
        view.set_area_at(fields::BOOT_RX_MAILBOX, self.boot_rx_mailbox);
        view.set_area_at(fields::BOOT_TX_MAILBOX, self.boot_tx_mailbox);
        view.set_area_at(fields::STD_RX_MAILBOX, self.std_rx_mailbox);
        view.set_area_at(fields::STD_TX_MAILBOX, self.std_tx_mailbox);
        view.set_u16_at(fields::MAILBOX_PROTOCOLS, self.mailbox_protocols.0);
        view.buffer.as_mut()[fields::RESERVED_1D_3D].fill(0);
        view.set_u16_at(fields::SIZE, self.size_word);
        view.set_u16_at(fields::VERSION, self.version);
        view.update_checksum();
        Ok(())
    }
}

impl fmt::Display for SiiFixedRepr {
    /// `SII vendor 0x00000002 product 0x07d43052 rev 0x00100000 alias 0 mailbox none`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "SII vendor {:#010x} product {:#010x} rev {:#010x} serial {} alias {} mailbox {}",
            self.vendor_id,
            self.product_code,
            self.revision,
            self.serial,
            self.alias,
            self.mailbox_protocols
        )?;
        if self.std_rx_mailbox.is_present() {
            write!(
                f,
                " rx {:#06x}/{} tx {:#06x}/{}",
                self.std_rx_mailbox.offset,
                self.std_rx_mailbox.size,
                self.std_tx_mailbox.offset,
                self.std_tx_mailbox.size
            )?;
        }
        Ok(())
    }
}

/// Sets the station alias in an SII image (word 4) and recomputes the checksum byte
/// (low byte of word 7), as IgH's `ethercat alias` does (spec-notes §sii.alias): only bytes 8, 9 and
/// 14 change, so a master writes back words 4 and 7 (or words 0-7).
pub fn set_alias(image: &mut [u8], alias: u16) -> Result<()> {
    need("SII image", image, CHECKSUM_OFFSET + 2)?;
    field::set_u16_le(image, fields::ALIAS.start, alias);
    let crc = checksum::checksum(image)?;
    image[CHECKSUM_OFFSET] = crc;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The first 16 bytes of the EL2004 dump (spec-notes §sii.fixed) and its identity (spec-notes §esc.sii-if).
    fn el2004() -> Vec<u8> {
        let mut image = vec![0u8; FIXED_LEN];
        image[..16].copy_from_slice(&[
            0x04, 0x01, 0x00, 0x00, 0x00, 0x00, 0x0f, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
            0xd8, 0x00,
        ]);
        // Words 8-9: vendor 2; words 0x0A-0x0B: product 0x07D43052 (spec-notes §esc.sii-if).
        image[16..24].copy_from_slice(&[0x02, 0x00, 0x00, 0x00, 0x52, 0x30, 0xd4, 0x07]);
        // Size word 0x000F (2 KiB), version 1 (ETG.2010, spec-notes §sii.fixed "simple terminals").
        image[124..128].copy_from_slice(&[0x0f, 0x00, 0x01, 0x00]);
        image
    }

    #[test]
    fn el2004_fixed_area() {
        let image = el2004();
        let view = SiiFixed::new_checked(&image[..]).unwrap();
        assert!(view.checksum_ok());
        let r = SiiFixedRepr::parse(&view).unwrap();
        assert_eq!(r.pdi_control, 0x0104);
        assert_eq!(r.sync_impulse_len, 0);
        assert_eq!(r.pdi_config2, 0x000f);
        assert_eq!((r.vendor_id, r.product_code), (2, 0x07D4_3052));
        assert_eq!(r.size_word, 0x000F);
        assert_eq!(r.size_bytes(), 2048);
        assert_eq!(r.version, 1);
        assert!(!r.has_mailbox());
        let mut out = vec![0xa5u8; FIXED_LEN];
        r.emit(&mut SiiFixed::new_unchecked(&mut out[..])).unwrap();
        assert_eq!(out, image);
    }

    #[test]
    fn bad_checksum_still_parses() {
        let mut image = el2004();
        image[14] = 0x00;
        let view = SiiFixed::new_checked(&image[..]).unwrap();
        assert!(!view.checksum_ok());
        assert!(SiiFixedRepr::parse(&view).is_ok());
    }

    #[test]
    fn alias_rewrite() {
        // EL2004 words 0-7 with alias 0x1001 written over them: only bytes 8, 9 and 14
        // change. CRC of `04 01 00 00 00 00 0f 00 01 10 00 00 00 00` worked out with the
        // bitwise algorithm of ETG.2010, spec-notes §sii.fixed (outside this crate): 0xC3.
        let mut image = el2004();
        set_alias(&mut image, 0x1001).unwrap();
        let mut expected = el2004();
        expected[8..10].copy_from_slice(&[0x01, 0x10]);
        expected[14] = 0xC3;
        assert_eq!(image, expected);
        // Back to alias 0 restores the dump's own checksum 0xD8.
        set_alias(&mut image, 0).unwrap();
        assert_eq!(image, el2004());
        // The view's setter agrees.
        let mut fixed = el2004();
        SiiFixed::new_unchecked(&mut fixed[..]).set_alias(0x1001);
        assert_eq!(fixed, expected);
        assert!(SiiFixed::new_checked(&fixed[..]).unwrap().checksum_ok());
        assert!(set_alias(&mut [0u8; 15], 1).is_err());
    }

    #[test]
    fn protocols_and_size() {
        let p = MailboxProtocols(MailboxProtocols::COE | MailboxProtocols::FOE);
        assert!(p.coe() && p.foe() && !p.eoe());
        assert_eq!(p.to_string(), "CoE FoE");
        assert_eq!(MailboxProtocols(0).to_string(), "none");
        assert_eq!(SiiFixedRepr::size_word_for(2048), Some(0x000F));
        assert_eq!(SiiFixedRepr::size_word_for(2049), Some(0x0010));
        assert_eq!(SiiFixedRepr::size_word_for(0), Some(0));
        assert!(SiiFixed::new_checked(&[0u8; 127][..]).is_err());
    }

    pub(crate) fn arb_area() -> impl Strategy<Value = SiiMailboxArea> {
        (any::<u16>(), any::<u16>()).prop_map(|(offset, size)| SiiMailboxArea { offset, size })
    }

    pub(crate) fn arb_fixed() -> impl Strategy<Value = SiiFixedRepr> {
        (
            proptest::array::uniform5(any::<u16>()),
            proptest::array::uniform4(any::<u32>()),
            proptest::array::uniform3(any::<u16>()),
            proptest::array::uniform4(arb_area()),
            proptest::array::uniform3(any::<u16>()),
        )
            .prop_map(|(w, id, d, mb, tail)| SiiFixedRepr {
                pdi_control: w[0],
                pdi_config: w[1],
                sync_impulse_len: w[2],
                pdi_config2: w[3],
                alias: w[4],
                vendor_id: id[0],
                product_code: id[1],
                revision: id[2],
                serial: id[3],
                execution_delay: d[0],
                port0_delay: d[1],
                port1_delay: d[2],
                boot_rx_mailbox: mb[0],
                boot_tx_mailbox: mb[1],
                std_rx_mailbox: mb[2],
                std_tx_mailbox: mb[3],
                mailbox_protocols: MailboxProtocols(tail[0]),
                size_word: tail[1],
                version: tail[2],
            })
    }

    proptest! {
        #[test]
        fn round_trip(repr in arb_fixed()) {
            let mut buf = [0u8; FIXED_LEN];
            repr.emit(&mut SiiFixed::new_unchecked(&mut buf[..])).unwrap();
            let view = SiiFixed::new_checked(&buf[..]).unwrap();
            prop_assert!(view.checksum_ok());
            prop_assert_eq!(SiiFixedRepr::parse(&view).unwrap(), repr);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..140)) {
            if let Ok(view) = SiiFixed::new_checked(&bytes[..]) {
                let _ = view.checksum_ok();
                let _ = SiiFixedRepr::parse(&view).map(|r| (r.to_string(), r.size_bytes()));
            }
            let mut b = bytes.clone();
            let _ = set_alias(&mut b, 7);
        }
    }
}
