//! Any byte string as an EtherCAT payload: walk it as a datagram chain, read-only and in place.
#![no_main]

use libfuzzer_sys::fuzz_target;
use master_core::wire::datagram::{Datagrams, DatagramsMut};

fuzz_target!(|data: &[u8]| {
    for datagram in Datagrams::new(data) {
        if datagram.is_err() {
            break;
        }
    }
    let mut copy = data.to_vec();
    for datagram in DatagramsMut::new(&mut copy) {
        match datagram {
            Ok(mut d) => {
                let wkc = d.wkc().wrapping_add(1);
                d.set_wkc(wkc);
            }
            Err(_) => break,
        }
    }
});
