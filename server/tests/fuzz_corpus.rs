//! Replays the seed corpus of the fuzz target `server_input` (`fuzz/corpus/server_input/`)
//! through `server::fuzzing::inputs`: seeds, prefixes and fixed mutants (`fuzz/replay.rs`),
//! so every CI run exercises the input parsers and a crash input added to the corpus stays
//! a regression test.

#[path = "../../fuzz/replay.rs"]
mod replay;

#[test]
fn the_input_parsers_survive_their_seed_corpus() {
    let runs = replay::replay("server_input", server::fuzzing::inputs);
    assert!(runs > replay::MUTANTS);
}
