//! Issue 15, item 1, through the ecatd process: our client of the gateway manual's layout
//! (`master-core/tests/gateway_support/compat_client.rs`: type code in bits 7:4, the
//! manual's SoE and FoE forms) replays the seven samples of the manual's Python client and then of
//! its Rust client against `ecatd --simulate`'s gateway, and checks each real answer: the
//! master's 0x1018:01 at address 0, 0x6040 read and written, S-0-0032 read and written, the
//! first packet of `firmware.bin`, the VoE answer. `server_gateway_compat_veth.rs` runs the
//! same against `ecatd --iface` on veth. Expected values come from
//! `Topology::default_segment()` and from the standard layout.

use crate::server_support;

use crate::compat_client;

use std::time::Duration;

use compat_client::{CompatClient, Expected, replay};
use server_support::Ecatd;
use server_support::gateway_client::GatewayClient;
use sim::topology::Topology;

/// One FoE packet of the drive: its 128-byte mailbox less the mailbox and FoE headers.
const FOE_PACKET: usize = 128 - 6 - 6;

/// Longer than the gateway's request timeout (5 s): a client's request to the drive may wait
/// for another client's session there (the manual's FoE read leaves its transfer open).
const WAIT: Duration = Duration::from_secs(8);

fn firmware_first_packet() -> Vec<u8> {
    let drive = &Topology::default_segment().slaves[0];
    let file = drive
        .foe_files
        .iter()
        .find(|f| f.name == "firmware.bin")
        .expect("firmware.bin on the drive");
    assert!(file.content.is_none(), "a sized test-pattern file");
    (0..FOE_PACKET).map(|i| (i % 251) as u8).collect()
}

#[test]
fn the_manuals_python_and_rust_samples_get_real_answers() {
    let ecatd = Ecatd::start(&[]);
    let gateway = ecatd.gateway_addr();
    // The master's vendor ID, read in the standard layout.
    let mut standard = GatewayClient::new(gateway);
    let vendor = standard.sdo_upload(0, 0x1018, 1).expect("0x1018:01");
    let master_vendor_id = u32::from_le_bytes(vendor[..4].try_into().unwrap());
    let python = CompatClient::new(gateway, WAIT);
    let answers = replay(
        &python,
        &Expected {
            master_vendor_id,
            operation_mode_before: 0x0002,
            firmware_first_packet: firmware_first_packet(),
        },
    );
    assert_eq!(answers.len(), 7);
    let rust = CompatClient::new(gateway, WAIT);
    replay(
        &rust,
        &Expected {
            master_vendor_id,
            operation_mode_before: 1000,
            firmware_first_packet: firmware_first_packet(),
        },
    );
    // The standard client is served as before, beside them.
    assert_eq!(
        standard.sdo_upload(0, 0x1018, 1).expect("0x1018:01"),
        vendor
    );
}
