//! The core's views as `ecat.v1` messages.

use proto::v1 as pb;
use tonic::Status;

use crate::service::{ApiError, EventView, IdentityView, SlaveView};

/// The protobuf enum for a state name.
pub fn al_state(name: &str) -> pb::AlState {
    match name {
        "INIT" => pb::AlState::Init,
        "PREOP" => pb::AlState::Preop,
        "BOOT" => pb::AlState::Boot,
        "SAFEOP" => pb::AlState::Safeop,
        "OP" => pb::AlState::Op,
        _ => pb::AlState::Unspecified,
    }
}

/// The state name of a protobuf enum value.
pub fn state_name(value: i32) -> Result<&'static str, Status> {
    match pb::AlState::try_from(value) {
        Ok(pb::AlState::Init) => Ok("INIT"),
        Ok(pb::AlState::Preop) => Ok("PREOP"),
        Ok(pb::AlState::Boot) => Ok("BOOT"),
        Ok(pb::AlState::Safeop) => Ok("SAFEOP"),
        Ok(pb::AlState::Op) => Ok("OP"),
        _ => Err(Status::from(ApiError::invalid(format!(
            "no AL state {value}"
        )))),
    }
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
        state: al_state(&view.state) as i32,
        al_error: view.al_error,
        al_status_code: u32::from(view.al_status_code),
        al_status_text: view.al_status_text.clone(),
        mailbox_protocols: view.mailbox_protocols.clone(),
        requested_state: al_state(&view.requested_state) as i32,
        present: view.present,
    }
}

/// An event.
pub fn event(view: &EventView) -> pb::Event {
    let state = |s: &Option<String>| s.as_deref().map_or(pb::AlState::Unspecified, al_state) as i32;
    pb::Event {
        kind: view.kind.clone(),
        position: u32::from(view.position),
        station: u32::from(view.station),
        name: view.name.clone(),
        from: state(&view.from),
        to: state(&view.to),
        al_status_code: view.al_status_code.map_or(0, u32::from),
        identity: view.identity.as_ref().map(identity),
        text: view.text.clone(),
        emergency: view.emergency.as_ref().map(|e| pb::Emergency {
            error_code: u32::from(e.error_code),
            error_register: u32::from(e.error_register),
            data: hex::decode(&e.data).unwrap_or_default(),
        }),
        transfer: view.transfer.as_ref().map(|t| pb::TransferProgress {
            id: t.id,
            file: t.file.clone(),
            direction: t.direction.clone(),
            bytes: t.bytes,
            total: t.total,
            done: t.done,
        }),
    }
}
