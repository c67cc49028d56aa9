//! The core's views as `ecat.v1` messages.

use master_core::wire::register::AlState;
use proto::v1 as pb;
use tonic::Status;

use crate::service::view::ShownState;
use crate::service::{ApiError, EventView, IdentityView, SlaveView};

/// The protobuf enum of an AL state (`Unspecified` for a value outside the state machine).
pub fn pb_state(state: AlState) -> pb::AlState {
    match state {
        AlState::Init => pb::AlState::Init,
        AlState::PreOp => pb::AlState::Preop,
        AlState::Boot => pb::AlState::Boot,
        AlState::SafeOp => pb::AlState::Safeop,
        AlState::Op => pb::AlState::Op,
        AlState::Unknown(_) => pb::AlState::Unspecified,
    }
}

/// The AL state of a protobuf enum value, if it names one.
pub fn state_of(value: i32) -> Option<AlState> {
    AlState::ALL
        .into_iter()
        .find(|&state| pb_state(state) as i32 == value)
}

/// The protobuf enum of a view's state (`ABSENT` and unknown values: `Unspecified`).
pub fn al_state(state: ShownState) -> pb::AlState {
    match state {
        ShownState::Al(state) => pb_state(state),
        ShownState::Absent => pb::AlState::Unspecified,
    }
}

/// The AL state a request names.
pub fn requested_state(value: i32) -> Result<AlState, Status> {
    state_of(value).ok_or_else(|| {
        Status::from(ApiError::invalid_field(
            "state",
            format!("no AL state {value}"),
        ))
    })
}

fn identity(id: &IdentityView) -> pb::Identity {
    pb::Identity {
        vendor_id: id.vendor_id,
        product_code: id.product_code,
        revision: id.revision,
        serial: id.serial,
    }
}

/// A slave.
pub fn slave(view: &SlaveView) -> pb::Slave {
    pb::Slave {
        position: u32::from(view.position),
        station: u32::from(view.station),
        alias: u32::from(view.alias),
        identity: Some(identity(&view.identity)),
        name: view.name.clone(),
        state: al_state(view.state) as i32,
        al_error: view.al_error,
        al_status_code: u32::from(view.al_status_code),
        al_status_text: view.al_status_text.clone(),
        mailbox_protocols: view.mailbox_protocols.clone(),
        requested_state: al_state(view.requested_state) as i32,
        present: view.present,
    }
}

/// An event.
pub fn event(view: &EventView) -> pb::Event {
    let state = |s: Option<ShownState>| s.map_or(pb::AlState::Unspecified, al_state) as i32;
    pb::Event {
        kind: view.kind.clone(),
        position: u32::from(view.position),
        station: u32::from(view.station),
        name: view.name.clone(),
        from: state(view.from),
        to: state(view.to),
        al_status_code: view.al_status_code.map_or(0, u32::from),
        identity: view.identity.as_ref().map(identity),
        text: view.text.clone(),
        emergency: view.emergency.as_ref().map(|e| pb::Emergency {
            error_code: u32::from(e.error_code),
            error_register: u32::from(e.error_register),
            data: hex::decode(&e.data).unwrap_or_default(),
        }),
        id: view.id,
        time: view.time.clone(),
        transfer: view.transfer.as_ref().map(|t| pb::TransferProgress {
            id: t.id,
            file: t.file.clone(),
            direction: t.direction.clone(),
            bytes: t.bytes,
            total: t.total,
            done: t.done,
        }),
        ring: view.ring.as_ref().map(redundancy),
    }
}

/// The ring's state.
pub fn redundancy(view: &crate::service::RedundancyView) -> pb::Redundancy {
    pb::Redundancy {
        state: view.state.clone(),
        break_after: view.break_after.map(u32::from),
        primary_side: u32::from(view.primary_side),
        backup_side: u32::from(view.backup_side),
        ring_slaves: u32::from(view.ring_slaves),
        unreachable: u32::from(view.unreachable),
        breaks: view.breaks,
        heals: view.heals,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_state_goes_to_its_enum_and_back_and_nothing_else_is_a_state() {
        for state in AlState::ALL {
            assert_eq!(state_of(pb_state(state) as i32), Some(state));
            assert_eq!(al_state(ShownState::Al(state)), pb_state(state));
            assert_eq!(requested_state(pb_state(state) as i32).unwrap(), state);
        }
        assert_eq!(state_of(pb::AlState::Unspecified as i32), None);
        assert_eq!(state_of(99), None);
        assert_eq!(
            requested_state(99).unwrap_err().code(),
            tonic::Code::InvalidArgument
        );
        assert_eq!(al_state(ShownState::Absent), pb::AlState::Unspecified);
        assert_eq!(pb_state(AlState::Unknown(0x6)), pb::AlState::Unspecified);
    }
}
