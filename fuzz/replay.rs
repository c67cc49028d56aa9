//! Replays a fuzz target's seed corpus (`fuzz/corpus/<target>/*`) through its entry point:
//! every seed, every prefix of it (truncation is the most common malformation on a wire),
//! and a fixed set of mutants of it (bytes flipped, inserted, removed, repeated), so that
//! each CI run exercises the targets a little even without a fuzzer, and a crash input
//! added to the corpus stays a regression test. Shared by the replay tests of master-core,
//! sim and server (`tests/checks/fuzz_corpus.rs`).

use std::path::{Path, PathBuf};

/// Mutants made of each seed.
pub const MUTANTS: usize = 64;

/// The corpus folder of `target`.
pub fn corpus(target: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fuzz/corpus")
        .join(target)
}

/// The seed inputs of `target`, sorted by name; panics if there are none.
pub fn seeds(target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let dir = corpus(target);
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("corpus folder {} is missing: {e}", dir.display()))
        .map(|entry| entry.expect("corpus entry").path())
        .filter(|path| path.is_file())
        .collect();
    paths.sort();
    assert!(!paths.is_empty(), "no seed inputs for fuzz target {target}");
    paths
        .into_iter()
        .map(|path| {
            let bytes = std::fs::read(&path).expect("read corpus input");
            (path, bytes)
        })
        .collect()
}

/// A small deterministic generator (xorshift64), so that the mutants are the same in
/// every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }
}

/// The mutants of `seed`.
pub fn mutants(seed: &[u8]) -> Vec<Vec<u8>> {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15 ^ seed.len() as u64);
    (0..MUTANTS)
        .map(|_| {
            let mut m = seed.to_vec();
            for _ in 0..1 + rng.below(4) {
                let at = rng.below(m.len() + 1);
                match rng.below(5) {
                    0 if at < m.len() => m[at] ^= 1 << rng.below(8),
                    1 if at < m.len() => m[at] = [0x00, 0xFF, 0x7F, 0x80][rng.below(4)],
                    2 => m.insert(at, rng.next() as u8),
                    3 if at < m.len() => {
                        m.remove(at);
                    }
                    _ => {
                        let end = (at + 1 + rng.below(8)).min(m.len());
                        let chunk = m[at..end].to_vec();
                        m.splice(at..at, chunk);
                    }
                }
            }
            m
        })
        .collect()
}

/// Runs `entry_point` on every seed of `target`, its prefixes and its mutants; returns how
/// many inputs ran.
pub fn replay(target: &str, entry_point: fn(&[u8])) -> usize {
    let mut runs = 0;
    for (_, seed) in seeds(target) {
        for len in 0..=seed.len() {
            entry_point(&seed[..len]);
            runs += 1;
        }
        for mutant in mutants(&seed) {
            entry_point(&mutant);
            runs += 1;
        }
    }
    runs
}
