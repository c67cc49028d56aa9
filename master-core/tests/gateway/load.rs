//! Load: 64 UDP clients at once, 2,000 requests each, spread over every slave with a
//! mailbox and the master's dictionary. Every reply must reach the client that asked and
//! carry the answer to its own question (VoE echoes of a payload unique to the request,
//! identities per slave, station addresses from the master's dictionary).

use crate::gateway_support;

use std::sync::Barrier;

use gateway_support::master_support::wait_until;
use gateway_support::{COE_STORE, Client, DRIVE, GwRig, sdo, station, test_config};
use master_core::wire::Emit;
use master_core::wire::coe::{SdoPayload, SdoRequest, SdoResponse};
use master_core::wire::mailbox::MailboxType;
use master_core::wire::voe::{VoePacket, VoeRepr};
use sim::device::voe::VoeEcho;

const CLIENTS: usize = 64;
const REQUESTS: usize = 2_000;

fn upload(index: u16, subindex: u8) -> Vec<u8> {
    sdo(SdoRequest::InitiateUpload {
        index,
        subindex,
        complete_access: false,
    })
}

fn expedited(client: &mut Client, address: u16, index: u16, subindex: u8) -> Vec<u8> {
    let reply = client.request(address, MailboxType::Coe, &upload(index, subindex));
    assert_eq!(reply.header.address, address);
    match reply.sdo() {
        SdoResponse::InitiateUpload {
            index: i,
            subindex: s,
            payload: SdoPayload::Expedited(value),
            ..
        } => {
            assert_eq!((i, s), (index, subindex), "the answer to this question");
            value.to_vec()
        }
        other => panic!("{other:?}"),
    }
}

fn voe_echo(client: &mut Client, who: usize, n: usize) {
    let payload: Vec<u8> = [who as u32, n as u32]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let repr = VoeRepr {
        vendor_id: 0x1164,
        vendor_type: 0x0042,
        data: &payload,
    };
    let request = repr.to_vec().unwrap();
    let reply = client.request(station(DRIVE), MailboxType::Voe, &request);
    let answer = VoeRepr::parse(&VoePacket::new_checked(&reply.data[..]).unwrap()).unwrap();
    assert_eq!(
        answer.data,
        VoeEcho::transform(&payload),
        "client {who} request {n} got its own echo"
    );
}

#[test]
fn sixty_four_clients_each_get_their_own_answers() {
    let rig = GwRig::start(test_config());
    let topology = &rig.topology;
    let start = Barrier::new(CLIENTS);
    std::thread::scope(|s| {
        for who in 0..CLIENTS {
            let rig = &rig;
            let start = &start;
            s.spawn(move || {
                let mut client = rig.client();
                start.wait();
                for n in 0..REQUESTS {
                    match (who + n) % 4 {
                        0 => voe_echo(&mut client, who, n),
                        1 => {
                            let product = expedited(&mut client, station(DRIVE), 0x1018, 2);
                            assert_eq!(product, topology.slaves[DRIVE].product_code.to_le_bytes());
                        }
                        2 => {
                            let serial = expedited(&mut client, station(COE_STORE), 0x1018, 4);
                            assert_eq!(serial, topology.slaves[COE_STORE].serial.to_le_bytes());
                        }
                        _ => {
                            let position = (who + n) % topology.slaves.len();
                            let address = expedited(&mut client, 0, 0x8000 + position as u16, 1);
                            assert_eq!(address, station(position).to_le_bytes());
                        }
                    }
                }
            });
        }
    });
    // A request leaves the in-flight count just after its reply is on its way, so the
    // last client may see its answer a moment before the gateway has counted it done.
    assert!(
        wait_until(|| rig.gateway().stats().in_flight == 0),
        "requests still in flight: {:?}",
        rig.gateway().stats()
    );
    let stats = rig.gateway().stats();
    let total = (CLIENTS * REQUESTS) as u64;
    assert_eq!(stats.total_requests, total);
    assert_eq!(stats.forwarded_requests, total);
    assert_eq!(stats.failed_requests, 0, "{:?}", stats.failures);
}
