//! Which modules a Rust source file names: the reading behind the import-direction tests
//! inside a crate (`master-core/tests/checks/layering.rs`, `server/tests/checks/layering.rs`;
//! the ranks themselves are in those tests, docs/architecture.md explains them). Between
//! crates Cargo holds the direction.
//!
//! [`uses`] parses a file with Rust's grammar and returns every path it names, resolved
//! against the file's place in its crate: `use` items (grouped ones too, `use
//! crate::{a, b::{c, d}}`), paths in expressions, types and patterns, and the tokens of macro
//! calls and `macro_rules!` bodies (`crate::`, `$crate::` and `super::` chains there). `self::`
//! and `super::` are resolved through the file's module path and any inline `mod` around
//! them. Comments, doc comments and other attributes are not code and are not read.

use proc_macro2::{TokenStream, TokenTree};
use syn::visit::Visit;

/// One path a file names.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct Use {
    /// The path from its root: `crate` then the modules for a path into the file's own
    /// crate (`["crate", "mailbox", "eoe", "EoeTx"]`), else the path as written
    /// (`["master_core", "wire", "frame"]`, `["std", "fs"]`).
    pub path: Vec<String>,
    /// The line it is on (1-based).
    pub line: usize,
}

impl Use {
    /// The top-level module of the file's own crate this path enters, if it is one
    /// (`crate::mailbox::eoe` → `mailbox`).
    pub fn top_module(&self) -> Option<&str> {
        match self.path.as_slice() {
            [root, module, ..] if root == "crate" => Some(module),
            _ => None,
        }
    }

    /// The module under `parent` this path enters (`crate::mailbox::eoe::rx` with parent
    /// `mailbox` → `eoe`).
    pub fn module_under(&self, parent: &str) -> Option<&str> {
        match self.path.as_slice() {
            [root, p, module, ..] if root == "crate" && p == parent => Some(module),
            _ => None,
        }
    }

    /// The module of extern crate `name` this path enters (`master_core::wire::frame` with
    /// name `master_core` → `wire`).
    pub fn extern_module(&self, name: &str) -> Option<&str> {
        match self.path.as_slice() {
            [root, module, ..] if root == name => Some(module),
            _ => None,
        }
    }
}

/// Every `.rs` file under `dir`, sorted.
pub fn source_files(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    fn walk(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        let entries =
            std::fs::read_dir(dir).unwrap_or_else(|err| panic!("{}: {err}", dir.display()));
        for entry in entries {
            let path = entry.expect("directory entry").path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    let mut files = Vec::new();
    walk(dir, &mut files);
    files.sort();
    files
}

/// The module path of a source file under a crate's `src/`: `mailbox/engine/demux.rs` →
/// `["mailbox", "engine", "demux"]`, `mailbox/mod.rs` → `["mailbox"]`, `lib.rs` → `[]`.
pub fn module_path(relative: &std::path::Path) -> Vec<String> {
    let mut parts: Vec<String> = relative
        .iter()
        .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    if parts
        .last()
        .is_some_and(|p| p == "mod" || p == "lib" || p == "main")
    {
        parts.pop();
    }
    parts
}

/// Every path `source` names, for a file whose module path is `module` (see
/// [`module_path()`]).
pub fn uses(module: &[String], source: &str) -> syn::Result<Vec<Use>> {
    let file = syn::parse_file(source)?;
    let mut reader = Reader {
        module: module.to_vec(),
        found: Vec::new(),
    };
    reader.visit_file(&file);
    reader
        .found
        .sort_by(|a, b| (a.line, &a.path).cmp(&(b.line, &b.path)));
    reader.found.dedup();
    Ok(reader.found)
}

struct Reader {
    /// Where the code being read stands: the file's module path, then inline modules.
    module: Vec<String>,
    found: Vec<Use>,
}

impl Reader {
    /// `segments` (as written, the first one a root or a relative start) made absolute.
    fn resolve(&self, segments: &[String]) -> Option<Vec<String>> {
        let first = segments.first()?;
        match first.as_str() {
            "crate" => Some(segments.to_vec()),
            "self" => {
                let mut path = vec!["crate".to_string()];
                path.extend(self.module.iter().cloned());
                path.extend(segments[1..].iter().cloned());
                Some(path)
            }
            "super" => {
                let climbs = segments.iter().take_while(|s| *s == "super").count();
                let base = self.module.len().checked_sub(climbs)?;
                let mut path = vec!["crate".to_string()];
                path.extend(self.module[..base].iter().cloned());
                path.extend(segments[climbs..].iter().cloned());
                Some(path)
            }
            _ => Some(segments.to_vec()),
        }
    }

    fn push(&mut self, segments: &[String], line: usize) {
        // A lone `self` or `super` (`use super::*` reads as `super`) still names a module.
        if let Some(path) = self.resolve(segments) {
            self.found.push(Use { path, line });
        }
    }

    fn use_tree(&mut self, prefix: &mut Vec<String>, tree: &syn::UseTree) {
        match tree {
            syn::UseTree::Path(path) => {
                prefix.push(path.ident.to_string());
                self.use_tree(prefix, &path.tree);
                prefix.pop();
            }
            syn::UseTree::Name(syn::UseName { ident })
            | syn::UseTree::Rename(syn::UseRename { ident, .. }) => {
                let line = ident.span().start().line;
                if ident == "self" {
                    self.push(&prefix.clone(), line);
                } else {
                    prefix.push(ident.to_string());
                    self.push(&prefix.clone(), line);
                    prefix.pop();
                }
            }
            syn::UseTree::Glob(glob) => {
                if !prefix.is_empty() {
                    self.push(&prefix.clone(), glob.star_token.span.start().line);
                }
            }
            syn::UseTree::Group(group) => {
                for tree in &group.items {
                    self.use_tree(prefix, tree);
                }
            }
        }
    }

    /// `crate :: a :: b`, `$crate :: a` and `super :: super :: a` sequences in raw tokens.
    fn tokens(&mut self, tokens: TokenStream) {
        let tokens: Vec<TokenTree> = tokens.into_iter().collect();
        let mut i = 0;
        while i < tokens.len() {
            match &tokens[i] {
                TokenTree::Group(group) => self.tokens(group.stream()),
                TokenTree::Ident(ident)
                    if (ident == "crate" || ident == "super")
                        && !follows_path_separator(&tokens, i) =>
                {
                    let line = ident.span().start().line;
                    let mut segments = vec![ident.to_string()];
                    let mut j = i + 1;
                    while let (Some(TokenTree::Punct(a)), Some(TokenTree::Punct(b))) =
                        (tokens.get(j), tokens.get(j + 1))
                        && a.as_char() == ':'
                        && b.as_char() == ':'
                    {
                        match tokens.get(j + 2) {
                            Some(TokenTree::Ident(next)) => {
                                segments.push(next.to_string());
                                j += 3;
                            }
                            Some(TokenTree::Group(group)) => {
                                // `crate::{a, b}` in a macro: each item's first name.
                                for item in group_items(group.stream()) {
                                    let mut path = segments.clone();
                                    path.push(item);
                                    self.push(&path, line);
                                }
                                j += 3;
                                segments.clear();
                                break;
                            }
                            _ => break,
                        }
                    }
                    if segments.len() > 1 {
                        self.push(&segments, line);
                    }
                    i = j.max(i + 1);
                    continue;
                }
                _ => {}
            }
            i += 1;
        }
    }
}

/// Whether the token at `i` comes right after `::` (the `super` of `a::super` is no start).
fn follows_path_separator(tokens: &[TokenTree], i: usize) -> bool {
    i >= 1 && matches!(&tokens[i - 1], TokenTree::Punct(p) if p.as_char() == ':')
}

/// The first name of each comma-separated item in a `{...}` group.
fn group_items(tokens: TokenStream) -> Vec<String> {
    let mut items = Vec::new();
    let mut first = true;
    for token in tokens {
        match token {
            TokenTree::Ident(name) if first => {
                items.push(name.to_string());
                first = false;
            }
            TokenTree::Punct(p) if p.as_char() == ',' => first = true,
            _ => first = false,
        }
    }
    items
}

impl<'ast> Visit<'ast> for Reader {
    fn visit_item_use(&mut self, item: &'ast syn::ItemUse) {
        self.use_tree(&mut Vec::new(), &item.tree);
    }

    fn visit_item_mod(&mut self, item: &'ast syn::ItemMod) {
        // Only an inline module changes where `self` and `super` point; `mod x;` is a file
        // of its own, read with its own module path.
        if item.content.is_some() {
            self.module.push(item.ident.to_string());
            syn::visit::visit_item_mod(self, item);
            self.module.pop();
        }
    }

    fn visit_path(&mut self, path: &'ast syn::Path) {
        let segments: Vec<String> = path.segments.iter().map(|s| s.ident.to_string()).collect();
        if segments.len() > 1
            && let Some(first) = path.segments.first()
        {
            self.push(&segments, first.ident.span().start().line);
        }
        syn::visit::visit_path(self, path);
    }

    fn visit_macro(&mut self, mac: &'ast syn::Macro) {
        self.tokens(mac.tokens.clone());
        syn::visit::visit_macro(self, mac);
    }

    fn visit_attribute(&mut self, _: &'ast syn::Attribute) {
        // Doc comments and other attributes: a link in prose is not an import.
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paths(module: &[&str], source: &str) -> Vec<String> {
        let module: Vec<String> = module.iter().map(|s| s.to_string()).collect();
        uses(&module, source)
            .expect("parses")
            .into_iter()
            .map(|u| format!("{}:{}", u.line, u.path.join("::")))
            .collect()
    }

    #[test]
    fn grouped_imports_are_each_seen() {
        assert_eq!(
            paths(
                &["service"],
                "use crate::{config::Config, error::{ApiError, ErrorKind}, self as here};"
            ),
            [
                "1:crate",
                "1:crate::config::Config",
                "1:crate::error::ApiError",
                "1:crate::error::ErrorKind",
            ]
        );
    }

    #[test]
    fn super_and_self_resolve_through_files_and_inline_modules() {
        let source = "use super::super::bus::BusHandle;\n\
                      use self::inner::X;\n\
                      mod tests { use super::*; fn f() { super::super::g(); } }\n";
        assert_eq!(
            paths(&["mailbox", "engine", "demux"], source),
            [
                "1:crate::mailbox::bus::BusHandle",
                "2:crate::mailbox::engine::demux::inner::X",
                "3:crate::mailbox::engine::demux",
                "3:crate::mailbox::engine::g",
            ]
        );
        // Climbing above the crate root is no path.
        assert_eq!(
            paths(&["wire"], "use super::super::x;"),
            Vec::<String>::new()
        );
    }

    #[test]
    fn macro_bodies_are_read_and_comments_are_not() {
        let source = "//! Mentions crate::gateway in a comment only.\n\
                      /// And [`crate::daemon`] in a doc comment.\n\
                      fn f() {\n\
                      tracing::info!(x = %crate::service::Core::name()); // crate::master\n\
                      }\n\
                      macro_rules! m { () => { $crate::wire::Frame::new() }; }\n\
                      fn g() { let _ = master_core::wire::frame::Frame::new; }\n";
        assert_eq!(
            paths(&["bus"], source),
            [
                "4:crate::service::Core::name",
                "4:tracing::info",
                "6:crate::wire::Frame::new",
                "7:master_core::wire::frame::Frame::new",
            ]
        );
    }

    #[test]
    fn modules_are_read_off_a_path() {
        let u = Use {
            path: ["crate", "mailbox", "eoe", "rx"].map(String::from).to_vec(),
            line: 1,
        };
        assert_eq!(u.top_module(), Some("mailbox"));
        assert_eq!(u.module_under("mailbox"), Some("eoe"));
        assert_eq!(u.module_under("wire"), None);
        let e = Use {
            path: ["master_core", "wire", "frame"].map(String::from).to_vec(),
            line: 1,
        };
        assert_eq!(
            (e.top_module(), e.extern_module("master_core")),
            (None, Some("wire"))
        );
        assert_eq!(
            module_path(std::path::Path::new("mailbox/engine/mod.rs")),
            ["mailbox", "engine"]
        );
    }
}
