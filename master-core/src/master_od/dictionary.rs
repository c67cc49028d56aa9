//! Builds the master's dictionary from a [`MasterSnapshot`], with the write hooks that turn
//! downloads into [`Action`]s for the caller to carry out (a hook runs inside the SDO
//! server and cannot wait for the bus).

use std::sync::{Arc, Mutex, PoisonError};

use crate::od::{BuildError, StaticDictionary};
use crate::wire::coe::AbortCode;

use super::device::{
    self, DIAGNOSIS_CONTROL, RESET_DIAGNOSIS_SUBINDEX, SCAN_COMMAND, SCAN_REQUEST,
};
use super::identity::{self, MasterIdentity};
use super::slaves::{self, AL_CONTROL_SUBINDEX, DIAGNOSIS};
use super::snapshot::MasterSnapshot;

/// Something a download asks the master to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// 0xAnnn:02 written: bring the slave at `position` to the state in `control`
    /// (bits 0-3; the acknowledge bit 4 is implied, the master acknowledges errors itself).
    RequestState {
        /// Ring position (n of 0xAnnn).
        position: u16,
        /// The value written.
        control: u16,
    },
    /// 0xF002:01 written with the scan request: scan the segment again.
    Scan,
    /// 0xF200:10 written with TRUE: zero the diagnosis counters.
    ResetDiagnosis,
}

/// Where the hooks put the actions of one request.
pub(crate) type Actions = Arc<Mutex<Vec<Action>>>;

fn push(actions: &Actions, action: Action) {
    actions
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .push(action);
}

/// The dictionary for `snap`; downloads add their actions to `actions`.
pub(crate) fn build(
    snap: &MasterSnapshot,
    identity: &MasterIdentity,
    actions: &Actions,
) -> Result<StaticDictionary, BuildError> {
    let b = StaticDictionary::builder();
    let b = identity::declare(b, identity);
    let b = slaves::declare(b, snap);
    let b = device::declare(b, snap);
    let mut dict = b.build()?;
    let sink = Arc::clone(actions);
    dict.on_write(DIAGNOSIS..=DIAGNOSIS + 0x0FFF, move |event, dict| {
        if event.subindices.contains(&AL_CONTROL_SUBINDEX) {
            let control: u16 = dict
                .get(event.index, AL_CONTROL_SUBINDEX)
                .map_err(|_| AbortCode::GeneralError)?;
            if !matches!(control & 0x0F, 1 | 2 | 3 | 4 | 8) {
                return Err(AbortCode::ValueRange);
            }
            push(
                &sink,
                Action::RequestState {
                    position: event.index - DIAGNOSIS,
                    control,
                },
            );
        }
        Ok(())
    });
    let sink = Arc::clone(actions);
    dict.on_write(SCAN_COMMAND..=SCAN_COMMAND, move |_, dict| {
        let command = dict
            .get_bytes(SCAN_COMMAND, 1)
            .map_err(|_| AbortCode::GeneralError)?;
        if command != SCAN_REQUEST {
            return Err(AbortCode::ValueRange);
        }
        push(&sink, Action::Scan);
        Ok(())
    });
    let sink = Arc::clone(actions);
    dict.on_write(DIAGNOSIS_CONTROL..=DIAGNOSIS_CONTROL, move |_, dict| {
        let reset: bool = dict
            .get(DIAGNOSIS_CONTROL, RESET_DIAGNOSIS_SUBINDEX)
            .map_err(|_| AbortCode::GeneralError)?;
        if reset {
            push(&sink, Action::ResetDiagnosis);
        }
        Ok(())
    });
    Ok(dict)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::od::Dictionary;
    use crate::wire::coe::info::OdListType;
    use crate::wire::register::AlState;

    #[test]
    fn an_empty_master_has_its_identity_and_device_objects() {
        let actions = Actions::default();
        let dict = build(
            &MasterSnapshot::default(),
            &MasterIdentity::default(),
            &actions,
        )
        .unwrap();
        let all = dict.indices(OdListType::All);
        for index in [
            0x1000, 0x1008, 0x1009, 0x100A, 0x1018, 0xF000, 0xF002, 0xF020, 0xF040, 0xF120, 0xF200,
        ] {
            assert!(all.contains(&index), "{index:#06x}");
        }
        assert_eq!(dict.get::<u8>(0xF020, 0).unwrap(), 0);
    }

    #[test]
    fn writes_become_actions_and_bad_values_are_refused() {
        let actions = Actions::default();
        let mut dict = build(
            &MasterSnapshot::default(),
            &MasterIdentity::default(),
            &actions,
        )
        .unwrap();
        let state = AlState::Op;
        dict.write(0xF200, 0x10, &[1], state).unwrap();
        dict.write(0xF002, 1, &SCAN_REQUEST, state).unwrap();
        assert_eq!(
            dict.write(0xF002, 1, &[7, 0], state),
            Err(AbortCode::ValueRange)
        );
        assert_eq!(
            *actions.lock().unwrap(),
            vec![Action::ResetDiagnosis, Action::Scan]
        );
    }
}
