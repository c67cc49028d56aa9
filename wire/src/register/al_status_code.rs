//! AL status codes, register 0x0134 (ETG.1000.6, spec-notes §al.codes).

use core::fmt;

use crate::macros::enum_with_unknown;

enum_with_unknown! {
    /// Why a slave refused a state change or left a state (AL status code, spec-notes §al.codes).
    ///
    /// 0x8000–0xFFFF are vendor specific and stay `Unknown(code)`; see
    /// [`AlStatusCode::is_vendor_specific`].
    pub enum AlStatusCode(u16) {
        /// 0x0000 No error.
        NoError = 0x0000,
        /// 0x0001 Unspecified error.
        Unspecified = 0x0001,
        /// 0x0002 No memory.
        NoMemory = 0x0002,
        /// 0x0003 Invalid device setup.
        InvalidDeviceSetup = 0x0003,
        /// 0x0004 Invalid revision.
        InvalidRevision = 0x0004,
        /// 0x0005 Reserved (compatibility).
        Reserved0005 = 0x0005,
        /// 0x0006 SII/EEPROM information does not match firmware.
        SiiMismatch = 0x0006,
        /// 0x0007 Firmware update not successful, old firmware still running.
        FirmwareUpdateFailed = 0x0007,
        /// 0x000E License error.
        LicenseError = 0x000E,
        /// 0x0011 Invalid requested state change.
        InvalidStateChange = 0x0011,
        /// 0x0012 Unknown requested state.
        UnknownRequestedState = 0x0012,
        /// 0x0013 Bootstrap not supported.
        BootstrapNotSupported = 0x0013,
        /// 0x0014 No valid firmware.
        NoValidFirmware = 0x0014,
        /// 0x0015 Invalid mailbox configuration (BOOT).
        InvalidMailboxConfigBoot = 0x0015,
        /// 0x0016 Invalid mailbox configuration (PREOP).
        InvalidMailboxConfigPreop = 0x0016,
        /// 0x0017 Invalid sync manager configuration.
        InvalidSmConfig = 0x0017,
        /// 0x0018 No valid inputs available.
        NoValidInputs = 0x0018,
        /// 0x0019 No valid outputs.
        NoValidOutputs = 0x0019,
        /// 0x001A Synchronization error.
        SyncError = 0x001A,
        /// 0x001B Sync manager watchdog.
        SmWatchdog = 0x001B,
        /// 0x001C Invalid sync manager types.
        InvalidSmTypes = 0x001C,
        /// 0x001D Invalid output configuration.
        InvalidOutputConfig = 0x001D,
        /// 0x001E Invalid input configuration.
        InvalidInputConfig = 0x001E,
        /// 0x001F Invalid watchdog configuration.
        InvalidWatchdogConfig = 0x001F,
        /// 0x0020 Slave needs cold start.
        NeedsColdStart = 0x0020,
        /// 0x0021 Slave needs INIT.
        NeedsInit = 0x0021,
        /// 0x0022 Slave needs PREOP.
        NeedsPreop = 0x0022,
        /// 0x0023 Slave needs SAFEOP.
        NeedsSafeop = 0x0023,
        /// 0x0024 Invalid input mapping.
        InvalidInputMapping = 0x0024,
        /// 0x0025 Invalid output mapping.
        InvalidOutputMapping = 0x0025,
        /// 0x0026 Inconsistent settings.
        InconsistentSettings = 0x0026,
        /// 0x0027 Free-run not supported.
        FreeRunNotSupported = 0x0027,
        /// 0x0028 Synchronization not supported.
        SyncNotSupported = 0x0028,
        /// 0x0029 Free-run needs 3-buffer mode.
        FreeRunNeeds3Buffer = 0x0029,
        /// 0x002A Background watchdog.
        BackgroundWatchdog = 0x002A,
        /// 0x002B No valid inputs and outputs.
        NoValidInputsOutputs = 0x002B,
        /// 0x002C Fatal sync error.
        FatalSyncError = 0x002C,
        /// 0x002D No sync error (SYNC signals missing).
        NoSyncError = 0x002D,
        /// 0x002E Cycle time too small (SOES: invalid input FMMU configuration).
        CycleTimeTooSmall = 0x002E,
        /// 0x0030 Invalid DC SYNC configuration.
        InvalidDcSyncConfig = 0x0030,
        /// 0x0031 Invalid DC latch configuration.
        InvalidDcLatchConfig = 0x0031,
        /// 0x0032 PLL error.
        PllError = 0x0032,
        /// 0x0033 DC sync I/O error.
        DcSyncIoError = 0x0033,
        /// 0x0034 DC sync timeout error.
        DcSyncTimeout = 0x0034,
        /// 0x0035 DC invalid sync cycle time.
        DcInvalidSyncCycleTime = 0x0035,
        /// 0x0036 DC invalid SYNC0 cycle time.
        DcInvalidSync0CycleTime = 0x0036,
        /// 0x0037 DC invalid SYNC1 cycle time.
        DcInvalidSync1CycleTime = 0x0037,
        /// 0x0041 Mailbox AoE error.
        MailboxAoe = 0x0041,
        /// 0x0042 Mailbox EoE error.
        MailboxEoe = 0x0042,
        /// 0x0043 Mailbox CoE error.
        MailboxCoe = 0x0043,
        /// 0x0044 Mailbox FoE error.
        MailboxFoe = 0x0044,
        /// 0x0045 Mailbox SoE error.
        MailboxSoe = 0x0045,
        /// 0x004F Mailbox VoE error.
        MailboxVoe = 0x004F,
        /// 0x0050 EEPROM no access.
        EepromNoAccess = 0x0050,
        /// 0x0051 EEPROM error.
        EepromError = 0x0051,
        /// 0x0052 External hardware not ready.
        ExternalHardwareNotReady = 0x0052,
        /// 0x0060 Slave restarted locally.
        RestartedLocally = 0x0060,
        /// 0x0061 Device identification value updated.
        DeviceIdUpdated = 0x0061,
        /// 0x0070 Detected module ident list does not match configured.
        ModuleIdentMismatch = 0x0070,
        /// 0x0080 Supply voltage too low.
        SupplyVoltageTooLow = 0x0080,
        /// 0x0081 Supply voltage too high.
        SupplyVoltageTooHigh = 0x0081,
        /// 0x0082 Temperature too low.
        TemperatureTooLow = 0x0082,
        /// 0x0083 Temperature too high.
        TemperatureTooHigh = 0x0083,
        /// 0x00F0 Application controller available.
        ApplicationControllerAvailable = 0x00F0,
    }
}

impl AlStatusCode {
    /// Whether the code lies in the vendor-specific range 0x8000–0xFFFF.
    pub fn is_vendor_specific(self) -> bool {
        u16::from(self) >= 0x8000
    }

    /// The meaning of the code, in the words of the ETG.1000.6 table (spec-notes §al.codes).
    ///
    /// 0x002E is named by both of its readings (spec-notes §al.codes).
    pub fn description(self) -> &'static str {
        use AlStatusCode::*;
        match self {
            NoError => "No error",
            Unspecified => "Unspecified error",
            NoMemory => "No memory",
            InvalidDeviceSetup => "Invalid device setup",
            InvalidRevision => "Invalid revision",
            Reserved0005 => "Reserved (compatibility)",
            SiiMismatch => "SII/EEPROM information does not match firmware",
            FirmwareUpdateFailed => "Firmware update not successful, old firmware still running",
            LicenseError => "License error",
            InvalidStateChange => "Invalid requested state change",
            UnknownRequestedState => "Unknown requested state",
            BootstrapNotSupported => "Bootstrap not supported",
            NoValidFirmware => "No valid firmware",
            InvalidMailboxConfigBoot => "Invalid mailbox configuration (BOOT)",
            InvalidMailboxConfigPreop => "Invalid mailbox configuration (PREOP)",
            InvalidSmConfig => "Invalid sync manager configuration",
            NoValidInputs => "No valid inputs available",
            NoValidOutputs => "No valid outputs",
            SyncError => "Synchronization error",
            SmWatchdog => "Sync manager watchdog",
            InvalidSmTypes => "Invalid sync manager types",
            InvalidOutputConfig => "Invalid output configuration",
            InvalidInputConfig => "Invalid input configuration",
            InvalidWatchdogConfig => "Invalid watchdog configuration",
            NeedsColdStart => "Slave needs cold start",
            NeedsInit => "Slave needs INIT",
            NeedsPreop => "Slave needs PREOP",
            NeedsSafeop => "Slave needs SAFEOP",
            InvalidInputMapping => "Invalid input mapping",
            InvalidOutputMapping => "Invalid output mapping",
            InconsistentSettings => "Inconsistent settings",
            FreeRunNotSupported => "Free-run not supported",
            SyncNotSupported => "Synchronization not supported",
            FreeRunNeeds3Buffer => "Free-run needs 3-buffer mode",
            BackgroundWatchdog => "Background watchdog",
            NoValidInputsOutputs => "No valid inputs and outputs",
            FatalSyncError => "Fatal sync error",
            NoSyncError => "No sync error (SYNC signals missing)",
            CycleTimeTooSmall => "Cycle time too small / invalid input FMMU configuration",
            InvalidDcSyncConfig => "Invalid DC SYNC configuration",
            InvalidDcLatchConfig => "Invalid DC latch configuration",
            PllError => "PLL error",
            DcSyncIoError => "DC sync I/O error",
            DcSyncTimeout => "DC sync timeout error",
            DcInvalidSyncCycleTime => "DC invalid sync cycle time",
            DcInvalidSync0CycleTime => "DC invalid SYNC0 cycle time",
            DcInvalidSync1CycleTime => "DC invalid SYNC1 cycle time",
            MailboxAoe => "Mailbox AoE error",
            MailboxEoe => "Mailbox EoE error",
            MailboxCoe => "Mailbox CoE error",
            MailboxFoe => "Mailbox FoE error",
            MailboxSoe => "Mailbox SoE error",
            MailboxVoe => "Mailbox VoE error",
            EepromNoAccess => "EEPROM no access",
            EepromError => "EEPROM error",
            ExternalHardwareNotReady => "External hardware not ready",
            RestartedLocally => "Slave restarted locally",
            DeviceIdUpdated => "Device identification value updated",
            ModuleIdentMismatch => {
                "Detected module ident list (0xF050) does not match configured (0xF030)"
            }
            SupplyVoltageTooLow => "Supply voltage too low",
            SupplyVoltageTooHigh => "Supply voltage too high",
            TemperatureTooLow => "Temperature too low",
            TemperatureTooHigh => "Temperature too high",
            ApplicationControllerAvailable => "Application controller available",
            Unknown(raw) if raw >= 0x8000 => "Vendor specific",
            Unknown(_) => "Unknown AL status code",
        }
    }
}

impl fmt::Display for AlStatusCode {
    /// `0x0016 Invalid mailbox configuration (PREOP)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#06x} {}", u16::from(*self), self.description())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every code of the ETG.1000.6 table (spec-notes §al.codes), with its text.
    const TABLE: &[(u16, &str)] = &[
        (0x0000, "No error"),
        (0x0001, "Unspecified error"),
        (0x0002, "No memory"),
        (0x0003, "Invalid device setup"),
        (0x0004, "Invalid revision"),
        (0x0005, "Reserved (compatibility)"),
        (0x0006, "SII/EEPROM information does not match firmware"),
        (
            0x0007,
            "Firmware update not successful, old firmware still running",
        ),
        (0x000E, "License error"),
        (0x0011, "Invalid requested state change"),
        (0x0012, "Unknown requested state"),
        (0x0013, "Bootstrap not supported"),
        (0x0014, "No valid firmware"),
        (0x0015, "Invalid mailbox configuration (BOOT)"),
        (0x0016, "Invalid mailbox configuration (PREOP)"),
        (0x0017, "Invalid sync manager configuration"),
        (0x0018, "No valid inputs available"),
        (0x0019, "No valid outputs"),
        (0x001A, "Synchronization error"),
        (0x001B, "Sync manager watchdog"),
        (0x001C, "Invalid sync manager types"),
        (0x001D, "Invalid output configuration"),
        (0x001E, "Invalid input configuration"),
        (0x001F, "Invalid watchdog configuration"),
        (0x0020, "Slave needs cold start"),
        (0x0021, "Slave needs INIT"),
        (0x0022, "Slave needs PREOP"),
        (0x0023, "Slave needs SAFEOP"),
        (0x0024, "Invalid input mapping"),
        (0x0025, "Invalid output mapping"),
        (0x0026, "Inconsistent settings"),
        (0x0027, "Free-run not supported"),
        (0x0028, "Synchronization not supported"),
        (0x0029, "Free-run needs 3-buffer mode"),
        (0x002A, "Background watchdog"),
        (0x002B, "No valid inputs and outputs"),
        (0x002C, "Fatal sync error"),
        (0x002D, "No sync error (SYNC signals missing)"),
        (0x002E, "Cycle time too small"),
        (0x0030, "Invalid DC SYNC configuration"),
        (0x0031, "Invalid DC latch configuration"),
        (0x0032, "PLL error"),
        (0x0033, "DC sync I/O error"),
        (0x0034, "DC sync timeout error"),
        (0x0035, "DC invalid sync cycle time"),
        (0x0036, "DC invalid SYNC0 cycle time"),
        (0x0037, "DC invalid SYNC1 cycle time"),
        (0x0041, "Mailbox AoE error"),
        (0x0042, "Mailbox EoE error"),
        (0x0043, "Mailbox CoE error"),
        (0x0044, "Mailbox FoE error"),
        (0x0045, "Mailbox SoE error"),
        (0x004F, "Mailbox VoE error"),
        (0x0050, "EEPROM no access"),
        (0x0051, "EEPROM error"),
        (0x0052, "External hardware not ready"),
        (0x0060, "Slave restarted locally"),
        (0x0061, "Device identification value updated"),
        (
            0x0070,
            "Detected module ident list (0xF050) does not match configured (0xF030)",
        ),
        (0x0080, "Supply voltage too low"),
        (0x0081, "Supply voltage too high"),
        (0x0082, "Temperature too low"),
        (0x0083, "Temperature too high"),
        (0x00F0, "Application controller available"),
    ];

    #[test]
    fn every_table_code_is_named_with_its_text() {
        for &(raw, text) in TABLE {
            let code = AlStatusCode::from(raw);
            assert!(
                !matches!(code, AlStatusCode::Unknown(_)),
                "{raw:#06x} has no variant"
            );
            assert_eq!(u16::from(code), raw);
            assert!(
                code.description().starts_with(text),
                "{raw:#06x}: {} vs {text}",
                code.description()
            );
        }
    }

    #[test]
    fn display_matches_brief() {
        assert_eq!(
            AlStatusCode::from(0x0016).to_string(),
            "0x0016 Invalid mailbox configuration (PREOP)"
        );
        assert_eq!(
            AlStatusCode::from(0x8001).to_string(),
            "0x8001 Vendor specific"
        );
        assert!(AlStatusCode::from(0x8001).is_vendor_specific());
        assert_eq!(
            AlStatusCode::from(0x0008).to_string(),
            "0x0008 Unknown AL status code"
        );
    }
}
