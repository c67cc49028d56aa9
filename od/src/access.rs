//! Which access bits apply in which AL state, and the abort code for each refusal
//! (ETG.1000.6, spec-notes §coe.info object access word, §coe.abort abort codes).

use ecat_wire::coe::{AbortCode, ObjectAccess};
use ecat_wire::register::AlState;

/// Read and write bits of the access word that apply in `state`.
///
/// SDO traffic exists from PREOP up; INIT, BOOT and unknown states are treated like PREOP
/// (the master's own dictionary has no state of its own and passes what suits it).
pub fn state_bits(state: AlState) -> (u16, u16) {
    match state {
        AlState::SafeOp => (ObjectAccess::READ_SAFEOP, ObjectAccess::WRITE_SAFEOP),
        AlState::Op => (ObjectAccess::READ_OP, ObjectAccess::WRITE_OP),
        _ => (ObjectAccess::READ_PREOP, ObjectAccess::WRITE_PREOP),
    }
}

/// Whether an entry with `access` may be read in `state`: write-only entries give
/// 0x06010001, entries readable only in other states 0x08000022.
pub fn check_read(access: ObjectAccess, state: AlState) -> Result<(), AbortCode> {
    let (read, _) = state_bits(state);
    if access.0 & read != 0 {
        Ok(())
    } else if access.readable() {
        Err(AbortCode::DeviceState)
    } else {
        Err(AbortCode::WriteOnly)
    }
}

/// Whether an entry with `access` may be written in `state`: read-only entries give
/// 0x06010002, entries writable only in other states 0x08000022.
pub fn check_write(access: ObjectAccess, state: AlState) -> Result<(), AbortCode> {
    let (_, write) = state_bits(state);
    if access.0 & write != 0 {
        Ok(())
    } else if access.writable() {
        Err(AbortCode::DeviceState)
    } else {
        Err(AbortCode::ReadOnly)
    }
}

/// Access word helpers for declaring entries.
pub mod presets {
    use ecat_wire::coe::ObjectAccess;

    /// Read in every state, write in PREOP only (0x000F): PDO mapping and assignment.
    pub const RW_PREOP: ObjectAccess = ObjectAccess(0x000F);
    /// Write-only in every state (0x0038).
    pub const WO: ObjectAccess = ObjectAccess(0x0038);
    /// Read-only, TxPDO-mappable (0x0087): inputs.
    pub const RO_TX: ObjectAccess = ObjectAccess(0x0007 | ObjectAccess::TXPDO_MAPPABLE);
    /// Read-write, RxPDO-mappable (0x007F): outputs.
    pub const RW_RX: ObjectAccess = ObjectAccess(0x003F | ObjectAccess::RXPDO_MAPPABLE);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_by_state() {
        let pre = presets::RW_PREOP;
        assert_eq!(check_write(pre, AlState::PreOp), Ok(()));
        assert_eq!(
            check_write(pre, AlState::SafeOp),
            Err(AbortCode::DeviceState)
        );
        assert_eq!(
            check_write(ObjectAccess::RO, AlState::Op),
            Err(AbortCode::ReadOnly)
        );
        assert_eq!(
            check_read(presets::WO, AlState::Op),
            Err(AbortCode::WriteOnly)
        );
        assert_eq!(
            check_read(ObjectAccess(0x0001), AlState::Op),
            Err(AbortCode::DeviceState)
        );
        assert_eq!(check_read(ObjectAccess::RO, AlState::Init), Ok(()));
    }
}
