//! SDO abort codes (ETG.1000.6 Table "SDO abort codes", CiA 301 §7.2.4.3.17, spec-notes §coe.abort).
//!
//! The same u32 code travels in an SDO abort (service 2 or 3, command 0x80) and in an SDO
//! Information error (opcode 7), always little-endian.

use core::fmt;

use crate::Emit;
use crate::coe::SdoResponse;
use crate::macros::enum_with_unknown;

enum_with_unknown! {
    /// An SDO abort code (u32). Unknown values are kept as data.
    pub enum AbortCode(u32) {
        /// 0x05030000: toggle bit not alternated.
        ToggleBit = 0x0503_0000,
        /// 0x05040000: SDO protocol timed out.
        Timeout = 0x0504_0000,
        /// 0x05040001: client/server command specifier not valid or unknown.
        UnknownCommand = 0x0504_0001,
        /// 0x05040002: invalid block size (block mode only).
        InvalidBlockSize = 0x0504_0002,
        /// 0x05040003: invalid sequence number (block mode only).
        InvalidSequenceNumber = 0x0504_0003,
        /// 0x05040004: CRC error (block mode only).
        CrcError = 0x0504_0004,
        /// 0x05040005: out of memory.
        OutOfMemory = 0x0504_0005,
        /// 0x06010000: unsupported access to an object.
        UnsupportedAccess = 0x0601_0000,
        /// 0x06010001: attempt to read a write-only object.
        WriteOnly = 0x0601_0001,
        /// 0x06010002: attempt to write a read-only object.
        ReadOnly = 0x0601_0002,
        /// 0x06010003: subindex cannot be written, SI0 must be 0 for write access.
        SubindexNotWritable = 0x0601_0003,
        /// 0x06010004: complete access not supported for objects of variable length.
        CompleteAccessUnsupported = 0x0601_0004,
        /// 0x06010005: object length exceeds mailbox size.
        ObjectTooLong = 0x0601_0005,
        /// 0x06010006: object mapped to RxPDO, SDO download blocked.
        MappedToRxPdo = 0x0601_0006,
        /// 0x06020000: object does not exist in the object dictionary.
        ObjectDoesNotExist = 0x0602_0000,
        /// 0x06040041: object cannot be mapped into the PDO.
        NotMappable = 0x0604_0041,
        /// 0x06040042: mapped objects would exceed the PDO length.
        PdoTooLong = 0x0604_0042,
        /// 0x06040043: general parameter incompatibility.
        ParameterIncompatible = 0x0604_0043,
        /// 0x06040047: general internal incompatibility in the device.
        InternalIncompatible = 0x0604_0047,
        /// 0x06060000: access failed due to a hardware error.
        HardwareError = 0x0606_0000,
        /// 0x06070010: data type or service parameter length does not match.
        LengthMismatch = 0x0607_0010,
        /// 0x06070012: service parameter length too high.
        LengthTooHigh = 0x0607_0012,
        /// 0x06070013: service parameter length too low.
        LengthTooLow = 0x0607_0013,
        /// 0x06090011: subindex does not exist.
        SubindexDoesNotExist = 0x0609_0011,
        /// 0x06090030: value range of parameter exceeded.
        ValueRange = 0x0609_0030,
        /// 0x06090031: value written too high.
        ValueTooHigh = 0x0609_0031,
        /// 0x06090032: value written too low.
        ValueTooLow = 0x0609_0032,
        /// 0x06090033: detected and configured module ident lists do not match.
        ModuleIdentMismatch = 0x0609_0033,
        /// 0x06090036: maximum value is less than minimum value.
        MaxLessThanMin = 0x0609_0036,
        /// 0x060A0023: resource not available (SDO connection).
        ResourceUnavailable = 0x060A_0023,
        /// 0x08000000: general error.
        GeneralError = 0x0800_0000,
        /// 0x08000020: data cannot be transferred or stored to the application.
        TransferFailed = 0x0800_0020,
        /// 0x08000021: ... because of local control.
        LocalControl = 0x0800_0021,
        /// 0x08000022: ... because of the present device state.
        DeviceState = 0x0800_0022,
        /// 0x08000023: object dictionary dynamic generation fails or no OD present.
        NoObjectDictionary = 0x0800_0023,
        /// 0x08000024: no data available.
        NoData = 0x0800_0024,
    }
}

impl AbortCode {
    /// Every abort code the ETG.1000.6 table (spec-notes §coe.abort) names, in table order.
    pub const ALL: [AbortCode; 36] = [
        AbortCode::ToggleBit,
        AbortCode::Timeout,
        AbortCode::UnknownCommand,
        AbortCode::InvalidBlockSize,
        AbortCode::InvalidSequenceNumber,
        AbortCode::CrcError,
        AbortCode::OutOfMemory,
        AbortCode::UnsupportedAccess,
        AbortCode::WriteOnly,
        AbortCode::ReadOnly,
        AbortCode::SubindexNotWritable,
        AbortCode::CompleteAccessUnsupported,
        AbortCode::ObjectTooLong,
        AbortCode::MappedToRxPdo,
        AbortCode::ObjectDoesNotExist,
        AbortCode::NotMappable,
        AbortCode::PdoTooLong,
        AbortCode::ParameterIncompatible,
        AbortCode::InternalIncompatible,
        AbortCode::HardwareError,
        AbortCode::LengthMismatch,
        AbortCode::LengthTooHigh,
        AbortCode::LengthTooLow,
        AbortCode::SubindexDoesNotExist,
        AbortCode::ValueRange,
        AbortCode::ValueTooHigh,
        AbortCode::ValueTooLow,
        AbortCode::ModuleIdentMismatch,
        AbortCode::MaxLessThanMin,
        AbortCode::ResourceUnavailable,
        AbortCode::GeneralError,
        AbortCode::TransferFailed,
        AbortCode::LocalControl,
        AbortCode::DeviceState,
        AbortCode::NoObjectDictionary,
        AbortCode::NoData,
    ];

    /// The standard text of the code (spec-notes §coe.abort); "Unknown abort code" for unnamed values.
    pub fn description(self) -> &'static str {
        match self {
            AbortCode::ToggleBit => "Toggle bit not changed",
            AbortCode::Timeout => "SDO protocol timeout",
            AbortCode::UnknownCommand => "Client/Server command specifier not valid or unknown",
            AbortCode::InvalidBlockSize => "Invalid block size",
            AbortCode::InvalidSequenceNumber => "Invalid sequence number",
            AbortCode::CrcError => "CRC error",
            AbortCode::OutOfMemory => "Out of memory",
            AbortCode::UnsupportedAccess => "Unsupported access to an object",
            AbortCode::WriteOnly => "Attempt to read a write only object",
            AbortCode::ReadOnly => "Attempt to write a read only object",
            AbortCode::SubindexNotWritable => {
                "Subindex cannot be written, SI0 must be 0 for write access"
            }
            AbortCode::CompleteAccessUnsupported => {
                "SDO Complete access not supported for objects of variable length"
            }
            AbortCode::ObjectTooLong => "Object length exceeds mailbox size",
            AbortCode::MappedToRxPdo => "Object mapped to RxPDO, SDO Download blocked",
            AbortCode::ObjectDoesNotExist => "Object does not exist in the object dictionary",
            AbortCode::NotMappable => "Object cannot be mapped into the PDO",
            AbortCode::PdoTooLong => {
                "The number and length of the objects to be mapped would exceed the PDO length"
            }
            AbortCode::ParameterIncompatible => "General parameter incompatibility reason",
            AbortCode::InternalIncompatible => "General internal incompatibility in the device",
            AbortCode::HardwareError => "Access failed due to a hardware error",
            AbortCode::LengthMismatch => {
                "Data type does not match, length of service parameter does not match"
            }
            AbortCode::LengthTooHigh => {
                "Data type does not match, length of service parameter too high"
            }
            AbortCode::LengthTooLow => {
                "Data type does not match, length of service parameter too low"
            }
            AbortCode::SubindexDoesNotExist => "Subindex does not exist",
            AbortCode::ValueRange => "Value range of parameter exceeded",
            AbortCode::ValueTooHigh => "Value of parameter written too high",
            AbortCode::ValueTooLow => "Value of parameter written too low",
            AbortCode::ModuleIdentMismatch => {
                "Detected Module Ident List (0xF050) and Configured Module Ident List (0xF030) do not match"
            }
            AbortCode::MaxLessThanMin => "Maximum value is less than minimum value",
            AbortCode::ResourceUnavailable => "Resource not available: SDO connection",
            AbortCode::GeneralError => "General error",
            AbortCode::TransferFailed => "Data cannot be transferred or stored to the application",
            AbortCode::LocalControl => {
                "Data cannot be transferred or stored to the application because of local control"
            }
            AbortCode::DeviceState => {
                "Data cannot be transferred or stored to the application because of the present device state"
            }
            AbortCode::NoObjectDictionary => {
                "Object dictionary dynamic generation fails or no object dictionary is present"
            }
            AbortCode::NoData => "No data available",
            AbortCode::Unknown(_) => "Unknown abort code",
        }
    }
}

/// The CoE data (CoE header included) of an SDO abort for `index:subindex` with `code`:
/// the Abort SDO Transfer request of ETG.1000.6 §5.6.2.7 (command 0x80), as a server
/// answers a request it refuses.
pub fn sdo_abort(index: u16, subindex: u8, code: AbortCode) -> Vec<u8> {
    let response = SdoResponse::Abort {
        index,
        subindex,
        code,
    };
    // `to_vec` sizes the buffer and an abort has no field `emit` could refuse: never the
    // empty default.
    response.to_vec().unwrap_or_default()
}

impl fmt::Display for AbortCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#010x} {}", u32::from(*self), self.description())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_sdo_abort_is_the_abort_request_naming_the_object() {
        // Object 0x2000:00 does not exist: CoE header service 3, command 0x80, code LE.
        assert_eq!(
            sdo_abort(0x2000, 0, AbortCode::ObjectDoesNotExist),
            [0x00, 0x30, 0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x02, 0x06]
        );
    }

    #[test]
    fn every_code_has_a_description_and_round_trips() {
        for code in AbortCode::ALL {
            assert_ne!(code.description(), "Unknown abort code", "{code:?}");
            assert_eq!(AbortCode::from(u32::from(code)), code);
        }
        // All codes distinct (the table has 36 rows).
        let mut raw: Vec<u32> = AbortCode::ALL.iter().map(|c| u32::from(*c)).collect();
        raw.sort_unstable();
        raw.dedup();
        assert_eq!(raw.len(), 36);
    }

    #[test]
    fn table_values_match_the_digest() {
        assert_eq!(AbortCode::from(0x0503_0000), AbortCode::ToggleBit);
        assert_eq!(AbortCode::from(0x0602_0000), AbortCode::ObjectDoesNotExist);
        assert_eq!(
            AbortCode::from(0x0609_0011),
            AbortCode::SubindexDoesNotExist
        );
        assert_eq!(AbortCode::from(0x060A_0023), AbortCode::ResourceUnavailable);
        assert_eq!(AbortCode::from(0x0800_0024), AbortCode::NoData);
        assert_eq!(
            AbortCode::from(0x1234_5678),
            AbortCode::Unknown(0x1234_5678)
        );
    }

    #[test]
    fn display_gives_hex_and_text() {
        assert_eq!(
            AbortCode::ObjectDoesNotExist.to_string(),
            "0x06020000 Object does not exist in the object dictionary"
        );
        assert_eq!(
            AbortCode::Unknown(0x0102_0304).to_string(),
            "0x01020304 Unknown abort code"
        );
    }
}
