//! What can go wrong when the master talks to its slaves.

use crate::bus::BusError;
use crate::mailbox::MailboxError;
use crate::wire::WireError;
use crate::wire::register::{AlState, AlStatusCode};

use super::access::address::SlaveAddress;

/// Why a master operation failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MasterError {
    /// A datagram failed (timeout, wrong working counter, bus stopped).
    #[error("{what}: {source}")]
    Bus {
        /// What the master was doing.
        what: &'static str,
        /// The bus's error.
        source: BusError,
    },
    /// No scanned slave has this address.
    #[error("no slave at {0}")]
    UnknownSlave(SlaveAddress),
    /// A slave refused a state change; `code` says why (with its name in `Display`).
    #[error(
        "slave {position} \"{name}\" (station {station:#06x}) refused {from} -> {to}: AL status code {code}"
    )]
    StateRefused {
        /// Ring position.
        position: u16,
        /// Station address.
        station: u16,
        /// Device name from the SII.
        name: String,
        /// State before the request.
        from: AlState,
        /// Requested state.
        to: AlState,
        /// The AL status code the slave reported.
        code: AlStatusCode,
    },
    /// A slave did not reach a state in time.
    #[error("slave {position} \"{name}\" did not reach {to} in time (still {state})")]
    StateTimeout {
        /// Ring position.
        position: u16,
        /// Device name from the SII.
        name: String,
        /// Requested state.
        to: AlState,
        /// The state it was in at the deadline.
        state: AlState,
    },
    /// The state cannot be requested this way (BOOT is reached from INIT only, say).
    #[error("cannot request {0} this way")]
    InvalidState(AlState),
    /// The EEPROM interface of a slave failed.
    #[error("station {station:#06x}: EEPROM {reason}")]
    Eeprom {
        /// Station address.
        station: u16,
        /// What went wrong.
        reason: &'static str,
    },
    /// Bytes from a slave (SII, registers) do not parse.
    #[error("slave {position}: {what}: {source}")]
    Malformed {
        /// Ring position.
        position: u16,
        /// What was being parsed.
        what: &'static str,
        /// The codec's error.
        source: WireError,
    },
    /// The slaves' process data is larger than one cyclic frame carries.
    #[error("process image of {need} bytes does not fit one frame ({room} bytes)")]
    ImageTooLarge {
        /// Bytes needed.
        need: usize,
        /// Bytes a frame carries.
        room: usize,
    },
    /// More slaves answered than station addresses fit above the configured base.
    #[error("{count} slaves do not fit station addresses from {base:#06x}")]
    TooManySlaves {
        /// Slaves counted.
        count: u16,
        /// Configured base.
        base: u16,
    },
    /// The slave did not answer the master's last look (link cut, powered off, removed):
    /// nothing is sent to it until it is found again.
    #[error("slave {position} (station {station:#06x}) is absent: it did not answer the last look")]
    Absent {
        /// Ring position.
        position: u16,
        /// Station address.
        station: u16,
    },
    /// The slave has no mailbox, or it is not served in the slave's state (INIT).
    #[error("slave {position} has no mailbox in {state}")]
    NoMailbox {
        /// Ring position.
        position: u16,
        /// The slave's AL state.
        state: AlState,
    },
    /// A mailbox transfer the master needed (reading or writing the PDO configuration)
    /// failed.
    #[error("slave {position}: {what}: {source}")]
    Mailbox {
        /// Ring position.
        position: u16,
        /// What the master was doing.
        what: &'static str,
        /// The mailbox engine's error.
        source: MailboxError,
    },
    /// A start-up command of the slave's configuration failed (ETG.1020 §6.4); the slave
    /// stays in the state it was in.
    #[error("slave {position}: start-up command {command} ({transition}) failed: {source}")]
    Startup {
        /// Ring position.
        position: u16,
        /// The transition it belonged to, e.g. `PREOP -> SAFEOP`.
        transition: String,
        /// The command, e.g. `SDO 0x6060:00`.
        command: String,
        /// The mailbox error (an SDO abort carries its abort code).
        source: MailboxError,
    },
    /// The configuration does not fit the segment (found before anything was written).
    #[error("slave {position}: {reason}")]
    Configuration {
        /// Ring position.
        position: u16,
        /// What is wrong.
        reason: String,
    },
    /// A value the caller passed cannot be used.
    #[error("invalid argument: {0}")]
    InvalidArgument(&'static str),
    /// The master (its background thread) has stopped.
    #[error("the master has stopped")]
    Stopped,
}

impl MasterError {
    /// A bus error while doing `what`.
    pub(crate) fn bus(what: &'static str) -> impl FnOnce(BusError) -> MasterError {
        move |source| MasterError::Bus { what, source }
    }

    /// The AL status code, for a refused state change.
    pub fn al_status_code(&self) -> Option<AlStatusCode> {
        match self {
            MasterError::StateRefused { code, .. } => Some(*code),
            _ => None,
        }
    }
}
