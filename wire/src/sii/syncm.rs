//! SYNCM category, type 41: 8 bytes per SyncManager (ETG.2010, spec-notes §sii.categories).
//!
//! ```text
//! 0 u16 physical start | 2 u16 default length | 4 u8 control (0x0804 layout)
//! 5 u8 status (0) | 6 u8 enable flags | 7 u8 SM type
//! ```
//! The SM index is the entry's position in the list.

use core::fmt;

use crate::error::{Result, WireError, room};
use crate::field::{self, Field};
use crate::macros::enum_with_unknown;
use crate::register::sync_manager::{SmControl, SmDirection, SmMode};

mod fields {
    use super::Field;
    pub const START: Field = 0..2;
    pub const LENGTH: Field = 2..4;
    pub const CONTROL: usize = 4;
    pub const STATUS: usize = 5;
    pub const ENABLE: usize = 6;
    pub const TYPE: usize = 7;
}

/// Size of one SYNCM entry.
pub const SYNCM_ENTRY_LEN: usize = fields::TYPE + 1;

enum_with_unknown! {
    /// SyncManager type, byte 7.
    pub enum SyncmType(u8) {
        /// 0: unused / unknown (infer from control).
        Unspecified = 0,
        /// 1: mailbox out (master → slave).
        MailboxOut = 1,
        /// 2: mailbox in (slave → master).
        MailboxIn = 2,
        /// 3: process data outputs.
        Outputs = 3,
        /// 4: process data inputs.
        Inputs = 4,
    }
}

impl SyncmType {
    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            SyncmType::Unspecified => "unspecified",
            SyncmType::MailboxOut => "mailbox out",
            SyncmType::MailboxIn => "mailbox in",
            SyncmType::Outputs => "outputs",
            SyncmType::Inputs => "inputs",
            SyncmType::Unknown(_) => "unknown",
        }
    }
}

/// Enable flags, byte 6.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SyncmEnable(pub u8);

impl SyncmEnable {
    /// Bit 0: enable.
    pub fn enable(self) -> bool {
        self.0 & 0x01 != 0
    }
    /// Bit 1: fixed content (configuration tool information).
    pub fn fixed_content(self) -> bool {
        self.0 & 0x02 != 0
    }
    /// Bit 2: virtual SyncManager (no hardware).
    pub fn virtual_sm(self) -> bool {
        self.0 & 0x04 != 0
    }
    /// Bit 3: enabled in OP only.
    pub fn op_only(self) -> bool {
        self.0 & 0x08 != 0
    }
}

/// One SYNCM entry. The control byte is kept raw so that an image round-trips exactly.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SyncmEntry {
    /// Physical start address.
    pub start: u16,
    /// Default length (0 = computed from the PDOs).
    pub length: u16,
    /// Control byte (register 0x0804 layout).
    pub control: u8,
    /// Status byte (don't care, normally 0).
    pub status: u8,
    /// Enable flags.
    pub enable: SyncmEnable,
    /// SM type as stored (may be `Unspecified`).
    pub sm_type: SyncmType,
}

impl Default for SyncmEntry {
    /// An all-zero entry (type unspecified).
    fn default() -> Self {
        SyncmEntry {
            start: 0,
            length: 0,
            control: 0,
            status: 0,
            enable: SyncmEnable(0),
            sm_type: SyncmType::Unspecified,
        }
    }
}

impl SyncmEntry {
    /// The decoded control byte.
    pub fn control(&self) -> SmControl {
        SmControl::decode(self.control)
    }

    /// The type, inferred from control when the stored type is 0 (ethercrab's rule):
    /// mailbox/write → mailbox out, mailbox/read → mailbox in, buffered/write → outputs,
    /// buffered/read → inputs. Reserved mode/direction codes stay `Unspecified`.
    pub fn effective_type(&self) -> SyncmType {
        if self.sm_type != SyncmType::Unspecified {
            return self.sm_type;
        }
        let c = self.control();
        match (c.mode, c.direction) {
            (SmMode::Mailbox, SmDirection::Write) => SyncmType::MailboxOut,
            (SmMode::Mailbox, SmDirection::Read) => SyncmType::MailboxIn,
            (SmMode::Buffered, SmDirection::Write) => SyncmType::Outputs,
            (SmMode::Buffered, SmDirection::Read) => SyncmType::Inputs,
            _ => SyncmType::Unspecified,
        }
    }

    /// Parses one 8-byte entry.
    pub fn parse(data: &[u8]) -> Result<Self> {
        crate::error::need("SII SYNCM entry", data, SYNCM_ENTRY_LEN)?;
        Ok(SyncmEntry {
            start: field::u16_le(data, fields::START.start),
            length: field::u16_le(data, fields::LENGTH.start),
            control: data[fields::CONTROL],
            status: data[fields::STATUS],
            enable: SyncmEnable(data[fields::ENABLE]),
            sm_type: SyncmType::from(data[fields::TYPE]),
        })
    }

    /// Writes one 8-byte entry.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        room("SII SYNCM entry", buf, SYNCM_ENTRY_LEN)?;
        field::set_u16_le(buf, fields::START.start, self.start);
        field::set_u16_le(buf, fields::LENGTH.start, self.length);
        buf[fields::CONTROL] = self.control;
        buf[fields::STATUS] = self.status;
        buf[fields::ENABLE] = self.enable.0;
        buf[fields::TYPE] = u8::from(self.sm_type);
        Ok(())
    }
}

impl fmt::Display for SyncmEntry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "SYNCM start={:#06x} len={} ctrl={:#04x} enable={:#04x} {}",
            self.start,
            self.length,
            self.control,
            self.enable.0,
            self.effective_type().name()
        )
    }
}

/// The parsed SYNCM category.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Default)]
pub struct SyncmCategoryRepr {
    /// Entries in SM order.
    pub entries: Vec<SyncmEntry>,
}

impl SyncmCategoryRepr {
    /// Parses the category data; its length must be a multiple of 8 (`BadLength`).
    pub fn parse(data: &[u8]) -> Result<Self> {
        if !data.len().is_multiple_of(SYNCM_ENTRY_LEN) {
            return Err(WireError::BadLength {
                what: "SII SYNCM",
                declared: data.len(),
                available: data.len() - data.len() % SYNCM_ENTRY_LEN,
            });
        }
        let entries = data
            .chunks_exact(SYNCM_ENTRY_LEN)
            .map(SyncmEntry::parse)
            .collect::<Result<_>>()?;
        Ok(SyncmCategoryRepr { entries })
    }

    /// Data length.
    pub fn buffer_len(&self) -> usize {
        self.entries.len() * SYNCM_ENTRY_LEN
    }

    /// Writes all entries.
    pub fn emit(&self, buf: &mut [u8]) -> Result<()> {
        room("SII SYNCM", buf, self.buffer_len())?;
        for (entry, out) in self
            .entries
            .iter()
            .zip(buf.chunks_exact_mut(SYNCM_ENTRY_LEN))
        {
            entry.emit(out)?;
        }
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::Emit;
    use proptest::prelude::*;

    // ETG.2010, spec-notes §sii.categories, EL2262: an output SM and a virtual input SM.
    static EL2262: [u8; 16] = [
        0x00, 0x10, 0x00, 0x00, 0x64, 0x00, 0x09, 0x03, 0x98, 0x09, 0x00, 0x00, 0x00, 0x00, 0x04,
        0x04,
    ];

    #[test]
    fn el2262_entries() {
        let r = SyncmCategoryRepr::parse(&EL2262).unwrap();
        let [sm0, sm1] = r.entries[..] else {
            panic!("two entries expected")
        };
        assert_eq!((sm0.start, sm0.length, sm0.control), (0x1000, 0, 0x64));
        assert!(sm0.enable.enable() && sm0.enable.op_only() && !sm0.enable.virtual_sm());
        assert_eq!(sm0.sm_type, SyncmType::Outputs);
        assert_eq!(sm0.control(), SmControl::OUTPUTS);
        assert_eq!((sm1.start, sm1.length), (0x0998, 0));
        assert!(sm1.enable.virtual_sm() && !sm1.enable.enable());
        assert_eq!(sm1.sm_type, SyncmType::Inputs);
        let mut out = [0xa5u8; 16];
        r.emit(&mut out).unwrap();
        assert_eq!(out, EL2262);
    }

    #[test]
    fn type_inference() {
        let mut e = SyncmEntry {
            control: 0x26,
            ..Default::default()
        };
        assert_eq!(e.effective_type(), SyncmType::MailboxOut);
        e.control = 0x22;
        assert_eq!(e.effective_type(), SyncmType::MailboxIn);
        e.control = 0x64;
        assert_eq!(e.effective_type(), SyncmType::Outputs);
        e.control = 0x20;
        assert_eq!(e.effective_type(), SyncmType::Inputs);
        e.control = 0x01; // reserved mode
        assert_eq!(e.effective_type(), SyncmType::Unspecified);
        e.sm_type = SyncmType::Inputs;
        assert_eq!(e.effective_type(), SyncmType::Inputs);
    }

    #[test]
    fn bad_length() {
        assert!(matches!(
            SyncmCategoryRepr::parse(&EL2262[..12]),
            Err(WireError::BadLength { .. })
        ));
    }

    pub(crate) fn arb_entry() -> impl Strategy<Value = SyncmEntry> {
        (
            any::<u16>(),
            any::<u16>(),
            proptest::array::uniform4(any::<u8>()),
        )
            .prop_map(|(start, length, b)| SyncmEntry {
                start,
                length,
                control: b[0],
                status: b[1],
                enable: SyncmEnable(b[2]),
                sm_type: SyncmType::from(b[3]),
            })
    }

    proptest! {
        #[test]
        fn round_trip(entries in proptest::collection::vec(arb_entry(), 0..8)) {
            let r = SyncmCategoryRepr { entries };
            let buf = r.to_vec().unwrap();
            prop_assert_eq!(SyncmCategoryRepr::parse(&buf).unwrap(), r);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
            if let Ok(r) = SyncmCategoryRepr::parse(&bytes) {
                for e in r.entries { let _ = e.to_string(); }
            }
        }
    }
}
