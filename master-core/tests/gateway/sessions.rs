//! Gateway sessions: clients in the middle of segmented transfers to one slave hold it in
//! turn, so transfers started at the same moment all finish with the right data (without
//! sessions the slave's SDO server drops one transfer for the other and the download is
//! aborted); a client that walks away mid-transfer holds the slave only until the session
//! timeout.

use crate::gateway_support;

use std::time::Duration;

use gateway_support::{
    COE_STORE, Client, GwRig, one_download_against_uploads, sdo, station, stored, test_config,
};
use master_core::gateway::GatewayConfig;
use master_core::wire::coe::{SdoPayload, SdoRequest, SdoResponse};
use master_core::wire::mailbox::MailboxType;

#[test]
fn concurrent_segmented_transfers_to_one_slave_all_finish_correctly() {
    let rig = GwRig::start(test_config());
    let new: Vec<u8> = (0..4096u32).map(|i| (i % 13) as u8 ^ 0x5A).collect();
    one_download_against_uploads(&rig, &new, 4, 3);
    let stats = rig.gateway().stats();
    assert_eq!(stats.failed_requests, 0, "{stats:?}");
}

#[test]
fn an_abandoned_transfer_holds_the_slave_only_until_the_session_timeout() {
    let rig = GwRig::start(GatewayConfig {
        session_timeout: Duration::from_millis(200),
        ..test_config()
    });
    let address = station(COE_STORE);
    let mut quitter = rig.client();
    let reply = quitter.request(
        address,
        MailboxType::Coe,
        &sdo(SdoRequest::InitiateUpload {
            index: 0x2000,
            subindex: 0,
            complete_access: false,
        }),
    );
    assert!(matches!(
        reply.sdo(),
        SdoResponse::InitiateUpload {
            payload: SdoPayload::Normal { .. },
            ..
        }
    ));
    // The quitter never asks for a segment. Another client is served once the hold ends.
    let mut patient = Client::new(rig.addr());
    assert_eq!(patient.upload(address, 0x2000, 0).unwrap(), stored(&rig));
}
