//! The simulator's own rules and corpora: it depends on the wire, dictionary and link
//! crates, not on the master; its fuzz seeds replay; the `ecat-sim` command line.

#[path = "../../../fuzz/replay.rs"]
mod replay;

mod ecat_sim_cli;
mod fuzz_corpus;
mod layering;
