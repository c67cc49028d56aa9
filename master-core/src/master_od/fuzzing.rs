//! The master dictionary's request handling without a bus, for the fuzz target `master_od`
//! (fuzz/) and the corpus replay test: a sequence of CoE requests from one client, served
//! as [`MasterDictionary`](crate::master_od::MasterDictionary) serves them (the
//! dictionary rebuilt from a snapshot for each request, one SDO server state kept across
//! them), with the write hooks' actions collected instead of carried out.

use crate::master::{Identity, ProcessDataInfo, SlaveInfo};
use crate::od::{Outcome, SdoServer, ServerContext};
use crate::wire::coe::CoeFrame;
use crate::wire::mailbox;
use crate::wire::register::{AlState, AlStatusCode, DlStatus, EscInfoRepr};

use super::dictionary::{Action, Actions, build};
use super::identity::MasterIdentity;
use super::snapshot::MasterSnapshot;

/// A snapshot of three present slaves, so that the per-slave objects (0x8nnn-0xAnnn)
/// exist.
fn snapshot() -> MasterSnapshot {
    let slaves: Vec<SlaveInfo> = (0..3u16)
        .map(|position| SlaveInfo {
            position,
            station: 0x1001 + position,
            alias: 0,
            identity: Identity::default(),
            name: format!("slave {position}"),
            esc: EscInfoRepr::default(),
            mailbox: None,
            boot_mailbox: None,
            dl_status: DlStatus::default(),
            al_state: AlState::Op,
            al_error: false,
            al_status_code: AlStatusCode::NoError,
            requested_state: AlState::Op,
            process_data: ProcessDataInfo::default(),
            present: true,
            device_type: 0,
        })
        .collect();
    MasterSnapshot {
        slaves,
        ..MasterSnapshot::default()
    }
}

/// Serves the requests in `data` (the first byte picks the mailbox size, then each request
/// is a length byte and that many bytes). Panics if a reply does not fit the mailbox, is no
/// CoE frame, or a write hook asks for an action with a value it should have refused.
#[doc(hidden)]
pub fn requests(data: &[u8]) {
    let Some((&size, mut rest)) = data.split_first() else {
        return;
    };
    // Sizes from the smallest the server accepts up to the ETG.8200 maximum.
    let mailbox_size = 16 + usize::from(size) * 4;
    let ctx = ServerContext {
        mailbox_size,
        rx_mailbox_size: 0,
        state: AlState::Op,
    };
    let snap = snapshot();
    let identity = MasterIdentity::default();
    let mut server = SdoServer::new();
    while let Some((&len, tail)) = rest.split_first() {
        let (request, next) = tail.split_at(usize::from(len).min(tail.len()));
        rest = next;
        let actions = Actions::default();
        let mut dict = build(&snap, &identity, &actions).expect("the dictionary builds");
        let mut replies = 0usize;
        let outcome = server.handle(&mut dict, request, ctx, &mut |reply: &[u8]| {
            replies += 1;
            assert!(
                reply.len() + mailbox::HEADER_LEN <= mailbox_size,
                "a reply of {} bytes in a mailbox of {mailbox_size}",
                reply.len()
            );
            assert!(
                CoeFrame::new_checked(reply).is_ok(),
                "a reply is no CoE frame"
            );
        });
        if let Outcome::Replied(n) = outcome {
            assert_eq!(n, replies, "replies counted");
        }
        let actions = actions.lock().map(|a| a.clone()).unwrap_or_default();
        for action in actions {
            if let Action::RequestState { position, control } = action {
                assert!(
                    usize::from(position) < snap.slaves.len(),
                    "no slave {position}"
                );
                assert!(
                    matches!(control & 0x0F, 1 | 2 | 3 | 4 | 8),
                    "state {control:#x}"
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_download_to_al_control_becomes_an_action() {
        // Expedited download of 2 bytes (0x2B) to 0xA001:02 = 0x0002 (PREOP).
        let sdo = [0x00, 0x20, 0x2B, 0x01, 0xA0, 0x02, 0x02, 0x00, 0x00, 0x00];
        let snap = snapshot();
        let actions = Actions::default();
        let mut dict = build(&snap, &MasterIdentity::default(), &actions).unwrap();
        let ctx = ServerContext {
            mailbox_size: 128,
            rx_mailbox_size: 0,
            state: AlState::Op,
        };
        let mut replies = Vec::new();
        let outcome = SdoServer::new().handle(&mut dict, &sdo, ctx, &mut |r: &[u8]| {
            replies.push(r.to_vec())
        });
        assert_eq!(outcome, Outcome::Replied(1));
        // Download response (0x60) for 0xA001:02.
        assert_eq!(&replies[0][2..6], &[0x60, 0x01, 0xA0, 0x02]);
        assert_eq!(
            *actions.lock().unwrap(),
            vec![Action::RequestState {
                position: 1,
                control: 2
            }]
        );
        // And the same through the fuzzing entry point.
        let mut input = vec![28, sdo.len() as u8];
        input.extend_from_slice(&sdo);
        requests(&input);
    }
}
