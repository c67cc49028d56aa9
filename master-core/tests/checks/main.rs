//! The project's own rules and corpora: every protocol citation names a document that
//! exists, imports point down the layers, the fuzz seed corpus and the seed capture replay.

#[path = "../../../fuzz/entry_points.rs"]
mod entry_points;
#[path = "../../../fuzz/replay.rs"]
mod replay;

mod citations;
mod fuzz_corpus;
mod layering;
mod seed_capture;
