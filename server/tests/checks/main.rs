//! The server's own rules and corpora: imports point down its layers, the example
//! configuration loads, and the fuzz seeds replay.

#[path = "../../../fuzz/replay.rs"]
mod replay;

mod example_config;
mod fuzz_corpus;
mod layering;
