//! The simulator stands beside the master, not on it (docs/architecture.md, "Rules"): it
//! builds on the wire formats, the object dictionary and the link (crates `ecat-wire`,
//! `ecat-od` and `ecat-link`), never on master-core's bus, mailboxes, master or gateway, so
//! that a bug in the master's logic cannot hide behind the same bug in the slaves it is
//! tested against. Cargo enforces that for as long as master-core is not one of the
//! simulator's dependencies; this test keeps it so.

use std::fs;
use std::path::Path;

/// The dependency tables of a manifest (normal, dev and build), by name.
fn dependency_tables(manifest: &toml::Table) -> Vec<(&'static str, &toml::Table)> {
    ["dependencies", "dev-dependencies", "build-dependencies"]
        .into_iter()
        .filter_map(|section| Some((section, manifest.get(section)?.as_table()?)))
        .collect()
}

fn manifest() -> toml::Table {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml");
    fs::read_to_string(&path)
        .expect("sim/Cargo.toml")
        .parse()
        .expect("sim/Cargo.toml is TOML")
}

#[test]
fn the_simulator_depends_on_the_wire_the_dictionary_and_the_link_and_not_on_the_master() {
    let manifest = manifest();
    let tables = dependency_tables(&manifest);
    for (section, table) in &tables {
        assert!(
            !table.contains_key("master-core"),
            "sim/Cargo.toml [{section}] names master-core"
        );
    }
    let (_, normal) = tables
        .iter()
        .find(|(section, _)| *section == "dependencies")
        .expect("sim/Cargo.toml has [dependencies]");
    for layer in ["ecat-wire", "ecat-od", "ecat-link"] {
        assert!(normal.contains_key(layer), "sim does not depend on {layer}");
    }
}

#[test]
fn a_dependency_on_the_master_is_found_in_any_section() {
    let manifest: toml::Table = "[dependencies]\necat-wire = \"1\"\n\
                                 [dev-dependencies]\nmaster-core = { path = \"../master-core\" }\n"
        .parse()
        .expect("TOML");
    let found: Vec<&str> = dependency_tables(&manifest)
        .into_iter()
        .filter(|(_, table)| table.contains_key("master-core"))
        .map(|(section, _)| section)
        .collect();
    assert_eq!(found, ["dev-dependencies"]);
}
