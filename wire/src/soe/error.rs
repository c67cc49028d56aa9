//! SoE error codes.

use crate::macros::enum_with_unknown;

enum_with_unknown! {
    /// SoE error code (ETG.1000.6, spec-notes §soe, IgH's table).
    pub enum SoeError(u16) {
        /// No error.
        NoError = 0x0000,
        /// No IDN.
        NoIdn = 0x1001,
        /// Invalid access to element 1.
        InvalidAccessElement1 = 0x1009,
        /// No name.
        NoName = 0x2001,
        /// Name transmission too short.
        NameTooShort = 0x2002,
        /// Name transmission too long.
        NameTooLong = 0x2003,
        /// Name cannot be changed (read only).
        NameReadOnly = 0x2004,
        /// Name is write-protected at this time.
        NameWriteProtected = 0x2005,
        /// Attribute transmission too short.
        AttributeTooShort = 0x3002,
        /// Attribute transmission too long.
        AttributeTooLong = 0x3003,
        /// Attribute cannot be changed (read only).
        AttributeReadOnly = 0x3004,
        /// Attribute is write-protected at this time.
        AttributeWriteProtected = 0x3005,
        /// No unit.
        NoUnit = 0x4001,
        /// Unit transmission too short.
        UnitTooShort = 0x4002,
        /// Unit transmission too long.
        UnitTooLong = 0x4003,
        /// Unit cannot be changed (read only).
        UnitReadOnly = 0x4004,
        /// Unit is write-protected at this time.
        UnitWriteProtected = 0x4005,
        /// No minimum input value.
        NoMinimum = 0x5001,
        /// Minimum input value transmission too short.
        MinimumTooShort = 0x5002,
        /// Minimum input value transmission too long.
        MinimumTooLong = 0x5003,
        /// Minimum input value cannot be changed (read only).
        MinimumReadOnly = 0x5004,
        /// Minimum input value is write-protected at this time.
        MinimumWriteProtected = 0x5005,
        /// No maximum input value.
        NoMaximum = 0x6001,
        /// Maximum input value transmission too short.
        MaximumTooShort = 0x6002,
        /// Maximum input value transmission too long.
        MaximumTooLong = 0x6003,
        /// Maximum input value cannot be changed (read only).
        MaximumReadOnly = 0x6004,
        /// Maximum input value is write-protected at this time.
        MaximumWriteProtected = 0x6005,
        /// Operation data transmission too short.
        DataTooShort = 0x7002,
        /// Operation data transmission too long.
        DataTooLong = 0x7003,
        /// Operation data cannot be changed (read only).
        DataReadOnly = 0x7004,
        /// Operation data is write-protected at this time (state).
        DataWriteProtected = 0x7005,
        /// Operation data is smaller than the minimum input value.
        DataBelowMinimum = 0x7006,
        /// Operation data is greater than the maximum input value.
        DataAboveMaximum = 0x7007,
        /// Invalid operation data (configured IDN not supported).
        InvalidData = 0x7008,
        /// Operation data write-protected by a password.
        DataPasswordProtected = 0x7009,
        /// Operation data write-protected (configured cyclically).
        DataCyclicallyConfigured = 0x700A,
        /// Invalid indirect addressing (data container, list handling).
        InvalidIndirectAddressing = 0x700B,
        /// Operation data write-protected due to other settings.
        DataProtectedBySettings = 0x700C,
        /// Reserved (0x700D).
        Reserved700D = 0x700D,
        /// Procedure command already active.
        ProcedureAlreadyActive = 0x7010,
        /// Procedure command not interruptible.
        ProcedureNotInterruptible = 0x7011,
        /// Procedure command not executable at this time (state).
        ProcedureNotExecutableNow = 0x7012,
        /// Procedure command not executable (invalid or false parameters).
        ProcedureInvalidParameters = 0x7013,
        /// No data state.
        NoDataState = 0x7014,
        /// No default value.
        NoDefault = 0x8001,
        /// Default value transmission too long.
        DefaultTooLong = 0x8002,
        /// Default value cannot be changed (read only).
        DefaultReadOnly = 0x8004,
        /// Invalid drive number.
        InvalidDriveNumber = 0x800A,
        /// General error.
        GeneralError = 0x800B,
        /// No element addressed.
        NoElementAddressed = 0x800C,
    }
}

impl SoeError {
    /// The text of the error code (ETG.1000.6, spec-notes §soe).
    pub fn description(self) -> &'static str {
        use SoeError::*;
        match self {
            NoError => "No error",
            NoIdn => "No IDN",
            InvalidAccessElement1 => "Invalid access to element 1",
            NoName => "No name",
            NameTooShort => "Name transmission too short",
            NameTooLong => "Name transmission too long",
            NameReadOnly => "Name cannot be changed (read only)",
            NameWriteProtected => "Name is write-protected at this time",
            AttributeTooShort => "Attribute transmission too short",
            AttributeTooLong => "Attribute transmission too long",
            AttributeReadOnly => "Attribute cannot be changed (read only)",
            AttributeWriteProtected => "Attribute is write-protected at this time",
            NoUnit => "No unit",
            UnitTooShort => "Unit transmission too short",
            UnitTooLong => "Unit transmission too long",
            UnitReadOnly => "Unit cannot be changed (read only)",
            UnitWriteProtected => "Unit is write-protected at this time",
            NoMinimum => "No minimum input value",
            MinimumTooShort => "Minimum input value transmission too short",
            MinimumTooLong => "Minimum input value transmission too long",
            MinimumReadOnly => "Minimum input value cannot be changed (read only)",
            MinimumWriteProtected => "Minimum input value is write-protected at this time",
            NoMaximum => "No maximum input value",
            MaximumTooShort => "Maximum input value transmission too short",
            MaximumTooLong => "Maximum input value transmission too long",
            MaximumReadOnly => "Maximum input value cannot be changed (read only)",
            MaximumWriteProtected => "Maximum input value is write-protected at this time",
            DataTooShort => "Operation data transmission too short",
            DataTooLong => "Operation data transmission too long",
            DataReadOnly => "Operation data cannot be changed (read only)",
            DataWriteProtected => "Operation data is write-protected at this time (state)",
            DataBelowMinimum => "Operation data is smaller than the minimum input value",
            DataAboveMaximum => "Operation data is greater than the maximum input value",
            InvalidData => "Invalid operation data (configured IDN not supported)",
            DataPasswordProtected => "Operation data write-protected by a password",
            DataCyclicallyConfigured => "Operation data write-protected (configured cyclically)",
            InvalidIndirectAddressing => {
                "Invalid indirect addressing (data container, list handling)"
            }
            DataProtectedBySettings => "Operation data write-protected due to other settings",
            Reserved700D => "Reserved",
            ProcedureAlreadyActive => "Procedure command already active",
            ProcedureNotInterruptible => "Procedure command not interruptible",
            ProcedureNotExecutableNow => "Procedure command not executable at this time (state)",
            ProcedureInvalidParameters => {
                "Procedure command not executable (invalid or false parameters)"
            }
            NoDataState => "No data state",
            NoDefault => "No default value",
            DefaultTooLong => "Default value transmission too long",
            DefaultReadOnly => "Default value cannot be changed (read only)",
            InvalidDriveNumber => "Invalid drive number",
            GeneralError => "General error",
            NoElementAddressed => "No element addressed",
            Unknown(_) => "Unknown error",
        }
    }
}
