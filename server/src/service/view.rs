//! What the core hands to both APIs: plain serialisable views of the master's types.

use master_core::bus::redundancy::RingStatus;
use master_core::master::{MasterEvent, SlaveInfo, TopologyProblem};
use master_core::wire::register::AlState;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// The `state` of a slave that did not answer the master's last look.
pub const ABSENT: &str = "ABSENT";

/// An AL state by its name ([`AlState::name`]: `INIT`, `PREOP`, `BOOT`, `SAFEOP`, `OP`), and
/// a value outside the state machine with its raw bits (`UNKNOWN(0x6)`).
pub fn state_name(state: AlState) -> String {
    match state {
        AlState::Unknown(raw) => format!("UNKNOWN({raw:#x})"),
        known => known.name().into(),
    }
}

/// A state as the APIs show it: an AL state, or [`ABSENT`] for a slave that did not answer.
/// Serialised as its name ([`state_name`]), typed everywhere else: gRPC maps it to its enum
/// without reading the name back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShownState {
    /// The slave did not answer the master's last look.
    Absent,
    /// An AL state.
    Al(AlState),
}

impl ShownState {
    /// Its name: `ABSENT`, or [`state_name`].
    pub fn name(self) -> String {
        match self {
            ShownState::Absent => ABSENT.to_owned(),
            ShownState::Al(state) => state_name(state),
        }
    }
}

impl Serialize for ShownState {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(&self.name())
    }
}

impl<'de> Deserialize<'de> for ShownState {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let name = String::deserialize(deserializer)?;
        if name == ABSENT {
            return Ok(ShownState::Absent);
        }
        if let Some(raw) = name
            .strip_prefix("UNKNOWN(0x")
            .and_then(|rest| rest.strip_suffix(')'))
        {
            return u8::from_str_radix(raw, 16)
                .map(|raw| ShownState::Al(AlState::from(raw)))
                .map_err(serde::de::Error::custom);
        }
        crate::input::state::parse_state(&name)
            .map(ShownState::Al)
            .map_err(|err| serde::de::Error::custom(err.message))
    }
}

/// Vendor, product, revision and serial number.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct IdentityView {
    /// Vendor id.
    pub vendor_id: u32,
    /// Product code.
    pub product_code: u32,
    /// Revision number.
    pub revision: u32,
    /// Serial number.
    pub serial: u32,
}

/// One slave.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct SlaveView {
    /// Ring position.
    pub position: u16,
    /// Configured station address.
    pub station: u16,
    /// Station alias (0: none).
    pub alias: u16,
    /// Identity from the SII.
    pub identity: IdentityView,
    /// Name from the SII.
    pub name: String,
    /// Current AL state; [`ABSENT`] while the slave does not answer.
    #[schema(value_type = String)]
    pub state: ShownState,
    /// The error indication of the AL status register.
    pub al_error: bool,
    /// AL status code.
    pub al_status_code: u16,
    /// Text of the AL status code.
    pub al_status_text: String,
    /// Mailbox protocols (`CoE`, `SoE`, `FoE`, `VoE`, `EoE`, `AoE`).
    pub mailbox_protocols: Vec<String>,
    /// The state the master keeps the slave in.
    #[schema(value_type = String)]
    pub requested_state: ShownState,
    /// Whether the slave answered the last look.
    pub present: bool,
}

impl From<&SlaveInfo> for SlaveView {
    fn from(info: &SlaveInfo) -> SlaveView {
        let mut mailbox_protocols = Vec::new();
        if let Some(mailbox) = &info.mailbox {
            let p = mailbox.protocols;
            for (flag, name) in [
                (p.coe(), "CoE"),
                (p.soe(), "SoE"),
                (p.foe(), "FoE"),
                (p.voe(), "VoE"),
                (p.eoe(), "EoE"),
                (p.aoe(), "AoE"),
            ] {
                if flag {
                    mailbox_protocols.push(name.to_owned());
                }
            }
        }
        SlaveView {
            position: info.position,
            station: info.station,
            alias: info.alias,
            identity: IdentityView {
                vendor_id: info.identity.vendor_id,
                product_code: info.identity.product_code,
                revision: info.identity.revision,
                serial: info.identity.serial,
            },
            name: info.name.clone(),
            // A lost slave's last AL state says nothing of now (issue 35: "OP" beside
            // `present: false` read as live).
            state: if info.present {
                ShownState::Al(info.al_state)
            } else {
                ShownState::Absent
            },
            al_error: info.al_error,
            al_status_code: u16::from(info.al_status_code),
            al_status_text: info.al_status_code.description().to_owned(),
            mailbox_protocols,
            requested_state: ShownState::Al(info.requested_state),
            present: info.present,
        }
    }
}

/// A topology or state event.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct EventView {
    /// Number of the event, rising while ecatd runs (the server-sent event's `id`, for
    /// `Last-Event-ID`); 0 for the `lagged` note a stream sends one subscriber.
    #[serde(default)]
    pub id: u64,
    /// When ecatd published it: UTC, RFC 3339 with milliseconds (`2026-11-29T07:10:00.123Z`);
    /// empty for a `lagged` note.
    #[serde(default)]
    pub time: String,
    /// `slave_found`, `slave_lost`, `slave_replaced`, `state_changed`, `al_error`,
    /// `topology_mismatch`, `startup_failed`, `emergency`, `bus_fault`, `bus_recovered`,
    /// `ring_broken`, `ring_closed`, `gateway_started`, `gateway_stopped`, `gateway_failed`, `write`, the application
    /// interface's (`app_*`, `process_data_*`), `foe_progress`, `lagged`
    /// (docs/operations.md, "APIs").
    pub kind: String,
    /// Ring position.
    pub position: u16,
    /// Station address.
    pub station: u16,
    /// Slave name, when the event has it.
    pub name: String,
    /// State before (state changes).
    #[schema(value_type = Option<String>)]
    pub from: Option<ShownState>,
    /// State after (state changes, AL errors).
    #[schema(value_type = Option<String>)]
    pub to: Option<ShownState>,
    /// AL status code (AL errors).
    pub al_status_code: Option<u16>,
    /// New identity (found, replaced).
    pub identity: Option<IdentityView>,
    /// The CoE emergency (kind `emergency`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub emergency: Option<EmergencyView>,
    /// The progress of an FoE transfer (kind `foe_progress`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transfer: Option<TransferView>,
    /// The ring's state (kinds `ring_broken` and `ring_closed`, docs/redundancy.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ring: Option<RedundancyView>,
    /// Summary.
    pub text: String,
}

/// How far an FoE transfer through the API has come: what a progress bar needs
/// (`bytes` of `total`). Published as `foe_progress` events at most every
/// [`PROGRESS_PERIOD`](super::transfer::PROGRESS_PERIOD), and once more when the last byte
/// moved.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct TransferView {
    /// Number of the transfer, unique while ecatd runs (the events of one transfer share it).
    pub id: u64,
    /// The file on the slave.
    pub file: String,
    /// `read` or `write`.
    pub direction: String,
    /// File bytes acknowledged by the slave (write) or received from it (read) so far.
    pub bytes: u64,
    /// Size of the file: known for writes, absent for reads until the last packet.
    pub total: Option<u64>,
    /// Whether the last packet moved (the transfer's result follows on its own call).
    pub done: bool,
}

/// A CoE emergency a slave sent (ETG.1000.6, spec-notes §coe.emcy).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct EmergencyView {
    /// CiA 301 error code.
    pub error_code: u16,
    /// Error register (object 0x1001).
    pub error_register: u8,
    /// The five manufacturer-specific bytes, hex.
    pub data: String,
}

impl EventView {
    /// The progress of an FoE transfer with the slave at `position` / `station`.
    pub fn foe_progress(
        position: u16,
        station: u16,
        text: String,
        transfer: TransferView,
    ) -> EventView {
        EventView {
            kind: "foe_progress".into(),
            position,
            station,
            text,
            transfer: Some(transfer),
            ..EventView::lagged(0)
        }
    }

    /// An event of the application interface (`app_claimed`, `app_released`,
    /// `app_watchdog`, `app_layout_changed`).
    pub fn app(event: &crate::app::AppEvent) -> EventView {
        EventView {
            kind: event.kind().into(),
            text: event.text(),
            ..EventView::lagged(0)
        }
    }

    /// An event of ecatd itself, about no slave (`gateway_started`, `bus_fault`, `write`,
    /// ...), with its words.
    pub fn note(kind: &str, text: String) -> EventView {
        EventView {
            kind: kind.into(),
            text,
            ..EventView::lagged(0)
        }
    }

    /// The event for a subscriber that fell behind and missed `missed` events.
    pub fn lagged(missed: u64) -> EventView {
        EventView {
            id: 0,
            time: String::new(),
            kind: "lagged".into(),
            position: 0,
            station: 0,
            name: String::new(),
            from: None,
            to: None,
            al_status_code: None,
            identity: None,
            emergency: None,
            transfer: None,
            ring: None,
            text: format!("{missed} events were missed"),
        }
    }
}

impl From<&MasterEvent> for EventView {
    fn from(event: &MasterEvent) -> EventView {
        let id = |i: &master_core::master::Identity| IdentityView {
            vendor_id: i.vendor_id,
            product_code: i.product_code,
            revision: i.revision,
            serial: i.serial,
        };
        let base = |kind: &str, position: u16, station: u16, name: &str| EventView {
            id: 0,
            time: String::new(),
            kind: kind.into(),
            position,
            station,
            name: name.into(),
            from: None,
            to: None,
            al_status_code: None,
            identity: None,
            emergency: None,
            transfer: None,
            ring: None,
            text: String::new(),
        };
        let mut view = match event {
            MasterEvent::SlaveFound {
                position,
                station,
                identity,
                name,
            } => EventView {
                identity: Some(id(identity)),
                ..base("slave_found", *position, *station, name)
            },
            MasterEvent::SlaveLost {
                position,
                station,
                name,
            } => base("slave_lost", *position, *station, name),
            MasterEvent::SlaveReplaced {
                position,
                station,
                new,
                name,
                ..
            } => EventView {
                identity: Some(id(new)),
                ..base("slave_replaced", *position, *station, name)
            },
            MasterEvent::StateChanged {
                position,
                station,
                from,
                to,
            } => EventView {
                from: Some(ShownState::Al(*from)),
                to: Some(ShownState::Al(*to)),
                ..base("state_changed", *position, *station, "")
            },
            MasterEvent::AlError {
                position,
                station,
                name,
                state,
                code,
            } => EventView {
                to: Some(ShownState::Al(*state)),
                al_status_code: Some(u16::from(*code)),
                ..base("al_error", *position, *station, name)
            },
            MasterEvent::TopologyMismatch {
                position,
                station,
                problem,
            } => {
                let found = match problem {
                    TopologyProblem::Mismatch { found, .. } | TopologyProblem::Extra { found } => {
                        Some(id(found))
                    }
                    TopologyProblem::Missing { .. } => None,
                };
                EventView {
                    identity: found,
                    ..base("topology_mismatch", *position, *station, "")
                }
            }
            MasterEvent::StartupFailed {
                position, station, ..
            } => base("startup_failed", *position, *station, ""),
        };
        view.text = text_of(event);
        view
    }
}

/// The event in words, for the log and the dashboard (`slave 2 (EL2008) lost`).
fn text_of(event: &MasterEvent) -> String {
    let slave = |position: u16, name: &str| {
        if name.is_empty() {
            format!("slave {position}")
        } else {
            format!("slave {position} ({name})")
        }
    };
    let identity = |i: &master_core::master::Identity| {
        format!(
            "vendor {:#010x}, product {:#010x}, revision {:#010x}",
            i.vendor_id, i.product_code, i.revision
        )
    };
    match event {
        MasterEvent::SlaveFound {
            position,
            identity: found,
            name,
            ..
        } => format!("{} found: {}", slave(*position, name), identity(found)),
        MasterEvent::SlaveLost { position, name, .. } => {
            format!("{} lost", slave(*position, name))
        }
        MasterEvent::SlaveReplaced {
            position,
            old,
            new,
            name,
            ..
        } => format!(
            "{} replaced: now {}, was {}",
            slave(*position, name),
            identity(new),
            identity(old)
        ),
        MasterEvent::StateChanged {
            position, from, to, ..
        } => format!(
            "slave {position}: {} -> {}",
            state_name(*from),
            state_name(*to)
        ),
        MasterEvent::AlError {
            position,
            name,
            state,
            code,
            ..
        } => format!(
            "{} AL error in {}: {:#06x} {}",
            slave(*position, name),
            state_name(*state),
            u16::from(*code),
            code.description()
        ),
        MasterEvent::TopologyMismatch {
            position, problem, ..
        } => format!("slave {position}: {problem}"),
        MasterEvent::StartupFailed {
            position,
            transition,
            command,
            abort_code,
            error,
            ..
        } => {
            let abort = abort_code.map_or(String::new(), |code| format!(" (abort 0x{code:08X})"));
            format!("slave {position}: start-up {command} at {transition} failed: {error}{abort}")
        }
    }
}

pub use crate::input::ip::IpView;

/// An object of the CoE dictionary (SDO Information).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct ObjectView {
    /// Index.
    pub index: u16,
    /// Data type code.
    pub data_type: u16,
    /// Data type name.
    pub data_type_name: String,
    /// Highest subindex.
    pub max_subindex: u8,
    /// Object code (7 VAR, 8 ARRAY, 9 RECORD).
    pub object_code: u8,
    /// Name.
    pub name: String,
}

/// An entry of a CoE object (SDO Information).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct EntryView {
    /// Index.
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
    /// Data type code.
    pub data_type: u16,
    /// Data type name.
    pub data_type_name: String,
    /// Size in bits.
    pub bit_length: u16,
    /// Access flags.
    pub access: u16,
    /// Description.
    pub description: String,
}

/// A VoE message.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct VoeView {
    /// Vendor id.
    pub vendor_id: u32,
    /// Vendor type.
    pub vendor_type: u16,
    /// Payload, hex.
    pub data: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shown_state_is_its_name_on_the_wire_and_reads_back() {
        let mut states: Vec<ShownState> = AlState::ALL.into_iter().map(ShownState::Al).collect();
        states.extend([ShownState::Absent, ShownState::Al(AlState::Unknown(0x6))]);
        for state in states {
            let json = serde_json::to_string(&state).unwrap();
            assert_eq!(json, format!("\"{}\"", state.name()));
            assert_eq!(serde_json::from_str::<ShownState>(&json).unwrap(), state);
        }
        assert_eq!(ShownState::Al(AlState::PreOp).name(), "PREOP");
        assert_eq!(ShownState::Al(AlState::Unknown(0x6)).name(), "UNKNOWN(0x6)");
        assert!(serde_json::from_str::<ShownState>("\"RUNNING\"").is_err());
    }
}

/// The ring, as the APIs show it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct RedundancyView {
    /// `off` (one port, no ring), `unknown` (no frame back yet), `closed` or `broken`.
    pub state: String,
    /// With the ring broken: the break is after this many slaves from the primary port
    /// (0: the master's primary cable); null otherwise.
    pub break_after: Option<u16>,
    /// Slaves the last frame reached from the primary port.
    pub primary_side: u16,
    /// Slaves the last frame reached from the backup port (0 with the ring closed).
    pub backup_side: u16,
    /// Slaves in the ring as last seen closed.
    pub ring_slaves: u16,
    /// With the ring broken: slaves reached from neither port (a slave without power, or
    /// the slaves between two breaks).
    pub unreachable: u16,
    /// Times the ring broke since ecatd started.
    pub breaks: u64,
    /// Times the ring closed again after a break.
    pub heals: u64,
}

impl RedundancyView {
    /// No ring: the bus runs on one port.
    pub fn off() -> RedundancyView {
        RedundancyView {
            state: "off".into(),
            break_after: None,
            primary_side: 0,
            backup_side: 0,
            ring_slaves: 0,
            unreachable: 0,
            breaks: 0,
            heals: 0,
        }
    }

    /// The ring as `status` shows it.
    pub fn of(status: &RingStatus) -> RedundancyView {
        RedundancyView {
            state: status.state.name().into(),
            break_after: status.break_after,
            primary_side: status.primary_side,
            backup_side: status.backup_side,
            ring_slaves: status.ring_slaves,
            unreachable: status.unreachable,
            breaks: status.breaks,
            heals: status.heals,
        }
    }
}
