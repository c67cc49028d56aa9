//! Issue 15, item 1, in process: the Python and Rust sample clients of the gateway manual (docs/gateway.md, "Compatibility layout") (replayed
//! byte for byte by `gateway_support::compat_client`) get real answers from the default
//! segment in their own layout (type code in bits 7:4), and the gateway's own error answers
//! in that layout use the manual's code table. The standard clients' suites
//! (`gateway_*.rs`) run unchanged beside it.

use crate::gateway_support;

use crate::compat_client;

use std::time::Duration;

use compat_client::{COE, CompatClient, Expected, FOE, SLAVE, SOE, VENDOR, replay};
use gateway_support::{COE_STORE, DRIVE, GwRig, test_config};
use master_core::gateway::GatewayConfig;
use master_core::master_od::MasterIdentity;
use master_core::wire::foe;

/// A short session: the manual's FoE read leaves its transfer open (the client never
/// ACKs), and the next client's requests to that slave wait for it.
fn config() -> GatewayConfig {
    GatewayConfig {
        session_timeout: Duration::from_millis(300),
        ..test_config()
    }
}

fn expected(rig: &GwRig, mode_before: u32) -> Expected {
    let firmware = rig.handles[DRIVE]
        .files
        .as_ref()
        .expect("FoE store")
        .data("firmware.bin")
        .expect("firmware.bin");
    Expected {
        master_vendor_id: MasterIdentity::default().vendor_id,
        operation_mode_before: mode_before,
        firmware_first_packet: firmware[..foe::max_data(128)].to_vec(),
    }
}

#[test]
fn the_manuals_python_and_rust_samples_get_real_answers() {
    let rig = GwRig::start(config());
    let dict = rig.handles[DRIVE].dictionary.as_ref().expect("CoE");
    let writes = dict.lock().unwrap().write_count(0x6040);
    // The Python client, then the Rust client: each its own socket.
    let python = CompatClient::new(rig.addr(), Duration::from_secs(10));
    replay(&python, &expected(&rig, 0x0002));
    assert_eq!(
        dict.lock().unwrap().write_count(0x6040),
        writes + 1,
        "0x6040 written once"
    );
    let rust = CompatClient::new(rig.addr(), Duration::from_secs(10));
    replay(&rust, &expected(&rig, 1000));
    assert_eq!(dict.lock().unwrap().write_count(0x6040), writes + 2);
    let stats = rig.gateway().stats();
    assert_eq!(stats.failures.malformed, 0);
    assert_eq!(
        (
            stats.coe_count,
            stats.soe_count,
            stats.foe_count,
            stats.voe_count
        ),
        (6, 6, 2, 2)
    );
}

#[test]
fn the_gateways_own_errors_use_the_manuals_codes_in_that_layout() {
    let rig = GwRig::start(config());
    let client = CompatClient::new(rig.addr(), Duration::from_secs(10));
    // CoE to an unknown address: abort 0x06020000 naming the object.
    let r = client.coe_sdo_read(0x0999, 0x6040, 0).expect("answer");
    assert_eq!((r.code, r.low_nibble, r.address), (COE, 0, 0x0999));
    assert_eq!(r.data[2], 0x80);
    assert_eq!(r.data[3..6], [0x40, 0x60, 0x00]);
    assert_eq!(r.data[6..10], 0x0602_0000u32.to_le_bytes());
    // SoE to an unknown address: 0x1009, error bit set, the client's op code and element.
    let r = client.soe_read(0x0999, 32, 0, 5).expect("answer");
    assert_eq!((r.code, r.low_nibble), (SOE, 0));
    assert_eq!(r.data, [0x11, 0x05, 0x20, 0x00, 0x09, 0x10]);
    // SoE at the master's address: not served there, 0x8001.
    let r = client.soe_read(0x0000, 32, 0, 5).expect("answer");
    assert_eq!(r.data[4..], 0x8001u16.to_le_bytes());
    // FoE to a slave without FoE: 0x8001 (not implemented), FoE error without the
    // reserved byte.
    let store = 1001 + COE_STORE as u16;
    let r = client.foe_read(store, "firmware.bin").expect("answer");
    assert_eq!((r.code, r.low_nibble), (FOE, 0));
    assert_eq!(r.data[..5], [0x05, 0x01, 0x80, 0, 0]);
    // FoE to an unknown address: 0x8002 (not found, in the manual's table).
    let r = client.foe_read(0x0999, "firmware.bin").expect("answer");
    assert_eq!(r.data[..5], [0x05, 0x02, 0x80, 0, 0]);
    // VoE to a slave without VoE: a mailbox error (type byte 0x00) with the manual's VoE
    // code 0x0001 "service not available".
    let r = client.voe_send(store, VENDOR, 1, &[1]).expect("answer");
    assert_eq!((r.code, r.low_nibble), (0, 0));
    assert_eq!(r.data, [0x01, 0x00, 0x01, 0x00]);
    // A slave's own answers pass through in the layout: VoE for another vendor gets the
    // simulated slave's mailbox error 0x0004.
    let r = client.voe_send(SLAVE, 0x42, 1, &[1]).expect("answer");
    assert_eq!((r.code, r.data.clone()), (0, vec![0x01, 0x00, 0x04, 0x00]));
    // The layout is detected per message: a standard request from the same socket still
    // gets a standard answer (type CoE = 3 in bits 3:0, the counter in 6:4).
    let standard = gateway_support::datagram(
        SLAVE,
        master_core::wire::mailbox::MailboxType::Coe,
        5,
        &[0x00, 0x20, 0x40, 0x40, 0x60, 0x00, 0, 0, 0, 0],
    );
    client.socket.send_to(&standard, rig.addr()).expect("send");
    let r = client.receive().expect("answer");
    assert_eq!(r.low_nibble, 3, "standard type CoE: {r:02X?}");
}

#[test]
fn element_numbers_map_to_the_standard_elements() {
    let rig = GwRig::start(config());
    let client = CompatClient::new(rig.addr(), Duration::from_secs(10));
    // 0 name: the standard name element (actual length, maximum length, text).
    let r = client.soe_read(SLAVE, 32, 0, 0).expect("name");
    assert_eq!(r.data[..4], [0x01, 0x00, 0x20, 0x00], "{r:02X?}");
    let text = b"Primary operation mode";
    assert_eq!(
        u16::from_le_bytes([r.data[4], r.data[5]]) as usize,
        text.len()
    );
    assert_eq!(&r.data[8..8 + text.len()], text);
    // 1 attribute and 7 data type: the 4-byte attribute (4-byte element, hexadecimal:
    // data type 3 in bits 22:20).
    for element in [1, 7] {
        let r = client.soe_read(SLAVE, 32, 0, element).expect("attribute");
        assert_eq!(r.data[1], element);
        assert_eq!(r.data[4..], 0x0032_0001u32.to_le_bytes());
    }
    // 6 default: 2, as 4 bytes.
    let r = client.soe_read(SLAVE, 32, 0, 6).expect("default");
    assert_eq!(r.data[4..], 2u32.to_le_bytes());
    // An IDN the drive lacks: the slave's own error, error bit set, in the layout.
    let r = client.soe_read(SLAVE, 0x7FFF, 0, 5).expect("error");
    assert_eq!(r.data[0], 0x11, "read with error bit: {r:02X?}");
    assert_eq!(r.data[4..], 0x1001u16.to_le_bytes());
}

#[test]
fn an_foe_write_in_that_layout_stores_the_file() {
    let rig = GwRig::start(config());
    let client = CompatClient::new(rig.addr(), Duration::from_secs(10));
    let r = client.foe_write(SLAVE, "compat.bin").expect("ACK 0");
    assert_eq!((r.code, r.data.clone()), (FOE, vec![0x04, 0, 0, 0, 0]));
    // DATA packet 1 in the layout: op code, packet number, data.
    let r = client
        .send_request(SLAVE, FOE, &[0x03, 1, 0, 0, 0, b'o', b'k'])
        .expect("ACK 1");
    assert_eq!(r.data, [0x04, 1, 0, 0, 0]);
    let store = rig.handles[DRIVE].files.as_ref().expect("FoE store");
    assert_eq!(store.data("compat.bin").as_deref(), Some(&b"ok"[..]));
}
