//! Any byte string as a whole Ethernet frame: parse, walk the datagrams, print them.
#![no_main]

use libfuzzer_sys::fuzz_target;
use master_core::wire::frame::EthercatFrame;

fuzz_target!(|data: &[u8]| {
    if let Ok(frame) = EthercatFrame::parse(data) {
        if let Ok(datagrams) = frame.datagrams() {
            for datagram in datagrams.flatten() {
                let _ = datagram.to_string();
            }
        }
        let _ = frame.to_string();
    }
});
