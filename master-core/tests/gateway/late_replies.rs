//! Replies matched to their request through the gateway's raw path: a slave that answers
//! late (here a simulated firmware with a response delay) leaves the answer of a request
//! that timed out in its send mailbox, and the gateway's next client must get the answer
//! to its own request, never that one. And an SDO abort as SOES sends it (CoE service 2,
//! low command bits set) is forwarded to the client unchanged.

use crate::gateway_support;

use std::time::Duration;

use gateway_support::{COE_STORE, GwRig, sdo, station, test_config};
use master_core::mailbox::MailboxError;
use master_core::master::SlaveAddress;
use master_core::wire::coe::sdo::SdoFrame;
use master_core::wire::coe::{AbortCode, SdoRequest};
use master_core::wire::mailbox::MailboxType;
use sim::topology::{EscSpec, Topology};

fn rig(esc: EscSpec) -> GwRig {
    let mut topology = Topology::default_segment();
    topology.slaves[COE_STORE].esc = esc;
    GwRig::with_topology(topology, test_config())
}

fn upload(index: u16) -> Vec<u8> {
    sdo(SdoRequest::InitiateUpload {
        index,
        subindex: 0,
        complete_access: false,
    })
}

#[test]
fn a_late_answer_is_never_the_gateway_client_answer() {
    let rig = rig(EscSpec {
        response_delay_us: 300_000,
        ..EscSpec::default()
    });
    let store = rig
        .master()
        .mailbox(SlaveAddress::Position(COE_STORE as u16))
        .unwrap();
    // 0x1008 (the device name) times out for an API caller; its answer comes later.
    let hasty = store.with_timeout(Duration::from_millis(20));
    let err = gateway_support::block_on(hasty.sdo_upload(0x1008, 0)).unwrap_err();
    assert!(matches!(err, MailboxError::Timeout { .. }), "{err:?}");
    let before = store.stats().unexpected;
    let mut client = rig.client();
    client.send(station(COE_STORE), MailboxType::Coe, &upload(0x2001));
    let reply = client
        .recv_within(Duration::from_secs(3))
        .expect("the gateway answers");
    let frame = SdoFrame::new_checked(&reply.data[..]).unwrap();
    assert_eq!((frame.index(), frame.subindex()), (0x2001, 0), "{reply:?}");
    assert_eq!(frame.data_field(), 0x1234_5678u32.to_le_bytes());
    assert_eq!(
        store.stats().unexpected - before,
        1,
        "the late answer counted"
    );
}

#[test]
fn an_abort_in_service_2_with_low_bits_is_forwarded_unchanged() {
    let rig = rig(EscSpec {
        sdo_abort_in_request: true,
        sdo_abort_keeps_command_bits: true,
        ..EscSpec::default()
    });
    let mut client = rig.client();
    let reply = client.request(station(COE_STORE), MailboxType::Coe, &upload(0x5555));
    assert_eq!(
        reply.data[..3],
        [0x00, 0x20, 0x80],
        "service 2, 0x80 | 0x40 & 0x1f"
    );
    let frame = SdoFrame::new_checked(&reply.data[..]).unwrap();
    assert_eq!(
        frame.any_abort(),
        Some((0x5555, 0, AbortCode::ObjectDoesNotExist))
    );
}
