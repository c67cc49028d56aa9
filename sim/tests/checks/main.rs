//! The simulator's own rules and corpora: it imports only master-core's wire, od and link,
//! its fuzz seeds replay, and the `ecat-sim` command line.

#[path = "../../../fuzz/replay.rs"]
mod replay;

mod ecat_sim_cli;
mod fuzz_corpus;
mod layering;
