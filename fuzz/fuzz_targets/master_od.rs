//! Fuzz target `master_od`: see `entry_points::master_od`.
#![no_main]

#[path = "../entry_points.rs"]
mod entry_points;

libfuzzer_sys::fuzz_target!(|data: &[u8]| entry_points::master_od(data));
