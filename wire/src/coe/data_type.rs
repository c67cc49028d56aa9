//! CoE data types, object codes and object access flags (spec-notes §coe.info, §coe.types; ETG.1000.6
//! data type index table, ETG.1020 base types).
//!
//! These are shared by the wire (SDO Information) and by object dictionaries on both sides
//! (the master's ETG.1510 dictionary and the simulator's CoE server).

use core::fmt;

use crate::macros::enum_with_unknown;

enum_with_unknown! {
    /// Data type index of an object or entry (u16, ETG.1000.6, spec-notes §coe.types).
    pub enum DataType(u16) {
        /// 0x0001 BOOLEAN (1 bit).
        Boolean = 0x0001,
        /// 0x0002 INTEGER8.
        Integer8 = 0x0002,
        /// 0x0003 INTEGER16.
        Integer16 = 0x0003,
        /// 0x0004 INTEGER32.
        Integer32 = 0x0004,
        /// 0x0005 UNSIGNED8.
        Unsigned8 = 0x0005,
        /// 0x0006 UNSIGNED16.
        Unsigned16 = 0x0006,
        /// 0x0007 UNSIGNED32.
        Unsigned32 = 0x0007,
        /// 0x0008 REAL32.
        Real32 = 0x0008,
        /// 0x0009 VISIBLE_STRING.
        VisibleString = 0x0009,
        /// 0x000A OCTET_STRING.
        OctetString = 0x000A,
        /// 0x000B UNICODE_STRING.
        UnicodeString = 0x000B,
        /// 0x000C TIME_OF_DAY (48 bits).
        TimeOfDay = 0x000C,
        /// 0x000D TIME_DIFFERENCE (48 bits).
        TimeDifference = 0x000D,
        /// 0x000F DOMAIN.
        Domain = 0x000F,
        /// 0x0010 INTEGER24.
        Integer24 = 0x0010,
        /// 0x0011 REAL64.
        Real64 = 0x0011,
        /// 0x0012 INTEGER40.
        Integer40 = 0x0012,
        /// 0x0013 INTEGER48.
        Integer48 = 0x0013,
        /// 0x0014 INTEGER56.
        Integer56 = 0x0014,
        /// 0x0015 INTEGER64.
        Integer64 = 0x0015,
        /// 0x0016 UNSIGNED24.
        Unsigned24 = 0x0016,
        /// 0x0018 UNSIGNED40.
        Unsigned40 = 0x0018,
        /// 0x0019 UNSIGNED48.
        Unsigned48 = 0x0019,
        /// 0x001A UNSIGNED56.
        Unsigned56 = 0x001A,
        /// 0x001B UNSIGNED64.
        Unsigned64 = 0x001B,
        /// 0x001D GUID (128 bits).
        Guid = 0x001D,
        /// 0x001E BYTE.
        Byte = 0x001E,
        /// 0x001F WORD.
        Word = 0x001F,
        /// 0x0020 DWORD.
        Dword = 0x0020,
        /// 0x0021 PDO_MAPPING (record).
        PdoMapping = 0x0021,
        /// 0x0023 IDENTITY (record).
        Identity = 0x0023,
        /// 0x0029 SM_SYNCHRONISATION (record).
        SmSynchronisation = 0x0029,
        /// 0x002D BITARR8.
        BitArr8 = 0x002D,
        /// 0x002E BITARR16.
        BitArr16 = 0x002E,
        /// 0x002F BITARR32.
        BitArr32 = 0x002F,
        /// 0x0030 BIT1.
        Bit1 = 0x0030,
        /// 0x0031 BIT2.
        Bit2 = 0x0031,
        /// 0x0032 BIT3.
        Bit3 = 0x0032,
        /// 0x0033 BIT4.
        Bit4 = 0x0033,
        /// 0x0034 BIT5.
        Bit5 = 0x0034,
        /// 0x0035 BIT6.
        Bit6 = 0x0035,
        /// 0x0036 BIT7.
        Bit7 = 0x0036,
        /// 0x0037 BIT8.
        Bit8 = 0x0037,
        /// 0x0038 BIT9.
        Bit9 = 0x0038,
        /// 0x0039 BIT10.
        Bit10 = 0x0039,
        /// 0x003A BIT11.
        Bit11 = 0x003A,
        /// 0x003B BIT12.
        Bit12 = 0x003B,
        /// 0x003C BIT13.
        Bit13 = 0x003C,
        /// 0x003D BIT14.
        Bit14 = 0x003D,
        /// 0x003E BIT15.
        Bit15 = 0x003E,
        /// 0x003F BIT16.
        Bit16 = 0x003F,
        /// 0x0260 ARRAY OF INT.
        ArrayOfInt = 0x0260,
        /// 0x0261 ARRAY OF SINT.
        ArrayOfSint = 0x0261,
        /// 0x0262 ARRAY OF DINT.
        ArrayOfDint = 0x0262,
        /// 0x0263 ARRAY OF UDINT.
        ArrayOfUdint = 0x0263,
        /// 0x0281 ERROR_SETTING.
        ErrorSetting = 0x0281,
        /// 0x0282 DIAGNOSIS_HISTORY.
        DiagnosisHistory = 0x0282,
        /// 0x0283 EXTERNAL_SYNC_STATUS.
        ExternalSyncStatus = 0x0283,
        /// 0x0284 EXTERNAL_SYNC_SETTINGS.
        ExternalSyncSettings = 0x0284,
        /// 0x0285 FSOE frame.
        FsoeFrame = 0x0285,
        /// 0x0286 FSOE communication parameters.
        FsoeCommPar = 0x0286,
    }
}

impl DataType {
    /// The standard's name of the type (upper case, as in ETG.1000.6 and the ESI files).
    pub fn name(self) -> &'static str {
        use DataType::*;
        match self {
            Boolean => "BOOLEAN",
            Integer8 => "INTEGER8",
            Integer16 => "INTEGER16",
            Integer32 => "INTEGER32",
            Unsigned8 => "UNSIGNED8",
            Unsigned16 => "UNSIGNED16",
            Unsigned32 => "UNSIGNED32",
            Real32 => "REAL32",
            VisibleString => "VISIBLE_STRING",
            OctetString => "OCTET_STRING",
            UnicodeString => "UNICODE_STRING",
            TimeOfDay => "TIME_OF_DAY",
            TimeDifference => "TIME_DIFFERENCE",
            Domain => "DOMAIN",
            Integer24 => "INTEGER24",
            Real64 => "REAL64",
            Integer40 => "INTEGER40",
            Integer48 => "INTEGER48",
            Integer56 => "INTEGER56",
            Integer64 => "INTEGER64",
            Unsigned24 => "UNSIGNED24",
            Unsigned40 => "UNSIGNED40",
            Unsigned48 => "UNSIGNED48",
            Unsigned56 => "UNSIGNED56",
            Unsigned64 => "UNSIGNED64",
            Guid => "GUID",
            Byte => "BYTE",
            Word => "WORD",
            Dword => "DWORD",
            PdoMapping => "PDO_MAPPING",
            Identity => "IDENTITY",
            SmSynchronisation => "SM_SYNCHRONISATION",
            BitArr8 => "BITARR8",
            BitArr16 => "BITARR16",
            BitArr32 => "BITARR32",
            Bit1 => "BIT1",
            Bit2 => "BIT2",
            Bit3 => "BIT3",
            Bit4 => "BIT4",
            Bit5 => "BIT5",
            Bit6 => "BIT6",
            Bit7 => "BIT7",
            Bit8 => "BIT8",
            Bit9 => "BIT9",
            Bit10 => "BIT10",
            Bit11 => "BIT11",
            Bit12 => "BIT12",
            Bit13 => "BIT13",
            Bit14 => "BIT14",
            Bit15 => "BIT15",
            Bit16 => "BIT16",
            ArrayOfInt => "ARRAY_OF_INT",
            ArrayOfSint => "ARRAY_OF_SINT",
            ArrayOfDint => "ARRAY_OF_DINT",
            ArrayOfUdint => "ARRAY_OF_UDINT",
            ErrorSetting => "ERROR_SETTING",
            DiagnosisHistory => "DIAGNOSIS_HISTORY",
            ExternalSyncStatus => "EXTERNAL_SYNC_STATUS",
            ExternalSyncSettings => "EXTERNAL_SYNC_SETTINGS",
            FsoeFrame => "FSOE_FRAME",
            FsoeCommPar => "FSOE_COMMPAR",
            Unknown(_) => "unknown",
        }
    }

    /// Size in bits for types of fixed size; `None` for strings, DOMAIN, records and arrays
    /// (their size is the entry's bit length from the object dictionary).
    pub fn bit_size(self) -> Option<u16> {
        use DataType::*;
        Some(match self {
            Boolean | Bit1 => 1,
            Bit2 => 2,
            Bit3 => 3,
            Bit4 => 4,
            Bit5 => 5,
            Bit6 => 6,
            Bit7 => 7,
            Integer8 | Unsigned8 | Byte | Bit8 | BitArr8 => 8,
            Bit9 => 9,
            Bit10 => 10,
            Bit11 => 11,
            Bit12 => 12,
            Bit13 => 13,
            Bit14 => 14,
            Bit15 => 15,
            Integer16 | Unsigned16 | Word | Bit16 | BitArr16 => 16,
            Integer24 | Unsigned24 => 24,
            Integer32 | Unsigned32 | Real32 | Dword | BitArr32 => 32,
            Integer40 | Unsigned40 => 40,
            Integer48 | Unsigned48 | TimeOfDay | TimeDifference => 48,
            Integer56 | Unsigned56 => 56,
            Integer64 | Unsigned64 | Real64 => 64,
            Guid => 128,
            _ => return None,
        })
    }
}

impl fmt::Display for DataType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DataType::Unknown(raw) => write!(f, "type {raw:#06x}"),
            known => f.write_str(known.name()),
        }
    }
}

enum_with_unknown! {
    /// Object code of an object (u8, ETG.1000.6, spec-notes §coe.info "Get Object Description").
    pub enum ObjectCode(u8) {
        /// 0x00 NULL.
        Null = 0x00,
        /// 0x02 DOMAIN.
        Domain = 0x02,
        /// 0x05 DEFTYPE.
        DefType = 0x05,
        /// 0x06 DEFSTRUCT.
        DefStruct = 0x06,
        /// 0x07 VAR (a single value).
        Var = 0x07,
        /// 0x08 ARRAY (entries of one type).
        Array = 0x08,
        /// 0x09 RECORD (entries of differing types).
        Record = 0x09,
    }
}

impl ObjectCode {
    /// The standard's name ("VAR", "ARRAY", "RECORD", ...).
    pub fn name(self) -> &'static str {
        match self {
            ObjectCode::Null => "NULL",
            ObjectCode::Domain => "DOMAIN",
            ObjectCode::DefType => "DEFTYPE",
            ObjectCode::DefStruct => "DEFSTRUCT",
            ObjectCode::Var => "VAR",
            ObjectCode::Array => "ARRAY",
            ObjectCode::Record => "RECORD",
            ObjectCode::Unknown(_) => "unknown",
        }
    }
}

impl fmt::Display for ObjectCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ObjectCode::Unknown(raw) => write!(f, "code {raw:#04x}"),
            known => f.write_str(known.name()),
        }
    }
}

/// Object access word of an entry (u16, spec-notes §coe.info; SOES/KickCAT bit order — Wireshark's
/// comment on these bits is wrong, see spec-notes §coe.info).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ObjectAccess(pub u16);

impl ObjectAccess {
    /// Bit 0: readable in PREOP.
    pub const READ_PREOP: u16 = 1 << 0;
    /// Bit 1: readable in SAFEOP.
    pub const READ_SAFEOP: u16 = 1 << 1;
    /// Bit 2: readable in OP.
    pub const READ_OP: u16 = 1 << 2;
    /// Bit 3: writable in PREOP.
    pub const WRITE_PREOP: u16 = 1 << 3;
    /// Bit 4: writable in SAFEOP.
    pub const WRITE_SAFEOP: u16 = 1 << 4;
    /// Bit 5: writable in OP.
    pub const WRITE_OP: u16 = 1 << 5;
    /// Bit 6: mappable into an RxPDO.
    pub const RXPDO_MAPPABLE: u16 = 1 << 6;
    /// Bit 7: mappable into a TxPDO.
    pub const TXPDO_MAPPABLE: u16 = 1 << 7;
    /// Bit 8: stored for device replacement (backup).
    pub const BACKUP: u16 = 1 << 8;
    /// Bit 9: startup parameter (settings).
    pub const SETTINGS: u16 = 1 << 9;
    /// Read-only in every state (0x0007).
    pub const RO: ObjectAccess = ObjectAccess(0x0007);
    /// Read-write in every state (0x003F).
    pub const RW: ObjectAccess = ObjectAccess(0x003F);

    /// Whether all bits of `mask` are set.
    pub const fn contains(self, mask: u16) -> bool {
        self.0 & mask == mask
    }

    /// Readable in at least one state.
    pub const fn readable(self) -> bool {
        self.0 & 0x0007 != 0
    }

    /// Writable in at least one state.
    pub const fn writable(self) -> bool {
        self.0 & 0x0038 != 0
    }
}

impl fmt::Display for ObjectAccess {
    /// ESI-like summary: `RO`, `RW`, `WO` or `--`, then `Rx`/`Tx` when PDO mappable, then
    /// the raw word.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let rw = match (self.readable(), self.writable()) {
            (true, true) => "RW",
            (true, false) => "RO",
            (false, true) => "WO",
            (false, false) => "--",
        };
        f.write_str(rw)?;
        if self.contains(Self::RXPDO_MAPPABLE) {
            f.write_str(" RxPDO")?;
        }
        if self.contains(Self::TXPDO_MAPPABLE) {
            f.write_str(" TxPDO")?;
        }
        write!(f, " ({:#06x})", self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_type_codes_match_the_digest() {
        assert_eq!(DataType::from(0x0007), DataType::Unsigned32);
        assert_eq!(DataType::from(0x001B), DataType::Unsigned64);
        assert_eq!(DataType::from(0x0030), DataType::Bit1);
        assert_eq!(DataType::from(0x003F), DataType::Bit16);
        assert_eq!(DataType::from(0x0017), DataType::Unknown(0x0017));
        assert_eq!(u16::from(DataType::SmSynchronisation), 0x0029);
    }

    #[test]
    fn bit_sizes() {
        assert_eq!(DataType::Boolean.bit_size(), Some(1));
        assert_eq!(DataType::Unsigned24.bit_size(), Some(24));
        assert_eq!(DataType::Real64.bit_size(), Some(64));
        assert_eq!(DataType::Bit12.bit_size(), Some(12));
        assert_eq!(DataType::VisibleString.bit_size(), None);
        assert_eq!(DataType::Unknown(0x1234).bit_size(), None);
        // BITn is n bits for every n.
        for n in 1u16..=16 {
            assert_eq!(DataType::from(0x002F + n).bit_size(), Some(n));
        }
    }

    #[test]
    fn names_and_display() {
        assert_eq!(DataType::VisibleString.to_string(), "VISIBLE_STRING");
        assert_eq!(DataType::Unknown(0x0017).to_string(), "type 0x0017");
        assert_eq!(ObjectCode::from(0x09), ObjectCode::Record);
        assert_eq!(ObjectCode::Array.to_string(), "ARRAY");
    }

    #[test]
    fn access_bits() {
        assert!(ObjectAccess::RO.readable() && !ObjectAccess::RO.writable());
        assert_eq!(ObjectAccess::RO.to_string(), "RO (0x0007)");
        let rw_rx = ObjectAccess(0x003F | ObjectAccess::RXPDO_MAPPABLE);
        assert_eq!(rw_rx.to_string(), "RW RxPDO (0x007f)");
        assert!(ObjectAccess(0x0008).writable() && !ObjectAccess(0x0008).readable());
    }
}
