//! The simulator stands beside the master, not on it (docs/architecture.md, "Rules"): it
//! uses master-core's wire formats, object dictionary and link only, never the bus, the
//! mailbox engine, the master or the gateway, so that a bug in the master's logic cannot
//! hide behind the same bug in the slaves it is tested against. Each source file is read by
//! the shared `layering` crate with Rust's grammar (grouped imports and macro bodies
//! included, comments not).

use std::fs;
use std::path::Path;

/// The master-core modules the simulator may use.
const ALLOWED: &[&str] = &["wire", "od", "link"];

/// `file:line: master_core::module` for every use of a module outside [`ALLOWED`].
fn forbidden(relative: &Path, source: &str) -> Vec<String> {
    let module = layering::module_path(relative);
    layering::uses(&module, source)
        .unwrap_or_else(|err| panic!("{} does not parse: {err}", relative.display()))
        .iter()
        .filter_map(|u| {
            let used = u.extern_module("master_core")?;
            (!ALLOWED.contains(&used))
                .then(|| format!("{}:{}: master_core::{used}", relative.display(), u.line))
        })
        .collect()
}

#[test]
fn the_simulator_uses_only_the_wire_the_dictionary_and_the_link() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let files = layering::source_files(&src);
    let (mut bad, mut seen) = (Vec::new(), 0);
    for file in &files {
        let relative = file.strip_prefix(&src).expect("under src/");
        let source = fs::read_to_string(file).expect("read source file");
        seen += layering::uses(&layering::module_path(relative), &source)
            .expect("parses")
            .iter()
            .filter(|u| u.extern_module("master_core").is_some())
            .count();
        bad.extend(forbidden(relative, &source));
    }
    assert!(
        bad.is_empty(),
        "the simulator uses the master:\n{}",
        bad.join("\n")
    );
    assert!(seen > 100, "only {seen} master_core paths found");
}

#[test]
fn a_use_of_the_master_is_reported_grouped_or_not() {
    let source = "use master_core::{wire::frame::Frame, mailbox::MailboxConfig};\n\
                  fn f() { let _ = master_core::bus::BusConfig::default(); }\n";
    assert_eq!(
        forbidden(Path::new("esc/mod.rs"), source),
        [
            "esc/mod.rs:1: master_core::mailbox",
            "esc/mod.rs:2: master_core::bus"
        ]
    );
}
