//! Fuzz target `server_input`: the server's parsers of caller input (slave names, values
//! by type, numbers, states, Host headers, EoE IP settings, watch entries); see
//! `server::fuzzing::inputs`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| server::fuzzing::inputs(data));
