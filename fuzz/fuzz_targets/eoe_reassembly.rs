//! Fuzz target `eoe_reassembly`: see `entry_points::eoe_reassembly`.
#![no_main]

#[path = "../entry_points.rs"]
mod entry_points;

libfuzzer_sys::fuzz_target!(|data: &[u8]| entry_points::eoe_reassembly(data));
