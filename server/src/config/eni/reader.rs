//! Reading an ENI's elements with their line numbers, and keeping track of which ones
//! were used, so that the rest can be listed (never silently dropped).

use std::cell::RefCell;
use std::collections::{BTreeMap, HashSet};

use roxmltree::{Document, Node, NodeId};

/// A parsed ENI and the elements used so far.
pub struct Reader<'a, 'input> {
    /// The document.
    pub doc: &'a Document<'input>,
    /// The file, for messages.
    pub file: String,
    used: RefCell<HashSet<NodeId>>,
}

impl<'a, 'input> Reader<'a, 'input> {
    /// A reader of `doc` from `file`.
    pub fn new(doc: &'a Document<'input>, file: String) -> Self {
        Reader {
            doc,
            file,
            used: RefCell::new(HashSet::new()),
        }
    }

    /// `file:line: <Element>: what`.
    pub fn error(&self, node: Node<'_, '_>, what: impl std::fmt::Display) -> String {
        let pos = self.doc.text_pos_at(node.range().start);
        format!(
            "{}:{}: <{}>: {what}",
            self.file,
            pos.row,
            node.tag_name().name()
        )
    }

    /// Marks `node` (and everything in it) used.
    pub fn use_all(&self, node: Node<'_, '_>) {
        let mut used = self.used.borrow_mut();
        for n in node.descendants() {
            used.insert(n.id());
        }
    }

    /// Marks `node` itself used (its children are looked at one by one).
    pub fn use_node(&self, node: Node<'_, '_>) {
        self.used.borrow_mut().insert(node.id());
    }

    /// Takes the used mark off `node` (looked at, but not used: it is listed).
    pub fn used_off(&self, node: Node<'_, '_>) {
        self.used.borrow_mut().remove(&node.id());
    }

    /// The child element `name` of `node`, marked used.
    pub fn child<'n>(&self, node: Node<'n, 'input>, name: &str) -> Option<Node<'n, 'input>> {
        let found = node
            .children()
            .find(|c| c.is_element() && c.tag_name().name() == name)?;
        self.use_node(found);
        Some(found)
    }

    /// The child elements `name` of `node`, marked used.
    pub fn children<'n>(&self, node: Node<'n, 'input>, name: &str) -> Vec<Node<'n, 'input>> {
        let found: Vec<_> = node
            .children()
            .filter(|c| c.is_element() && c.tag_name().name() == name)
            .collect();
        for n in &found {
            self.use_node(*n);
        }
        found
    }

    /// The text of the child `name`, marked used.
    pub fn text(&self, node: Node<'_, 'input>, name: &str) -> Option<String> {
        let child = self.child(node, name)?;
        self.use_all(child);
        Some(child.text().unwrap_or("").trim().to_owned())
    }

    /// The number in the child `name` (decimal, or hex as `#x1A00` or `0x1A00`).
    pub fn number(&self, node: Node<'_, 'input>, name: &str) -> Result<Option<u64>, String> {
        let Some(child) = self.child(node, name) else {
            return Ok(None);
        };
        self.use_all(child);
        let text = child.text().unwrap_or("").trim();
        parse_number(text)
            .map(Some)
            .ok_or_else(|| self.error(child, format!("{text:?} is not a number")))
    }

    /// [`Reader::number`], required and fitting in `T`.
    pub fn required<T: TryFrom<u64>>(
        &self,
        node: Node<'_, 'input>,
        name: &str,
    ) -> Result<T, String> {
        let value = self
            .number(node, name)?
            .ok_or_else(|| self.error(node, format!("<{name}> is missing")))?;
        T::try_from(value)
            .map_err(|_| self.error(node, format!("<{name}> {value} is out of range")))
    }

    /// The unused elements, as paths with counts, topmost only (`Config/Slave/InitCmds: 5`).
    pub fn unused(&self) -> BTreeMap<String, usize> {
        let used = self.used.borrow();
        let mut out = BTreeMap::new();
        let root = self.doc.root_element();
        let mut stack = vec![root];
        while let Some(node) = stack.pop() {
            for child in node.children().filter(Node::is_element) {
                if used.contains(&child.id()) {
                    stack.push(child);
                } else {
                    *out.entry(path(child)).or_insert(0) += 1;
                }
            }
        }
        out
    }
}

/// `Config/Slave/InitCmds`, from under the root element.
fn path(node: Node<'_, '_>) -> String {
    let mut names: Vec<&str> = node
        .ancestors()
        .filter(|n| n.is_element())
        .map(|n| n.tag_name().name())
        .collect();
    names.pop(); // the root element
    names.reverse();
    names.join("/")
}

/// ETG.2100 numbers: decimal, `#x` hex, or `0x` hex.
pub fn parse_number(text: &str) -> Option<u64> {
    let text = text.trim();
    if let Some(hex) = text
        .strip_prefix("#x")
        .or_else(|| text.strip_prefix("0x"))
        .or_else(|| text.strip_prefix("#X"))
    {
        u64::from_str_radix(hex, 16).ok()
    } else {
        text.parse().ok()
    }
}
