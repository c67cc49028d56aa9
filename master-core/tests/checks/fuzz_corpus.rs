//! Replays the fuzz seed corpus (`fuzz/corpus/<entry point>/*`) through the same entry points
//! the fuzz targets call (seeds, prefixes and fixed mutants, see `fuzz/replay.rs`), so every
//! CI run exercises them and a crash input added to the corpus stays a regression test.

use crate::entry_points;
use crate::replay;

use std::path::Path;

#[test]
fn every_entry_point_survives_its_seed_corpus() {
    for (name, entry_point) in entry_points::ALL {
        let runs = replay::replay(name, *entry_point);
        assert!(runs > replay::MUTANTS, "{name}: {runs} inputs");
    }
}

/// Every target of the fuzz crate has an entry point replayed by one of the replay tests
/// (this one, sim's or server's), so no target goes without its corpus in CI. The other
/// crates' replays are found in their `tests/checks/fuzz_corpus.rs` by their `replay::replay("NAME"`
/// calls, so a target added there needs no second list here.
#[test]
fn every_fuzz_target_is_replayed() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let manifest = std::fs::read_to_string(root.join("fuzz/Cargo.toml")).expect("fuzz/Cargo.toml");
    let targets: Vec<&str> = manifest
        .lines()
        .filter_map(|line| line.strip_prefix("name = \""))
        .filter_map(|rest| rest.strip_suffix('"'))
        .filter(|name| *name != "ecatd-fuzz")
        .collect();
    let mut elsewhere = Vec::new();
    for crate_dir in ["sim", "server"] {
        let path = root.join(crate_dir).join("tests/checks/fuzz_corpus.rs");
        let text = std::fs::read_to_string(&path)
            .unwrap_or_else(|err| panic!("{}: {err}", path.display()));
        for call in text.split("replay::replay(\"").skip(1) {
            let name = call.split('"').next().expect("a quoted name");
            elsewhere.push(name.to_string());
        }
    }
    assert!(
        !elsewhere.is_empty(),
        "the other replay tests were not found"
    );
    for target in &targets {
        assert!(
            entry_points::ALL.iter().any(|(name, _)| name == target)
                || elsewhere.iter().any(|name| name == target),
            "fuzz target {target} has no replayed entry point"
        );
    }
    assert_eq!(targets.len(), entry_points::ALL.len() + elsewhere.len());
}

/// The valid vectors in the corpus must decode, or the corpus seeds the fuzzer with noise.
#[test]
fn seed_vectors_decode() {
    use master_core::wire::frame::EthercatFrame;
    use master_core::wire::gateway::GatewayMessage;
    use master_core::wire::mailbox::MailboxMessage;
    use master_core::wire::sii::image::SiiImage;

    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/corpus");
    let read_all = |name: &str| -> Vec<(String, Vec<u8>)> {
        std::fs::read_dir(corpus.join(name))
            .expect("corpus folder")
            .map(|e| {
                let path = e.expect("entry").path();
                (
                    path.display().to_string(),
                    std::fs::read(&path).expect("read"),
                )
            })
            .collect()
    };
    for (path, bytes) in read_all("mailbox") {
        MailboxMessage::parse(&bytes).unwrap_or_else(|e| panic!("{path}: {e}"));
    }
    for (path, bytes) in read_all("gateway") {
        GatewayMessage::new_checked(&bytes[..]).unwrap_or_else(|e| panic!("{path}: {e}"));
    }
    for (path, bytes) in read_all("frame") {
        let frame = EthercatFrame::parse(&bytes).unwrap_or_else(|e| panic!("{path}: {e}"));
        for d in frame.datagrams().expect("datagram frame") {
            d.unwrap_or_else(|e| panic!("{path}: {e}"));
        }
    }
    for (path, bytes) in read_all("sii") {
        let image = SiiImage::parse(&bytes).unwrap_or_else(|e| panic!("{path}: {e}"));
        assert!(image.checksum_ok, "{path}: checksum");
    }
}
