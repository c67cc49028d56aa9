//! What the master reports about its segment.

use crate::wire::register::{AlState, AlStatusCode};

use super::bringup::slave_config::TopologyProblem;
use super::info::Identity;

/// Something that happened on the segment. Delivered to every subscriber of
/// [`Master::events`](super::Master::events), in order; a subscriber that falls behind by
/// more than [`MasterConfig::event_capacity`](super::MasterConfig::event_capacity) events
/// loses the oldest and is told how many.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MasterEvent {
    /// A scan found a slave, or a lost slave answers again.
    SlaveFound {
        /// Ring position.
        position: u16,
        /// Station address.
        station: u16,
        /// Identity.
        identity: Identity,
        /// Device name.
        name: String,
    },
    /// A slave stopped answering (unplugged, powered off, cable broken before it).
    SlaveLost {
        /// Ring position.
        position: u16,
        /// Station address.
        station: u16,
        /// Device name.
        name: String,
    },
    /// Another device answers at a known slave's position.
    SlaveReplaced {
        /// Ring position.
        position: u16,
        /// Station address (assigned again).
        station: u16,
        /// Identity of the slave that was there.
        old: Identity,
        /// Identity of the slave now there.
        new: Identity,
        /// Name of the new device.
        name: String,
    },
    /// A slave changed AL state.
    StateChanged {
        /// Ring position.
        position: u16,
        /// Station address.
        station: u16,
        /// Previous state.
        from: AlState,
        /// New state.
        to: AlState,
    },
    /// A slave signalled an AL error (refused a state change or left a state).
    AlError {
        /// Ring position.
        position: u16,
        /// Station address.
        station: u16,
        /// Device name.
        name: String,
        /// State the slave is in.
        state: AlState,
        /// The AL status code; `Display` gives its name.
        code: AlStatusCode,
    },
    /// The segment is not what the configuration expects: a slave not the one expected
    /// (it is held in PREOP), one missing, or one no entry names.
    TopologyMismatch {
        /// Ring position (of a missing slave: the configured one, if by position).
        position: u16,
        /// Station address.
        station: u16,
        /// What is wrong.
        problem: TopologyProblem,
    },
    /// A start-up command failed; the slave's bring-up stopped before the transition.
    StartupFailed {
        /// Ring position.
        position: u16,
        /// Station address.
        station: u16,
        /// The transition, e.g. `PREOP -> SAFEOP`.
        transition: String,
        /// The command, e.g. `SDO 0x6060:00`.
        command: String,
        /// The SDO abort code, if the slave aborted the transfer.
        abort_code: Option<u32>,
        /// The error in words.
        error: String,
    },
}
