//! The server's modules import each other one way only (docs/architecture.md, "Rules"):
//! every module may name only modules of a lower rank. The check parses each
//! source file with Rust's grammar and collects every `crate::` path: in `use` items
//! (grouped ones too: `use crate::{a, b}`), in expressions and types, and inside macro
//! bodies. Doc comments are not code and do not count.
//!
//! A new module fails here until it is given a rank, so the table stays the map.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

use proc_macro2::{TokenStream, TokenTree};
use syn::visit::Visit;

/// The server's top-level modules from the bottom up. A module may use modules of a lower
/// rank only; modules of one rank do not know each other.
const RANKS: &[(&str, u8)] = &[
    // Leaves: the one error type and process-wide services.
    ("error", 0),
    ("audit", 0),
    ("scheduling", 0),
    ("signals", 0),
    ("systemd", 0),
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
    // The one service core, and the role table over it.
    ("service", 4),
    ("roles", 5),
    ("watch", 5),
    // Read from the core at scrape time.
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

/// The top-level modules a file names through `crate::`.
#[derive(Default)]
struct CratePaths {
    modules: BTreeSet<String>,
}

impl CratePaths {
    /// `crate :: name` sequences in raw tokens (macro bodies).
    fn scan_tokens(&mut self, tokens: TokenStream) {
        let tokens: Vec<TokenTree> = tokens.into_iter().collect();
        for (i, token) in tokens.iter().enumerate() {
            match token {
                TokenTree::Group(group) => self.scan_tokens(group.stream()),
                TokenTree::Ident(ident) if ident == "crate" => {
                    if let (Some(TokenTree::Punct(a)), Some(TokenTree::Punct(b))) =
                        (tokens.get(i + 1), tokens.get(i + 2))
                        && a.as_char() == ':'
                        && b.as_char() == ':'
                    {
                        match tokens.get(i + 3) {
                            Some(TokenTree::Ident(name)) => {
                                self.modules.insert(name.to_string());
                            }
                            Some(TokenTree::Group(group)) => self.scan_group(group.stream()),
                            _ => {}
                        }
                    }
                }
                _ => {}
            }
        }
    }

    /// The first name of each comma-separated item of `crate::{...}`.
    fn scan_group(&mut self, tokens: TokenStream) {
        let mut first = true;
        for token in tokens {
            match token {
                TokenTree::Ident(name) if first => {
                    self.modules.insert(name.to_string());
                    first = false;
                }
                TokenTree::Punct(p) if p.as_char() == ',' => first = true,
                _ => first = false,
            }
        }
    }

    fn use_tree(&mut self, tree: &syn::UseTree, under_crate: bool) {
        match tree {
            syn::UseTree::Path(path) if !under_crate && path.ident == "crate" => {
                self.use_tree(&path.tree, true);
            }
            syn::UseTree::Path(_) if !under_crate => {}
            syn::UseTree::Path(path) => {
                self.modules.insert(path.ident.to_string());
            }
            syn::UseTree::Name(name) if under_crate => {
                self.modules.insert(name.ident.to_string());
            }
            syn::UseTree::Rename(rename) if under_crate => {
                self.modules.insert(rename.ident.to_string());
            }
            syn::UseTree::Group(group) => {
                for tree in &group.items {
                    self.use_tree(tree, under_crate);
                }
            }
            _ => {}
        }
    }
}

impl<'ast> Visit<'ast> for CratePaths {
    fn visit_item_use(&mut self, item: &'ast syn::ItemUse) {
        self.use_tree(&item.tree, false);
    }

    fn visit_path(&mut self, path: &'ast syn::Path) {
        let mut segments = path.segments.iter();
        if let (Some(first), Some(second)) = (segments.next(), segments.next())
            && first.ident == "crate"
        {
            self.modules.insert(second.ident.to_string());
        }
        syn::visit::visit_path(self, path);
    }

    fn visit_macro(&mut self, mac: &'ast syn::Macro) {
        self.scan_tokens(mac.tokens.clone());
        syn::visit::visit_macro(self, mac);
    }

    fn visit_attribute(&mut self, _: &'ast syn::Attribute) {
        // Doc comments and other attributes: links in prose are not imports.
    }
}

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).expect("read source folder") {
        let path = entry.expect("folder entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The top-level module a file of `src/` belongs to, or `None` for the crate roots and the
/// `ecat` binary (its own crate, which reaches the library as `server::`).
fn module_of(file: &Path) -> Option<String> {
    let relative = file.strip_prefix(src()).expect("under src/");
    let first = relative.components().next()?.as_os_str().to_str()?;
    let name = first.strip_suffix(".rs").unwrap_or(first);
    (!matches!(name, "lib" | "main" | "cli")).then(|| name.to_owned())
}

fn crate_paths(file: &Path) -> BTreeSet<String> {
    let text = fs::read_to_string(file).expect("read source file");
    let syntax = syn::parse_file(&text)
        .unwrap_or_else(|err| panic!("{} does not parse: {err}", file.display()));
    let mut paths = CratePaths::default();
    paths.visit_file(&syntax);
    paths.modules
}

#[test]
fn every_module_imports_only_modules_below_it() {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    files.sort();
    let mut unranked = BTreeSet::new();
    let mut upward = Vec::new();
    let mut seen = 0;
    for file in &files {
        let Some(module) = module_of(file) else {
            continue;
        };
        let Some(own) = rank(&module) else {
            unranked.insert(module);
            continue;
        };
        for used in crate_paths(file) {
            seen += 1;
            if used == module {
                continue;
            }
            match rank(&used) {
                Some(r) if r < own => {}
                // Items of the crate root (none today) and names that are not modules.
                None if !src().join(&used).exists()
                    && !src().join(format!("{used}.rs")).exists() => {}
                _ => upward.push(format!(
                    "{} ({module}) uses crate::{used}",
                    file.strip_prefix(src()).unwrap().display()
                )),
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
    // The scan saw the imports at all (a parser that found nothing would pass the above).
    assert!(seen > 100, "only {seen} crate:: paths found");
}

#[test]
fn grouped_imports_and_macro_bodies_are_seen() {
    let syntax: syn::File = syn::parse_str(
        "use crate::{config::Config, error::{ApiError, ErrorKind}};\n\
         /// [`crate::daemon`] in prose is not an import.\n\
         fn f() { tracing::info!(x = %crate::service::Core::name()); let _ = crate::input::ip::parse_mac; }\n\
         use crate::{self as here, tls};",
    )
    .expect("parses");
    let mut paths = CratePaths::default();
    paths.visit_file(&syntax);
    let found: Vec<&str> = paths.modules.iter().map(String::as_str).collect();
    assert_eq!(
        found,
        ["config", "error", "input", "self", "service", "tls"]
    );
}
