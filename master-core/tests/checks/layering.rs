//! Dependencies point down (docs/architecture.md, "Rules"): every source file of a layer
//! may name only the layers below it. Each file is read by the shared `layering` crate with
//! Rust's grammar: `crate::` paths in `use` items (grouped ones too) and in code, `super::`
//! chains, macro bodies; comments and doc links do not count. A new upward arrow fails here
//! instead of waiting for a reviewer.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

/// master-core's own top-level modules from the bottom up, as docs/architecture.md draws
/// them. A module may use modules of a lower rank only. The layers below them are crates
/// (`ecat-wire`, `ecat-link`, `ecat-od`, re-exported as `wire`, `link` and `od`): every
/// module may use them, and they cannot use master-core, which Cargo enforces (a crate cannot
/// depend on one that depends on it).
const RANKS: &[(&str, u8)] = &[
    ("bus", 0),
    ("mailbox", 1),
    ("master", 2),
    ("master_od", 3),
    ("gateway", 4),
];

/// Known upward arrows, each with the reason it is tolerated for now: none (the last one,
/// `master_od`'s use of the gateway's encoders, ended when they moved to `wire`).
const ALLOWED: &[(&str, &str, &str)] = &[];

/// The mailbox's modules from the bottom up: the engine carries messages and knows none of
/// the protocol clients on top of it (EoE plugs in through `engine::hook`); the clients
/// share a rank and do not know each other.
const MAILBOX_RANKS: &[(&str, u8)] = &[
    ("config", 0),
    ("error", 0),
    ("matching", 0),
    ("engine", 1),
    ("coe", 2),
    ("eoe", 2),
    ("foe", 2),
    ("raw", 2),
    ("soe", 2),
    ("voe", 2),
];

fn rank(module: &str) -> Option<u8> {
    RANKS.iter().find(|(m, _)| *m == module).map(|(_, r)| *r)
}

/// One use of a top-level module by a source file.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
struct Arrow {
    from: String,
    to: String,
    file: String,
    line: usize,
}

/// Every path `source` names, for a file whose module path is `path` (e.g.
/// `["mailbox", "engine", "demux"]`), read with Rust's grammar by the shared `layering`
/// crate: grouped imports, `super::` chains and macro bodies included, comments not.
fn paths(path: &[String], source: &str) -> Vec<layering::Use> {
    layering::uses(path, source).unwrap_or_else(|err| panic!("{path:?} does not parse: {err}"))
}

/// The top-level modules `source` names, with the line of each use.
fn uses(path: &[String], source: &str) -> Vec<(String, usize)> {
    paths(path, source)
        .iter()
        .filter_map(|u| Some((u.top_module()?.to_string(), u.line)))
        .collect()
}

fn module_path(src: &Path, file: &Path) -> Vec<String> {
    layering::module_path(file.strip_prefix(src).expect("file under src"))
}

/// Every use of one top-level module by another in the sources under `src`.
fn arrows(src: &Path) -> Vec<Arrow> {
    let files = layering::source_files(src);
    let mut arrows = Vec::new();
    for file in files {
        let path = module_path(src, &file);
        let Some(from) = path.first().cloned() else {
            continue;
        };
        if from == "lib" {
            continue;
        }
        let source = fs::read_to_string(&file).expect("readable source");
        for (to, line) in uses(&path, &source) {
            if to != from {
                arrows.push(Arrow {
                    from: from.clone(),
                    to,
                    file: file.strip_prefix(src).unwrap().display().to_string(),
                    line,
                });
            }
        }
    }
    arrows
}

/// The arrows that point up (or sideways) and are not allowed.
fn violations(arrows: &[Arrow]) -> Vec<String> {
    arrows
        .iter()
        .filter(|a| {
            let (Some(from), Some(to)) = (rank(&a.from), rank(&a.to)) else {
                return false;
            };
            to >= from && !ALLOWED.iter().any(|(f, t, _)| *f == a.from && *t == a.to)
        })
        .map(|a| format!("{}:{}: {} uses {}", a.file, a.line, a.from, a.to))
        .collect()
}

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// The mailbox modules `source` names, for a file under `mailbox/` whose module path is
/// `path`: `crate::mailbox::x` paths and `super::` chains that climb to the mailbox root,
/// with the line of each use.
fn mailbox_uses(path: &[String], source: &str) -> Vec<(String, usize)> {
    paths(path, source)
        .iter()
        .filter_map(|u| Some((u.module_under("mailbox")?.to_string(), u.line)))
        .collect()
}

/// Uses of one mailbox module by another that point up or sideways.
fn mailbox_violations(src: &Path) -> Vec<String> {
    let rank = |module: &str| {
        MAILBOX_RANKS
            .iter()
            .find(|(m, _)| *m == module)
            .map(|(_, r)| *r)
    };
    let files = layering::source_files(&src.join("mailbox"));
    let mut bad = Vec::new();
    for file in files {
        let path = module_path(src, &file);
        let Some(from) = path.get(1).cloned() else {
            continue;
        };
        let source = fs::read_to_string(&file).expect("readable source");
        for (to, line) in mailbox_uses(&path, &source) {
            if let (Some(f), Some(t)) = (rank(&from), rank(&to))
                && to != from
                && t >= f
            {
                let file = file.strip_prefix(src).unwrap().display();
                bad.push(format!("{file}:{line}: mailbox::{from} uses mailbox::{to}"));
            }
        }
    }
    bad
}

#[test]
fn every_mailbox_module_has_a_rank() {
    let lib = fs::read_to_string(src().join("mailbox/mod.rs")).expect("mailbox/mod.rs");
    let modules: BTreeSet<&str> = lib
        .lines()
        .filter_map(|l| l.trim().strip_prefix("mod "))
        .map(|l| l.trim_end_matches(';'))
        .collect();
    let ranked: BTreeSet<&str> = MAILBOX_RANKS.iter().map(|(m, _)| *m).collect();
    assert_eq!(
        modules, ranked,
        "mailbox/mod.rs's modules and its layer table differ"
    );
}

#[test]
fn the_mailbox_engine_knows_no_protocol_client() {
    let bad = mailbox_violations(&src());
    assert!(
        bad.is_empty(),
        "upward dependencies in the mailbox:\n{}",
        bad.join("\n")
    );
}

#[test]
fn an_engine_use_of_eoe_is_reported() {
    let path: Vec<String> = ["mailbox", "engine", "owner"].map(String::from).to_vec();
    let source = "use crate::mailbox::eoe::EoeTx; // crate::mailbox::coe\n\
                  use super::super::eoe::rx::EoeRx;\n\
                  use super::hook::Background;\n\
                  use crate::mailbox::error::Result;\n";
    assert_eq!(
        mailbox_uses(&path, source),
        vec![
            ("eoe".to_string(), 1),
            ("eoe".to_string(), 2),
            // Its own module (the check skips it), through `super::`.
            ("engine".to_string(), 3),
            ("error".to_string(), 4)
        ]
    );
    // And the check over the real tree sees these lines as violations: a copy of the tree
    // with the old import put back fails.
    let dir = std::env::temp_dir().join(format!("layering-{}", std::process::id()));
    let engine = dir.join("mailbox/engine");
    fs::create_dir_all(&engine).expect("temporary tree");
    fs::write(engine.join("owner.rs"), source).expect("temporary source");
    let bad = mailbox_violations(&dir);
    fs::remove_dir_all(&dir).expect("temporary tree removed");
    assert_eq!(
        bad,
        [
            "mailbox/engine/owner.rs:1: mailbox::engine uses mailbox::eoe",
            "mailbox/engine/owner.rs:2: mailbox::engine uses mailbox::eoe"
        ]
    );
}

#[test]
fn every_top_level_module_has_a_rank() {
    let lib = fs::read_to_string(src().join("lib.rs")).expect("lib.rs");
    let modules: BTreeSet<&str> = lib
        .lines()
        .filter_map(|l| l.trim().strip_prefix("pub mod "))
        .map(|l| l.trim_end_matches(';'))
        .collect();
    let ranked: BTreeSet<&str> = RANKS.iter().map(|(m, _)| *m).collect();
    assert_eq!(
        modules, ranked,
        "lib.rs's modules and the layer table differ"
    );
}

#[test]
fn dependencies_point_down() {
    let arrows = arrows(&src());
    // The scan must see the real code: the master uses the bus, the mailbox uses wire.
    assert!(arrows.iter().any(|a| a.from == "master" && a.to == "bus"));
    assert!(arrows.iter().any(|a| a.from == "mailbox" && a.to == "wire"));
    let bad = violations(&arrows);
    assert!(bad.is_empty(), "upward dependencies:\n{}", bad.join("\n"));
}

#[test]
fn an_upward_use_is_reported_with_its_place() {
    let path = vec!["bus".to_string(), "queue".to_string(), "slot".to_string()];
    let source = "//! Mentions crate::gateway in a comment only.\n\
                  use crate::wire::field;\n\
                  fn f() { let _ = crate::mailbox::MailboxConfig::default(); } // crate::master\n\
                  use super::super::super::master::Master;\n";
    let found = uses(&path, source);
    assert_eq!(
        found,
        vec![
            ("wire".to_string(), 2),
            ("mailbox".to_string(), 3),
            ("master".to_string(), 4)
        ]
    );
    let arrows: Vec<Arrow> = found
        .into_iter()
        .map(|(to, line)| Arrow {
            from: "bus".into(),
            to,
            file: "bus/queue/slot.rs".into(),
            line,
        })
        .collect();
    // The crate below (`wire`) is no arrow up; the master's own layers above are.
    assert_eq!(
        violations(&arrows),
        [
            "bus/queue/slot.rs:3: bus uses mailbox",
            "bus/queue/slot.rs:4: bus uses master"
        ]
    );
}

#[test]
fn no_upward_arrow_is_tolerated() {
    let arrow = |from: &str, to: &str| Arrow {
        from: from.into(),
        to: to.into(),
        file: "x.rs".into(),
        line: 1,
    };
    assert_eq!(violations(&[arrow("master_od", "gateway")]).len(), 1);
    assert_eq!(violations(&[arrow("mailbox", "gateway")]).len(), 1);
    assert_eq!(violations(&[arrow("bus", "mailbox")]).len(), 1);
    assert!(violations(&[arrow("gateway", "master_od")]).is_empty());
}
