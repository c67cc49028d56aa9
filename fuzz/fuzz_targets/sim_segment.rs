//! Fuzz target `sim_segment`: EtherCAT payloads through the simulator's built-in segment;
//! see `sim::fuzzing::frames`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| sim::fuzzing::frames(data));
