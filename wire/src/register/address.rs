//! Named ESC register addresses (ETG.1000.4 §6, spec-notes §esc.info and the topics after it).
//!
//! Byte addresses in the ESC's 64 KiB address space; everything below [`PROCESS_RAM`] is a
//! register. Only the registers a master (or an emulated ESC) actually touches are named.

// Information block (ETG.1000.4, spec-notes §esc.info).
/// ESC type (u8). Type at 0x0000, revision at 0x0001 (spec-notes §esc.info: Wireshark swaps them).
pub const TYPE: u16 = 0x0000;
/// ESC revision (u8).
pub const REVISION: u16 = 0x0001;
/// ESC build (u16).
pub const BUILD: u16 = 0x0002;
/// Number of FMMUs supported (u8).
pub const FMMU_COUNT: u16 = 0x0004;
/// Number of SyncManagers supported (u8).
pub const SM_COUNT: u16 = 0x0005;
/// Process RAM size in KiB (u8).
pub const RAM_SIZE: u16 = 0x0006;
/// Port descriptor, 2 bits per port (u8).
pub const PORT_DESCRIPTOR: u16 = 0x0007;
/// ESC features supported (u16).
pub const FEATURES: u16 = 0x0008;

// Addressing, write protection, reset (ETG.1000.4, spec-notes §esc.address).
/// Configured station address (u16), used by FPxx commands.
pub const STATION_ADDRESS: u16 = 0x0010;
/// Configured station alias (u16), loaded from SII word 4.
pub const STATION_ALIAS: u16 = 0x0012;
/// Write register enable (u8).
pub const WRITE_REGISTER_ENABLE: u16 = 0x0020;
/// Write register protection (u8).
pub const WRITE_REGISTER_PROTECTION: u16 = 0x0021;
/// ESC write enable (u8).
pub const ESC_WRITE_ENABLE: u16 = 0x0030;
/// ESC write protection (u8).
pub const ESC_WRITE_PROTECTION: u16 = 0x0031;
/// ESC reset from ECAT (u8): write 'R', 'E', 'S' in three consecutive datagrams.
pub const ESC_RESET_ECAT: u16 = 0x0040;
/// ESC reset from PDI (u8).
pub const ESC_RESET_PDI: u16 = 0x0041;
/// The three bytes written one per datagram to [`ESC_RESET_ECAT`] to reset an ESC.
pub const ESC_RESET_SEQUENCE: [u8; 3] = [b'R', b'E', b'S'];

// Data link (ETG.1000.4, spec-notes §esc.dl).
/// DL control (u32).
pub const DL_CONTROL: u16 = 0x0100;
/// DL control byte 1: loop settings of ports 0-3 (SOEM writes 0 = all auto).
pub const DL_CONTROL_LOOP: u16 = 0x0101;
/// DL control byte 3: bit 0 = station alias enable (SOEM writes 0).
pub const DL_CONTROL_ALIAS: u16 = 0x0103;
/// Physical read/write offset (u16).
pub const PHYSICAL_RW_OFFSET: u16 = 0x0108;
/// DL status (u16).
pub const DL_STATUS: u16 = 0x0110;

// Application layer (ETG.1000.6, spec-notes §al).
/// AL control (u16), written by the master.
pub const AL_CONTROL: u16 = 0x0120;
/// AL status (u16).
pub const AL_STATUS: u16 = 0x0130;
/// AL status code (u16).
pub const AL_STATUS_CODE: u16 = 0x0134;
/// RUN LED override (u8).
pub const RUN_LED_OVERRIDE: u16 = 0x0138;
/// ERR LED override (u8).
pub const ERR_LED_OVERRIDE: u16 = 0x0139;

// PDI and ESC configuration (ETG.1000.4, spec-notes §esc.info).
/// PDI control (u8), loaded from SII word 0 low byte.
pub const PDI_CONTROL: u16 = 0x0140;
/// ESC configuration (u8), loaded from SII word 0 high byte.
pub const ESC_CONFIG: u16 = 0x0141;
/// PDI information (u16, newer ESCs).
pub const PDI_INFORMATION: u16 = 0x014E;
/// PDI configuration, from SII word 1.
pub const PDI_CONFIG: u16 = 0x0150;
/// Sync/latch PDI configuration (u8).
pub const SYNC_LATCH_CONFIG: u16 = 0x0151;
/// Extended PDI configuration (u16), from SII word 3.
pub const PDI_CONFIG_EXT: u16 = 0x0152;

// Events (ETG.1000.4, spec-notes §esc.events).
/// ECAT event mask (u16).
pub const ECAT_EVENT_MASK: u16 = 0x0200;
/// AL event mask (u32).
pub const AL_EVENT_MASK: u16 = 0x0204;
/// ECAT event request (u16).
pub const ECAT_EVENT_REQUEST: u16 = 0x0210;
/// AL event request (u32).
pub const AL_EVENT_REQUEST: u16 = 0x0220;

// Error counters (ETG.1000.4, spec-notes §esc.errors).
/// Start of the error counter block (0x0300–0x0313, see [`super::error_counters`]).
pub const ERROR_COUNTERS: u16 = 0x0300;
/// Invalid frame counter of port `n` is at this + 2n; RX error counter at this + 2n + 1.
pub const RX_ERROR_COUNTERS: u16 = 0x0300;
/// Forwarded RX error counter of port `n` is at this + n.
pub const FORWARDED_RX_ERROR_COUNTERS: u16 = 0x0308;
/// ECAT processing unit error counter (u8).
pub const PROCESSING_UNIT_ERROR_COUNTER: u16 = 0x030C;
/// PDI error counter (u8).
pub const PDI_ERROR_COUNTER: u16 = 0x030D;
/// PDI error code (u8).
pub const PDI_ERROR_CODE: u16 = 0x030E;
/// Lost link counter of port `n` is at this + n.
pub const LOST_LINK_COUNTERS: u16 = 0x0310;

// Watchdogs (ETG.1000.4, spec-notes §esc.watchdog).
/// Watchdog divider (u16); tick = (value + 2) × 40 ns.
pub const WATCHDOG_DIVIDER: u16 = 0x0400;
/// PDI watchdog time (u16, ticks).
pub const WATCHDOG_TIME_PDI: u16 = 0x0410;
/// Process-data watchdog time (u16, ticks).
pub const WATCHDOG_TIME_PROCESS_DATA: u16 = 0x0420;
/// Process-data watchdog status (u16, bit 0).
pub const WATCHDOG_STATUS_PROCESS_DATA: u16 = 0x0440;
/// Process-data watchdog expiry counter (u8).
pub const WATCHDOG_COUNTER_PROCESS_DATA: u16 = 0x0442;
/// PDI watchdog expiry counter (u8).
pub const WATCHDOG_COUNTER_PDI: u16 = 0x0443;

// SII (EEPROM) interface (ETG.1000.4, spec-notes §esc.sii-if).
/// EEPROM configuration (u8): bit 0 PDI owns the EEPROM, bit 1 force ECAT access.
pub const EEPROM_CONFIG: u16 = 0x0500;
/// EEPROM PDI access state (u8).
pub const EEPROM_PDI_ACCESS: u16 = 0x0501;
/// EEPROM control/status (u16), see [`super::eeprom`].
pub const EEPROM_CONTROL: u16 = 0x0502;
/// EEPROM word address (u32).
pub const EEPROM_ADDRESS: u16 = 0x0504;
/// EEPROM data (4 or 8 bytes read, 2 bytes written).
pub const EEPROM_DATA: u16 = 0x0508;

// MII management (ETG.1000.4 §6).
/// MII management control/status (u16).
pub const MII_CONTROL: u16 = 0x0510;

// FMMUs and SyncManagers (ETG.1000.4, spec-notes §esc.fmmu, §esc.sm).
/// FMMU 0; FMMU n is at this + 16·n.
pub const FMMU_BASE: u16 = 0x0600;
/// Size of one FMMU register set.
pub const FMMU_STRIDE: u16 = 16;
/// Number of FMMU register sets the address space has room for.
pub const FMMU_MAX: u8 = 16;
/// SyncManager 0; SM n is at this + 8·n.
pub const SM_BASE: u16 = 0x0800;
/// Size of one SyncManager register set.
pub const SM_STRIDE: u16 = 8;
/// Number of SyncManager register sets the address space has room for.
pub const SM_MAX: u8 = 16;

// Distributed clocks (ETG.1000.4, spec-notes §esc.dc).
/// Receive time port 0 (u32); writing here latches all port receive times.
pub const DC_RECEIVE_TIME_PORT0: u16 = 0x0900;
/// Receive time port 1 (u32).
pub const DC_RECEIVE_TIME_PORT1: u16 = 0x0904;
/// Receive time port 2 (u32).
pub const DC_RECEIVE_TIME_PORT2: u16 = 0x0908;
/// Receive time port 3 (u32).
pub const DC_RECEIVE_TIME_PORT3: u16 = 0x090C;
/// System time (u64, or u32 on 32-bit DC).
pub const DC_SYSTEM_TIME: u16 = 0x0910;
/// Receive time of the ECAT processing unit (u64).
pub const DC_RECEIVE_TIME_PROCESSING_UNIT: u16 = 0x0918;
/// System time offset (u64, treated as signed).
pub const DC_SYSTEM_TIME_OFFSET: u16 = 0x0920;
/// System time delay (u32, ns).
pub const DC_SYSTEM_TIME_DELAY: u16 = 0x0928;
/// System time difference (u32, sign/magnitude).
pub const DC_SYSTEM_TIME_DIFFERENCE: u16 = 0x092C;
/// Speed counter start (u16).
pub const DC_SPEED_COUNTER_START: u16 = 0x0930;
/// Speed counter difference (i16).
pub const DC_SPEED_COUNTER_DIFF: u16 = 0x0932;
/// System time difference filter depth (u8).
pub const DC_TIME_FILTER_DEPTH: u16 = 0x0934;
/// Speed counter filter depth (u8).
pub const DC_SPEED_FILTER_DEPTH: u16 = 0x0935;
/// Cyclic unit control (u8); IgH writes 0x0980/0x0981 together as "AssignActivate".
pub const DC_CYCLIC_UNIT_CONTROL: u16 = 0x0980;
/// Activation register (u8).
pub const DC_ACTIVATION: u16 = 0x0981;
/// Pulse length of SYNC signals (u16, 10 ns units).
pub const DC_PULSE_LENGTH: u16 = 0x0982;
/// Activation status (u8).
pub const DC_ACTIVATION_STATUS: u16 = 0x0984;
/// SYNC0 status (u8).
pub const DC_SYNC0_STATUS: u16 = 0x098E;
/// SYNC1 status (u8).
pub const DC_SYNC1_STATUS: u16 = 0x098F;
/// Start time of cyclic operation (u64).
pub const DC_START_TIME: u16 = 0x0990;
/// Next SYNC1 pulse (u64).
pub const DC_NEXT_SYNC1: u16 = 0x0998;
/// SYNC0 cycle time (u32, ns).
pub const DC_SYNC0_CYCLE: u16 = 0x09A0;
/// SYNC1 cycle time (u32, ns).
pub const DC_SYNC1_CYCLE: u16 = 0x09A4;
/// Latch0 control (u8).
pub const DC_LATCH0_CONTROL: u16 = 0x09A8;
/// Latch1 control (u8).
pub const DC_LATCH1_CONTROL: u16 = 0x09A9;
/// Latch0 status (u8).
pub const DC_LATCH0_STATUS: u16 = 0x09AE;
/// Latch1 status (u8).
pub const DC_LATCH1_STATUS: u16 = 0x09AF;
/// Latch0 time, positive edge (u64).
pub const DC_LATCH0_POSITIVE: u16 = 0x09B0;
/// Latch0 time, negative edge (u64).
pub const DC_LATCH0_NEGATIVE: u16 = 0x09B8;
/// Latch1 time, positive edge (u64).
pub const DC_LATCH1_POSITIVE: u16 = 0x09C0;
/// Latch1 time, negative edge (u64).
pub const DC_LATCH1_NEGATIVE: u16 = 0x09C8;
/// EtherCAT buffer change event time (u32).
pub const DC_ECAT_BUFFER_CHANGE_TIME: u16 = 0x09F0;
/// PDI buffer start event time (u32).
pub const DC_PDI_BUFFER_START_TIME: u16 = 0x09F8;
/// PDI buffer change event time (u32).
pub const DC_PDI_BUFFER_CHANGE_TIME: u16 = 0x09FC;

// Other areas (ETG.1000.4, spec-notes §esc.info).
/// First byte of process data RAM; everything below is a register.
pub const PROCESS_RAM: u16 = 0x1000;

/// Register address of FMMU `n` (0x0600 + 16·n), or `None` beyond the 16 the map has room for.
pub const fn fmmu(n: u8) -> Option<u16> {
    if n < FMMU_MAX {
        Some(FMMU_BASE + FMMU_STRIDE * n as u16)
    } else {
        None
    }
}

/// Register address of SyncManager `n` (0x0800 + 8·n), or `None` beyond 16.
pub const fn sync_manager(n: u8) -> Option<u16> {
    if n < SM_MAX {
        Some(SM_BASE + SM_STRIDE * n as u16)
    } else {
        None
    }
}

/// Address of the status byte of SyncManager `n` (used for mapping the SM1 "mailbox full"
/// bit with an FMMU, e.g. 0x080D, spec-notes §capture).
pub const fn sync_manager_status(n: u8) -> Option<u16> {
    match sync_manager(n) {
        Some(base) => Some(base + 5),
        None => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indexed_register_sets() {
        assert_eq!(fmmu(0), Some(0x0600));
        assert_eq!(fmmu(2), Some(0x0620));
        assert_eq!(fmmu(15), Some(0x06F0));
        assert_eq!(fmmu(16), None);
        assert_eq!(sync_manager(0), Some(0x0800));
        assert_eq!(sync_manager(1), Some(0x0808));
        assert_eq!(sync_manager(15), Some(0x0878));
        assert_eq!(sync_manager(16), None);
        // The worked FMMU example (spec-notes §esc.fmmu) maps the SM1 status byte at 0x080D.
        assert_eq!(sync_manager_status(1), Some(0x080D));
    }
}
