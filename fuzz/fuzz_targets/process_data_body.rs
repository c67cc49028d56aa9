//! Fuzz target `process_data_body`: the JSON body of a process-data force; see
//! `server::fuzzing::process_data_body`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| server::fuzzing::process_data_body(data));
