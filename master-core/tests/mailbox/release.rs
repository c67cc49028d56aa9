//! A request under way when its slave's mailbox is let go (the slave lost, power-cycled or
//! scanned again) ends at once with `Shutdown`: it must not go on reading SM1, which a new
//! owner of the mailbox may be using by then, and would take that owner's answers (one
//! owner per mailbox).

use crate::mailbox_support;

use std::time::Duration;

use mailbox_support::{DRIVE, Rig, bus_config, station, wait_until};
use master_core::link::FaultConfig;
use master_core::mailbox::{MailboxConfig, MailboxError};
use sim::topology::Topology;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_request_under_way_ends_when_its_mailbox_is_released() {
    // The drive answers 2 s late, well inside the request's 10 s.
    let mut topology = Topology::default_segment();
    topology.slaves[DRIVE].esc.response_delay_us = 2_000_000;
    let mailbox = MailboxConfig {
        timeout: Duration::from_secs(10),
        idle_poll: None,
        ..MailboxConfig::default()
    };
    let rig = Rig::start_with(
        &topology,
        FaultConfig::default(),
        1,
        bus_config(),
        mailbox,
        |_, _| {},
    );
    let drive = rig.slave(DRIVE);
    let polled = rig.bus.stats().datagrams_polled_again;
    let upload = tokio::spawn(async move { drive.sdo_upload(0x1018, 1).await });
    // The request wrote its message and polls SM1 for the answer.
    wait_until("the request's polling", Duration::from_secs(5), || {
        rig.bus.stats().datagrams_polled_again > polled
    });
    assert!(rig.engine().remove_slave(station(DRIVE)));
    let result = upload.await.expect("the request's task");
    assert!(
        matches!(result, Err(MailboxError::Shutdown)),
        "ended with {result:?} instead of at the release"
    );
}
