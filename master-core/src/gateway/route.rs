//! Where a request goes, by the address in its mailbox header (docs/gateway.md):
//! 0 the master's dictionary; a slave's station address that slave; 0x8000 + n the slave at
//! ring position n (when no slave has that station address); 0xFFFF every slave that serves
//! the protocol.

use crate::mailbox::SlaveMailbox;
use crate::master::{Master, MasterError, SlaveAddress};
use crate::wire::mailbox::MailboxType;

use super::answer::Fault;

/// The master's own dictionary.
pub const MASTER_ADDRESS: u16 = 0x0000;
/// Base of the position addresses: 0x8000 + ring position.
pub const POSITION_BASE: u16 = 0x8000;
/// Every slave that serves the protocol.
pub const BROADCAST_ADDRESS: u16 = 0xFFFF;

/// A request's destination.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Target {
    /// Address 0.
    Master,
    /// One slave, by station address.
    Slave(u16),
    /// 0xFFFF.
    Broadcast,
}

/// Resolves `address` against the slaves of the master's last scan.
pub(crate) fn target(master: &Master, address: u16) -> Result<Target, Fault> {
    match address {
        MASTER_ADDRESS => return Ok(Target::Master),
        BROADCAST_ADDRESS => return Ok(Target::Broadcast),
        _ => {}
    }
    if let Ok(station) = master.station(SlaveAddress::Station(address)) {
        return Ok(Target::Slave(station));
    }
    if address >= POSITION_BASE
        && let Ok(station) = master.station(SlaveAddress::Position(address - POSITION_BASE))
    {
        return Ok(Target::Slave(station));
    }
    Err(Fault::UnknownAddress)
}

/// The mailbox of the slave at `station`, if it serves `mailbox_type` now.
pub(crate) fn mailbox(
    master: &Master,
    station: u16,
    mailbox_type: MailboxType,
) -> Result<SlaveMailbox, Fault> {
    let mailbox = master
        .mailbox(SlaveAddress::Station(station))
        .map_err(|err| match err {
            MasterError::UnknownSlave(_) => Fault::UnknownAddress,
            MasterError::Absent { .. } => Fault::Absent,
            MasterError::NoMailbox { .. } => {
                let has_one = master
                    .slave(SlaveAddress::Station(station))
                    .is_ok_and(|s| s.mailbox.is_some());
                if has_one {
                    Fault::NotRunning
                } else {
                    Fault::Unsupported
                }
            }
            _ => Fault::Other,
        })?;
    let served = !matches!(mailbox_type, MailboxType::Error | MailboxType::Unknown(_))
        && mailbox.config().protocols.supports(mailbox_type);
    if served {
        Ok(mailbox)
    } else {
        Err(Fault::Unsupported)
    }
}
