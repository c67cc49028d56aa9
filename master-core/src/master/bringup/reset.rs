//! The register writes a master does to put slaves into a known state before configuring
//! them (spec-notes §esc.reset, SOEM's `ecx_set_slaves_to_default`), by broadcast for the whole
//! segment or to one slave that came back.

use crate::bus::{BusHandle, DatagramData, DatagramRequest};
use crate::wire::register::address as reg;
use crate::wire::register::dc::{FILTER_DEPTHS_SOEM, SPEED_COUNTER_START_DEFAULT};
use crate::wire::register::eeprom::{CONFIG_ECAT_ACCESS, CONFIG_FORCE_ECAT};
use crate::wire::register::{AlControl, AlState};

use crate::master::error::MasterError;

/// Bytes of all 16 FMMUs and all 16 SyncManagers (SOEM clears 3 and 4; a slave may use
/// more, and clearing registers an ESC does not have is harmless).
const FMMU_BYTES: usize = 16 * 16;
const SM_BYTES: usize = 16 * 8;

/// The writes, in order: (register, bytes).
fn writes() -> Vec<(u16, DatagramData)> {
    let u16_bytes = |v: u16| DatagramData::from(v.to_le_bytes());
    let ack_init = AlControl::acknowledge(AlState::Init)
        .encode()
        .unwrap_or(0x0011);
    vec![
        // All ports' loops on auto.
        (reg::DL_CONTROL_LOOP, DatagramData::from([0u8])),
        // ECAT event mask: DL status changes only.
        (reg::ECAT_EVENT_MASK, u16_bytes(0x0004)),
        (reg::RX_ERROR_COUNTERS, DatagramData::zeroed(8)),
        (reg::FMMU_BASE, DatagramData::zeroed(FMMU_BYTES)),
        (reg::SM_BASE, DatagramData::zeroed(SM_BYTES)),
        (reg::DC_ACTIVATION, DatagramData::from([0u8])),
        (reg::DC_SYSTEM_TIME, DatagramData::zeroed(4)),
        (
            reg::DC_SPEED_COUNTER_START,
            u16_bytes(SPEED_COUNTER_START_DEFAULT),
        ),
        (reg::DC_TIME_FILTER_DEPTH, u16_bytes(FILTER_DEPTHS_SOEM)),
        // Station alias addressing off.
        (reg::DL_CONTROL_ALIAS, DatagramData::from([0u8])),
        (reg::AL_CONTROL, u16_bytes(ack_init)),
        (reg::EEPROM_CONFIG, DatagramData::from([CONFIG_FORCE_ECAT])),
        (reg::EEPROM_CONFIG, DatagramData::from([CONFIG_ECAT_ACCESS])),
    ]
}

/// Resets every slave by broadcast; each write must reach `count` slaves.
pub(crate) async fn reset_all(bus: &BusHandle, count: u16) -> Result<(), MasterError> {
    let pendings = bus.submit_group(
        writes()
            .into_iter()
            .map(|(ado, data)| DatagramRequest::bwr(ado, data).expect_wkc(count)),
    );
    for pending in pendings {
        pending
            .await
            .map_err(MasterError::bus("reset (broadcast)"))?;
    }
    Ok(())
}

/// Resets the one slave with station address `station`.
pub(crate) async fn reset_one(bus: &BusHandle, station: u16) -> Result<(), MasterError> {
    let pendings = bus.submit_group(
        writes()
            .into_iter()
            .map(|(ado, data)| DatagramRequest::fpwr(station, ado, data).expect_wkc(1)),
    );
    for pending in pendings {
        pending.await.map_err(MasterError::bus("reset"))?;
    }
    Ok(())
}
