//! Replays the fuzz seed corpus (`fuzz/corpus/<entry point>/*`) through the same entry points
//! the fuzz targets call, so every CI run exercises them and a crash input added to the corpus
//! stays a regression test.

#[path = "../../fuzz/entry_points.rs"]
mod entry_points;

use std::path::Path;

#[test]
fn every_entry_point_survives_its_seed_corpus() {
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/corpus");
    for (name, entry_point) in entry_points::ALL {
        let dir = corpus.join(name);
        let inputs: Vec<_> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("corpus folder {} is missing: {e}", dir.display()))
            .map(|entry| entry.expect("corpus entry").path())
            .collect();
        assert!(!inputs.is_empty(), "no seed inputs for fuzz target {name}");
        for input in inputs {
            let bytes = std::fs::read(&input).expect("read corpus input");
            entry_point(&bytes);
            // Every prefix too: truncation is the most common malformation on a wire.
            for len in 0..bytes.len() {
                entry_point(&bytes[..len]);
            }
        }
    }
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
