//! Fuzz target `frame_matcher`: see `entry_points::frame_matcher`.
#![no_main]

#[path = "../entry_points.rs"]
mod entry_points;

libfuzzer_sys::fuzz_target!(|data: &[u8]| entry_points::frame_matcher(data));
