//! What a configuration says about individual slaves, checked and applied at every
//! bring-up (the scan, and the watch's repair after a power cycle or hot-plug): the
//! identity expected at an address, the start-up commands of each AL transition, and the
//! slave's own distributed-clock settings. A leaf, so the shared context can hold it.
//!
//! Start-up commands follow ETG.1020 §6.4 ("Start-up behaviour"; the InitCmds of an ENI,
//! ETG.2100 §6.5): each belongs to one transition and runs, in the configured order,
//! before the master requests that transition, except those of INIT → PREOP, which run as
//! soon as the slave is in PREOP (its mailbox only works from there on, ETG.1000.6 §6.4.2).

use std::time::Duration;

use crate::master::access::address::SlaveAddress;
use crate::master::info::{Identity, SlaveInfo};
use crate::wire::register::AlState;

/// How a found revision is compared with the expected one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RevisionMatch {
    /// The revision must be the one expected.
    #[default]
    Exact,
    /// The revision must be at least the one expected.
    Minimum,
}

/// The identity a configuration expects at an address (ETG.1000.6 §5.6.7.4.1, the SII
/// identity words; `None`: any value).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ExpectedIdentity {
    /// Vendor ID.
    pub vendor_id: Option<u32>,
    /// Product code.
    pub product_code: Option<u32>,
    /// Revision number.
    pub revision: Option<u32>,
    /// How `revision` is compared.
    pub revision_match: RevisionMatch,
}

impl ExpectedIdentity {
    /// Why `found` is not what is expected; `None` when it is.
    pub fn mismatch(&self, found: &Identity) -> Option<String> {
        if let Some(vendor) = self.vendor_id
            && vendor != found.vendor_id
        {
            return Some(format!(
                "vendor {:#010x} expected, {:#010x} found",
                vendor, found.vendor_id
            ));
        }
        if let Some(product) = self.product_code
            && product != found.product_code
        {
            return Some(format!(
                "product code {:#010x} expected, {:#010x} found",
                product, found.product_code
            ));
        }
        match (self.revision, self.revision_match) {
            (Some(rev), RevisionMatch::Exact) if rev != found.revision => Some(format!(
                "revision {:#010x} expected, {:#010x} found",
                rev, found.revision
            )),
            (Some(rev), RevisionMatch::Minimum) if found.revision < rev => Some(format!(
                "revision {:#010x} or later expected, {:#010x} found",
                rev, found.revision
            )),
            _ => None,
        }
    }
}

/// An AL state transition (ETG.1000.6 §6.4.1, Figure 30), to which start-up commands
/// belong.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Transition {
    /// State left.
    pub from: AlState,
    /// State entered.
    pub to: AlState,
}

impl Transition {
    /// INIT → PREOP ("IP").
    pub const INIT_PREOP: Transition = Transition {
        from: AlState::Init,
        to: AlState::PreOp,
    };
    /// PREOP → SAFEOP ("PS").
    pub const PREOP_SAFEOP: Transition = Transition {
        from: AlState::PreOp,
        to: AlState::SafeOp,
    };
    /// SAFEOP → OP ("SO").
    pub const SAFEOP_OP: Transition = Transition {
        from: AlState::SafeOp,
        to: AlState::Op,
    };

    /// The two-letter name ETG.2100 uses (`IP`, `PS`, `SO`, `SP`, `OS`, `OP`, `PI`,
    /// `SI`, `OI`, `IB`, `BI`).
    pub fn code(&self) -> String {
        let letter = |s: AlState| match s {
            AlState::Init => 'I',
            AlState::PreOp => 'P',
            AlState::SafeOp => 'S',
            AlState::Op => 'O',
            AlState::Boot => 'B',
            AlState::Unknown(_) => '?',
        };
        [letter(self.from), letter(self.to)].iter().collect()
    }

    /// The transition an ETG.2100 two-letter name stands for.
    pub fn from_code(code: &str) -> Option<Transition> {
        let state = |c: u8| match c {
            b'I' => Some(AlState::Init),
            b'P' => Some(AlState::PreOp),
            b'S' => Some(AlState::SafeOp),
            b'O' => Some(AlState::Op),
            b'B' => Some(AlState::Boot),
            _ => None,
        };
        match code.to_ascii_uppercase().as_bytes() {
            [a, b] if a != b => Some(Transition {
                from: state(*a)?,
                to: state(*b)?,
            }),
            _ => None,
        }
    }
}

impl std::fmt::Display for Transition {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} -> {}", self.from, self.to)
    }
}

/// What one start-up command does.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum StartupAction {
    /// A CoE SDO download (ETG.1000.6 §5.6.2.2-3: expedited for up to 4 bytes, normal
    /// beyond; with `complete_access`, the whole object from `subindex` on, §5.6.2.1).
    Sdo {
        /// Object index.
        index: u16,
        /// Subindex (0 or 1 with complete access).
        subindex: u8,
        /// The value, little-endian.
        data: Vec<u8>,
        /// Write the object by complete access.
        complete_access: bool,
    },
    /// An SoE write of an IDN's value (ETG.1000.6 §5.8, IEC 61800-7-204).
    Idn {
        /// Drive number (0..=7).
        drive: u8,
        /// The IDN.
        idn: u16,
        /// The value, little-endian.
        data: Vec<u8>,
    },
}

impl std::fmt::Display for StartupAction {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StartupAction::Sdo {
                index,
                subindex,
                complete_access,
                ..
            } => {
                let ca = if *complete_access { " (complete)" } else { "" };
                write!(f, "SDO {index:#06x}:{subindex:02x}{ca}")
            }
            StartupAction::Idn { drive, idn, .. } => write!(f, "IDN {idn} of drive {drive}"),
        }
    }
}

/// A start-up command: an action and the transition it belongs to.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct StartupCommand {
    /// When it runs.
    pub transition: Transition,
    /// What it does.
    pub action: StartupAction,
}

/// One SYNC signal's cycle and shift.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SyncSignal {
    /// Cycle time (0x09A0 for SYNC0, 0x09A4 for SYNC1; ETG.1000.4 §6.8.5, Table 60).
    pub cycle: Duration,
    /// Shift of the signal from a multiple of the cycle.
    pub shift: Duration,
}

/// A slave's own distributed-clock settings, over the master's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SlaveDc {
    /// No SYNC signals on this slave (it still gets its delay and offset).
    Off,
    /// SYNC0, and SYNC1 if given, at these cycles.
    Sync {
        /// SYNC0.
        sync0: SyncSignal,
        /// SYNC1, if any.
        sync1: Option<SyncSignal>,
    },
}

/// The configuration of one slave.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SlaveConfig {
    /// Which slave (position, station or alias).
    pub address: Option<SlaveAddress>,
    /// The identity expected there; `None`: no check.
    pub expected: Option<ExpectedIdentity>,
    /// Its start-up commands, in order.
    pub startup: Vec<StartupCommand>,
    /// Its DC settings; `None`: the master's.
    pub dc: Option<SlaveDc>,
}

impl SlaveConfig {
    /// Whether this configuration names the slave of `info`.
    pub fn names(&self, info: &SlaveInfo) -> bool {
        match self.address {
            Some(SlaveAddress::Position(p)) => p == info.position,
            Some(SlaveAddress::Station(s)) => s == info.station,
            Some(SlaveAddress::Alias(a)) => a != 0 && a == info.alias,
            None => false,
        }
    }
}

/// What happens when a slave is not the one expected, or one expected is missing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MismatchPolicy {
    /// Only that slave stays in PREOP; the others go on.
    #[default]
    Slave,
    /// Every slave stays in PREOP.
    Segment,
    /// The scan fails before any slave leaves INIT (an ENI describes the exact network,
    /// ETG.2100 §6.2).
    Stop,
}

/// The SyncManager watchdog every slave with process data gets before SAFEOP
/// (ETG.1000.4 §6.3, Table 30: divider 0x0400, process-data watchdog time 0x0420).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Watchdog {
    /// Watchdog divider: one tick is (divider + 2) × 40 ns.
    pub divider: u16,
    /// Process-data watchdog time in ticks (0: off).
    pub process_data_ticks: u16,
}

/// The per-slave configuration the master applies at every bring-up.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SlaveConfigs {
    /// One entry per configured slave.
    pub slaves: Vec<SlaveConfig>,
    /// What a mismatch holds back.
    pub policy: MismatchPolicy,
    /// Report slaves no entry names (only when there are entries).
    pub report_extra: bool,
    /// The SyncManager watchdog to set; `None`: the slaves' own.
    pub watchdog: Option<Watchdog>,
}

impl SlaveConfigs {
    /// The entry naming the slave of `info`.
    pub fn for_slave(&self, info: &SlaveInfo) -> Option<&SlaveConfig> {
        self.slaves.iter().find(|c| c.names(info))
    }
}

/// What is wrong with the segment against the configuration.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TopologyProblem {
    /// The slave found is not the one expected.
    Mismatch {
        /// What was expected.
        expected: ExpectedIdentity,
        /// What was found.
        found: Identity,
        /// In words.
        reason: String,
    },
    /// No slave answers at a configured address.
    Missing {
        /// The configured address.
        address: SlaveAddress,
    },
    /// A slave no entry names.
    Extra {
        /// Its identity.
        found: Identity,
    },
}

impl std::fmt::Display for TopologyProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TopologyProblem::Mismatch { reason, .. } => {
                write!(f, "not the slave expected: {reason}")
            }
            TopologyProblem::Missing { address } => write!(f, "no slave at {address}"),
            TopologyProblem::Extra { found } => write!(
                f,
                "a slave not in the configuration (vendor {:#010x}, product {:#010x})",
                found.vendor_id, found.product_code
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn identity(revision: u32) -> Identity {
        Identity {
            vendor_id: 2,
            product_code: 0x1234,
            revision,
            serial: 0,
        }
    }

    #[test]
    fn revisions_compare_exactly_or_as_a_minimum() {
        let mut expected = ExpectedIdentity {
            vendor_id: Some(2),
            product_code: Some(0x1234),
            revision: Some(5),
            revision_match: RevisionMatch::Exact,
        };
        assert_eq!(expected.mismatch(&identity(5)), None);
        assert!(expected.mismatch(&identity(6)).is_some());
        expected.revision_match = RevisionMatch::Minimum;
        assert_eq!(expected.mismatch(&identity(6)), None);
        assert!(
            expected
                .mismatch(&identity(4))
                .unwrap()
                .contains("or later")
        );
        expected.product_code = Some(1);
        assert!(
            expected
                .mismatch(&identity(6))
                .unwrap()
                .contains("product code")
        );
    }

    #[test]
    fn transitions_have_their_etg_2100_names() {
        assert_eq!(Transition::PREOP_SAFEOP.code(), "PS");
        assert_eq!(Transition::from_code("so"), Some(Transition::SAFEOP_OP));
        assert_eq!(Transition::from_code("PP"), None);
        assert_eq!(Transition::from_code("PX"), None);
    }
}
