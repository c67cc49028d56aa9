//! Replays the seed corpora of the server's fuzz targets (`server_input`, `app_socket`,
//! `process_data_body`, in `fuzz/corpus/`) through their `server::fuzzing` functions: seeds, prefixes and fixed mutants (`fuzz/replay.rs`),
//! so every CI run exercises the input parsers and a crash input added to the corpus stays
//! a regression test.

use crate::replay;

#[test]
fn the_input_parsers_survive_their_seed_corpus() {
    let runs = replay::replay("server_input", server::fuzzing::inputs);
    assert!(runs > replay::MUTANTS);
}

#[test]
fn the_application_socket_parsers_survive_their_seed_corpus() {
    let runs = replay::replay("app_socket", server::fuzzing::app_socket);
    assert!(runs > replay::MUTANTS);
}

#[test]
fn the_process_data_body_parser_survives_its_seed_corpus() {
    let runs = replay::replay("process_data_body", server::fuzzing::process_data_body);
    assert!(runs > replay::MUTANTS);
}
