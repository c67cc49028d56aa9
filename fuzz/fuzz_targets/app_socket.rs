//! Fuzz target `app_socket`: the application interface's socket lines (both ways) and its
//! entry records; see `server::fuzzing::app_socket`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| server::fuzzing::app_socket(data));
