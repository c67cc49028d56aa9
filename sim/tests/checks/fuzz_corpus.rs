//! Replays the seed corpus of the fuzz target `sim_segment` (`fuzz/corpus/sim_segment/`)
//! through `sim::fuzzing::frames`: seeds, prefixes and fixed mutants (`fuzz/replay.rs`), so
//! every CI run exercises the segment with malformed frames and a crash input added to the
//! corpus stays a regression test.

use crate::replay;

#[test]
fn the_segment_survives_its_seed_corpus() {
    let runs = replay::replay("sim_segment", sim::fuzzing::frames);
    assert!(runs > replay::MUTANTS);
}
