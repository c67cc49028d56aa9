//! Dependencies point down (docs/architecture.md, "Rules"): every source file of a layer
//! may name only the layers below it. The check reads each file's `crate::` paths (and
//! `super::` chains that climb out of the layer) outside comments, so a new upward arrow
//! fails here instead of waiting for a reviewer.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

/// master-core's top-level modules from the bottom up, as docs/architecture.md draws them.
/// A module may use modules of a lower rank only; `link` and `od` share a rank and do not
/// know each other.
const RANKS: &[(&str, u8)] = &[
    ("wire", 0),
    ("link", 1),
    ("od", 1),
    ("bus", 2),
    ("mailbox", 3),
    ("master", 4),
    ("master_od", 5),
    ("gateway", 6),
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

/// The code of a line without its `//` comment (doc comments included). A `//` inside a
/// string literal ends the scan early, which can only hide a path, never invent one.
fn code_of(line: &str) -> &str {
    match line.find("//") {
        Some(at) => &line[..at],
        None => line,
    }
}

fn ident_at(text: &str) -> &str {
    let end = text
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or(text.len());
    &text[..end]
}

/// Every `super::` chain in `code` that starts a path (not `x::super::`): how many times it
/// climbs and the name after the last `super::` (non-empty).
fn super_chains(code: &str) -> Vec<(usize, &str)> {
    let mut chains = Vec::new();
    let mut rest = code;
    while let Some(at) = rest.find("super::") {
        let before = rest[..at].chars().next_back();
        let mut tail = &rest[at..];
        if before.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_' || c == ':') {
            rest = &tail["super::".len()..];
            continue;
        }
        let mut climbs = 0;
        while let Some(next) = tail.strip_prefix("super::") {
            climbs += 1;
            tail = next;
        }
        let name = ident_at(tail);
        if !name.is_empty() {
            chains.push((climbs, name));
        }
        rest = tail;
    }
    chains
}

/// The top-level modules `source` names, for a file whose module path is `path` (e.g.
/// `["mailbox", "engine", "demux"]`), with the line of each use.
fn uses(path: &[String], source: &str) -> Vec<(String, usize)> {
    let mut found = Vec::new();
    for (number, line) in source.lines().enumerate() {
        let code = code_of(line);
        let mut rest = code;
        while let Some(at) = rest.find("crate::") {
            // `$crate::` (macros) and `crate::` both name this crate.
            let before = rest[..at].chars().next_back();
            let tail = &rest[at + "crate::".len()..];
            if before.is_none_or(|c| !(c.is_ascii_alphanumeric() || c == '_'))
                || before == Some('$')
            {
                let name = ident_at(tail);
                if !name.is_empty() {
                    found.push((name.to_string(), number + 1));
                }
            }
            rest = tail;
        }
        // `super` from a file reaches its parent module; from the crate root's child it
        // reaches the root, where the next name is a top-level module.
        for (climbs, name) in super_chains(code) {
            if climbs >= path.len() && name != "super" {
                found.push((name.to_string(), number + 1));
            }
        }
    }
    found
}

/// The module path of a file under `src`: `mailbox/engine/demux.rs` → mailbox, engine,
/// demux; `mailbox/mod.rs` → mailbox.
fn module_path(src: &Path, file: &Path) -> Vec<String> {
    let relative = file.strip_prefix(src).expect("file under src");
    let mut parts: Vec<String> = relative
        .iter()
        .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    parts
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Every use of one top-level module by another in the sources under `src`.
fn arrows(src: &Path) -> Vec<Arrow> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
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
/// `path`: `crate::mailbox::x` paths, and `super::` chains that climb to the mailbox root.
fn mailbox_uses(path: &[String], source: &str) -> Vec<(String, usize)> {
    let mut found = Vec::new();
    for (number, line) in source.lines().enumerate() {
        let code = code_of(line);
        let mut rest = code;
        while let Some(at) = rest.find("crate::mailbox::") {
            let tail = &rest[at + "crate::mailbox::".len()..];
            let name = ident_at(tail);
            if !name.is_empty() {
                found.push((name.to_string(), number + 1));
            }
            rest = tail;
        }
        // From `mailbox/a/b.rs` (path mailbox, a, b) two climbs reach the mailbox root.
        for (climbs, name) in super_chains(code) {
            if climbs + 1 == path.len() {
                found.push((name.to_string(), number + 1));
            }
        }
    }
    found
}

/// Uses of one mailbox module by another that point up or sideways.
fn mailbox_violations(src: &Path) -> Vec<String> {
    let rank = |module: &str| {
        MAILBOX_RANKS
            .iter()
            .find(|(m, _)| *m == module)
            .map(|(_, r)| *r)
    };
    let mut files = Vec::new();
    rust_files(&src.join("mailbox"), &mut files);
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
    let path = vec!["wire".to_string(), "coe".to_string(), "sdo".to_string()];
    let source = "//! Mentions crate::gateway in a comment only.\n\
                  use crate::wire::field;\n\
                  fn f() { let _ = crate::mailbox::MailboxConfig::default(); } // crate::master\n\
                  use super::super::super::bus::BusHandle;\n";
    let found = uses(&path, source);
    assert_eq!(
        found,
        vec![
            ("wire".to_string(), 2),
            ("mailbox".to_string(), 3),
            ("bus".to_string(), 4)
        ]
    );
    let arrows: Vec<Arrow> = found
        .into_iter()
        .filter(|(to, _)| to != "wire")
        .map(|(to, line)| Arrow {
            from: "wire".into(),
            to,
            file: "wire/coe/sdo.rs".into(),
            line,
        })
        .collect();
    assert_eq!(
        violations(&arrows),
        [
            "wire/coe/sdo.rs:3: wire uses mailbox",
            "wire/coe/sdo.rs:4: wire uses bus"
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
    assert_eq!(violations(&[arrow("od", "link")]).len(), 1);
    assert!(violations(&[arrow("gateway", "master_od")]).is_empty());
}
