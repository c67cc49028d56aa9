//! The server's modules import each other one way only (docs/architecture.md, "Rules"):
//! every module may name only modules of a lower rank. Each source file is read by the
//! shared `layering` crate with Rust's grammar: `use` items (grouped ones too), paths in
//! code, `super::` chains and macro bodies; comments and doc links do not count.
//!
//! A new module fails here until it is given a rank, so the table stays the map.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

/// The server's top-level modules from the bottom up. A module may use modules of a lower
/// rank only; modules of one rank do not know each other.
const RANKS: &[(&str, u8)] = &[
    // Leaves: the one error type and process-wide services.
    ("error", 0),
    ("audit", 0),
    ("scheduling", 0),
    ("signals", 0),
    ("systemd", 0),
    ("exit", 0),
    // How callers write slaves, values and IP settings.
    ("input", 1),
    ("sim_hooks", 1),
    // The configuration: what ecatd was told, checked; no runtime module.
    ("config", 2),
    // Runtime parts the core stands on.
    ("app", 3),
    ("connections", 3),
    ("eoe", 3),
    ("logging", 3),
    ("security", 3),
    ("segment", 3),
    ("tls", 3),
    // The one service core, and what reads through it.
    ("service", 4),
    ("watch", 5),
    // Read from the core and every counter at scrape time.
    ("metrics", 6),
    // The adapters.
    ("grpc", 7),
    ("http", 7),
    // Start-up and its two hosts.
    ("daemon", 8),
    ("fuzzing", 8),
    ("embed", 9),
];

fn rank(module: &str) -> Option<u8> {
    RANKS.iter().find(|(m, _)| *m == module).map(|(_, r)| *r)
}

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// `from` (of rank `own`) naming `to`: whether that points down. Names under the crate
/// root that are no module of it (none today) do not count.
fn points_down(own: u8, from: &str, to: &str) -> bool {
    if to == from {
        return true;
    }
    match rank(to) {
        Some(r) => r < own,
        None => !src().join(to).exists() && !src().join(format!("{to}.rs")).exists(),
    }
}

#[test]
fn every_module_imports_only_modules_below_it() {
    let files = layering::source_files(&src());
    let (mut unranked, mut upward, mut seen) = (BTreeSet::new(), Vec::new(), 0);
    for file in &files {
        let relative = file.strip_prefix(src()).expect("under src/");
        let module = layering::module_path(relative);
        // The crate roots, and the `ecat` binary (a crate of its own, which reaches the
        // library as `server::`).
        let Some(from) = module.first().filter(|m| *m != "cli") else {
            continue;
        };
        let Some(own) = rank(from) else {
            unranked.insert(from.clone());
            continue;
        };
        let source = fs::read_to_string(file).expect("read source file");
        let uses = layering::uses(&module, &source)
            .unwrap_or_else(|err| panic!("{} does not parse: {err}", relative.display()));
        for u in &uses {
            let Some(to) = u.top_module() else { continue };
            seen += 1;
            if !points_down(own, from, to) {
                upward.push(format!(
                    "{}:{}: {from} uses {to}",
                    relative.display(),
                    u.line
                ));
            }
        }
    }
    assert!(
        unranked.is_empty(),
        "modules without a rank in RANKS: {unranked:?}"
    );
    assert!(
        upward.is_empty(),
        "imports that do not point down:\n{}",
        upward.join("\n")
    );
    // The scan saw the code at all (a reader that found nothing would pass the above).
    assert!(seen > 500, "only {seen} crate:: paths found");
}

#[test]
fn an_upward_import_is_reported() {
    // The configuration naming the core: the arrow this table exists to keep out.
    let own = rank("config").expect("ranked");
    assert!(!points_down(own, "config", "service"));
    assert!(!points_down(own, "config", "eoe"));
    assert!(points_down(own, "config", "input"));
    assert!(points_down(own, "config", "config"));
    let uses = layering::uses(
        &["config".to_string(), "bus".to_string()],
        "use crate::{input::value, service::Core};",
    )
    .expect("parses");
    let modules: Vec<_> = uses.iter().filter_map(|u| u.top_module()).collect();
    assert_eq!(modules, ["input", "service"]);
}
