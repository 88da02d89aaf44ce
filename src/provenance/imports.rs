//! The import graph of the crate's source files: one node per file of `src/`, an edge
//! `a → b` for any path in `a` that names an item of `b` (`use crate::…` trees with their
//! `{…}` groups, inline `crate::…`, `super::…` and `self::…` paths, paths through a child
//! module). A re-export (`pub use world::World`) is structure, not an import: a name is
//! followed through it to the file that defines it. `#[cfg(test)]` items, comments and
//! string literals are left out.
//!
//! One parser serves three users: `tests/import_graph.rs` (no circles), the build script
//! (each kind's source closure, hashed into the binary for the results lock) and
//! [`super::sources`]. It uses only `std`, so the build script includes this file as is.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The import graph of a source tree.
pub struct Graph {
    /// Module path (`crate::dem::world`) of each file.
    pub module_of: BTreeMap<PathBuf, Vec<String>>,
    /// File of each module path.
    pub file_of: BTreeMap<Vec<String>, PathBuf>,
    /// Per `mod.rs`: re-exported name → module path it comes from.
    pub reexports: BTreeMap<Vec<String>, BTreeMap<String, Vec<String>>>,
    /// Edges with the names behind them.
    pub edges: BTreeMap<PathBuf, BTreeMap<PathBuf, BTreeSet<String>>>,
}

/// The `.rs` files under `dir`, sorted (depth first).
pub fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else { return };
    let mut entries: Vec<_> = rd.flatten().map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The module path (`crate::dem::world`) of `file` under the source root.
pub fn module_path(root: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(root).unwrap();
    let mut parts: Vec<String> = rel.iter().map(|s| s.to_string_lossy().to_string()).collect();
    let last = parts.pop().unwrap();
    let stem = last.trim_end_matches(".rs").to_string();
    if stem != "mod" && stem != "lib" && stem != "main" {
        parts.push(stem);
    }
    let mut m = vec!["crate".to_string()];
    m.extend(parts);
    m
}

/// The code of a file without comments, string and char literals, and `#[cfg(test)]` items.
pub fn code_of(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            let mut depth = 0;
            while i < b.len() {
                if b[i..].starts_with(b"/*") {
                    depth += 1;
                    i += 2;
                } else if b[i..].starts_with(b"*/") {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if b[i] == b'r' && (b[i..].starts_with(b"r\"") || b[i..].starts_with(b"r#")) && !ident_byte_before(b, i)
        {
            // raw string r#"…"#
            let mut j = i + 1;
            let mut hashes = 0;
            while j < b.len() && b[j] == b'#' {
                hashes += 1;
                j += 1;
            }
            if j < b.len() && b[j] == b'"' {
                let close: Vec<u8> = std::iter::once(b'"').chain(std::iter::repeat_n(b'#', hashes)).collect();
                j += 1;
                while j < b.len() && !b[j..].starts_with(&close) {
                    j += 1;
                }
                i = j + close.len();
                out.push_str("\"\"");
            } else {
                out.push('r');
                i += 1;
            }
        } else if b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                if b[i] == b'\\' {
                    i += 1;
                }
                i += 1;
            }
            i += 1;
            out.push_str("\"\"");
        } else if b[i] == b'\'' {
            // a char literal ('a', '\n', '\u{..}') or a lifetime ('a)
            let rest = &text[i + 1..];
            let lit = if rest.starts_with('\\') {
                rest.find('\'').map(|k| k + 2)
            } else {
                let mut cs = rest.char_indices();
                match (cs.next(), cs.next()) {
                    (Some(_), Some((k, '\''))) => Some(k + 2),
                    _ => None,
                }
            };
            match lit {
                Some(n) => {
                    i += n;
                    out.push_str("' '");
                }
                None => {
                    out.push('\'');
                    i += 1;
                }
            }
        } else {
            let c = text[i..].chars().next().unwrap();
            out.push(c);
            i += c.len_utf8();
        }
    }
    strip_cfg_test(&out)
}

fn ident_byte_before(b: &[u8], i: usize) -> bool {
    i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')
}

/// Drops every item that follows `#[cfg(test)]` (up to its matching `}` or `;`).
fn strip_cfg_test(code: &str) -> String {
    let mut out = String::new();
    let mut rest = code;
    while let Some(k) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..k]);
        let after = &rest[k..];
        rest = &after[group_end(after, '{', '}', true)..];
    }
    out.push_str(rest);
    out
}

/// The byte just past the group `open … close` that starts `s` (nested groups counted),
/// or past the first `;` outside any group when `semicolon_ends`; `s.len()` when unclosed.
fn group_end(s: &str, open: char, close: char, semicolon_ends: bool) -> usize {
    let mut depth = 0usize;
    for (j, c) in s.char_indices() {
        if c == open {
            depth += 1;
        } else if c == close {
            depth = depth.saturating_sub(1);
            if depth == 0 {
                return j + c.len_utf8();
            }
        } else if c == ';' && semicolon_ends && depth == 0 {
            return j + 1;
        }
    }
    s.len()
}

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// Parses a use-tree at the start of `s` (after a leading path such as `crate::`), returning
/// its leaf paths (relative) and how many bytes it took.
pub fn use_tree(s: &str) -> (Vec<Vec<String>>, usize) {
    let mut i = 0;
    let mut prefix: Vec<String> = Vec::new();
    let b = s.as_bytes();
    let skip_ws = |i: &mut usize| {
        while *i < b.len() && (b[*i] as char).is_whitespace() {
            *i += 1;
        }
    };
    loop {
        skip_ws(&mut i);
        if i < b.len() && b[i] == b'{' {
            i += 1;
            let mut leaves = Vec::new();
            loop {
                skip_ws(&mut i);
                if i >= b.len() {
                    break;
                }
                if b[i] == b'}' {
                    i += 1;
                    break;
                }
                if b[i] == b',' {
                    i += 1;
                    continue;
                }
                let (sub, n) = use_tree(&s[i..]);
                i += n.max(1);
                for l in sub {
                    let mut p = prefix.clone();
                    p.extend(l);
                    leaves.push(p);
                }
            }
            return (leaves, i);
        }
        if i < b.len() && b[i] == b'*' {
            return (vec![prefix], i + 1);
        }
        let start = i;
        while i < b.len() && is_ident(b[i] as char) {
            i += 1;
        }
        if i == start {
            return (vec![prefix], i);
        }
        prefix.push(s[start..i].to_string());
        skip_ws(&mut i);
        if s[i..].starts_with("::") {
            i += 2;
        } else {
            return (vec![prefix], i);
        }
    }
}

impl Graph {
    /// The graph of the files under `root` (the crate's `src/`).
    pub fn build(root: &Path) -> Graph {
        let root = root.to_path_buf();
        let mut files = Vec::new();
        rust_files(&root, &mut files);
        let mut g = Graph {
            module_of: BTreeMap::new(),
            file_of: BTreeMap::new(),
            reexports: BTreeMap::new(),
            edges: BTreeMap::new(),
        };
        let mut code = BTreeMap::new();
        for f in &files {
            let m = module_path(&root, f);
            g.module_of.insert(f.clone(), m.clone());
            g.file_of.insert(m, f.clone());
            code.insert(f.clone(), code_of(&std::fs::read_to_string(f).unwrap_or_default()));
        }
        // re-exports of mod.rs / lib.rs: `pub use a::{B, c::D}` → B: m::a, D: m::a::c
        for (f, c) in &code {
            let m = g.module_of[f].clone();
            let mut names = BTreeMap::new();
            for (k, _) in c.match_indices("pub use ") {
                let (leaves, _) = use_tree(&c[k + 8..]);
                for l in leaves {
                    let Some(name) = l.last().cloned() else { continue };
                    let mut from = match l.first().map(String::as_str) {
                        Some("crate") => vec![],
                        Some("self") => m.clone(),
                        Some("super") => m[..m.len() - 1].to_vec(),
                        _ => m.clone(),
                    };
                    let skip = usize::from(matches!(
                        l.first().map(String::as_str),
                        Some("crate" | "self" | "super")
                    ));
                    if l.first().map(String::as_str) == Some("crate") {
                        from.push("crate".into());
                    }
                    from.extend(l[skip..l.len() - 1].iter().cloned());
                    names.insert(name, from);
                }
            }
            g.reexports.insert(m, names);
        }
        for (f, c) in &code {
            let m = g.module_of[f].clone();
            let c = &without_pub_use(c);
            // anchors: `crate::`, `super::`, `self::` and the names of this module's children
            let mut anchors: Vec<(String, Vec<String>)> = vec![
                ("crate::".into(), vec!["crate".into()]),
                ("super::".into(), m[..m.len() - 1].to_vec()),
                ("self::".into(), m.clone()),
            ];
            for child in g
                .file_of
                .keys()
                .filter(|k| k.len() == m.len() + 1 && k[..m.len()] == m[..])
            {
                anchors.push((format!("{}::", child.last().unwrap()), child.clone()));
            }
            let mut found: Vec<Vec<String>> = Vec::new();
            for (anchor, base) in &anchors {
                for (k, _) in c.match_indices(anchor.as_str()) {
                    let before = c[..k].chars().next_back();
                    if before.is_some_and(|ch| is_ident(ch) || ch == ':') {
                        continue;
                    }
                    let (leaves, _) = use_tree(&c[k + anchor.len()..]);
                    for l in leaves {
                        let mut b = base.clone();
                        let mut l = l.as_slice();
                        while l.first().map(String::as_str) == Some("super") {
                            b.pop();
                            l = &l[1..];
                        }
                        b.extend(l.iter().cloned());
                        found.push(b);
                    }
                }
            }
            // A name this file re-exports and also uses in its own code (`pub use
            // column_front::front_linked;` then `front_linked(…)` in a function body) is
            // an import too: the re-export line is structure, the call is not.
            if let Some(own) = g.reexports.get(&m) {
                for (name, from) in own {
                    if has_ident(c, name) {
                        let mut p = from.clone();
                        p.push(name.clone());
                        found.push(p);
                    }
                }
            }
            for path in found {
                if let Some((target, name)) = g.resolve(&path)
                    && &target != f
                {
                    g.edges
                        .entry(f.clone())
                        .or_default()
                        .entry(target)
                        .or_default()
                        .insert(name);
                }
            }
        }
        g
    }

    /// The file that defines what `path` (absolute, from `crate`) names, and that name.
    pub fn resolve(&self, path: &[String]) -> Option<(PathBuf, String)> {
        // longest prefix that is a module
        let mut k = path.len();
        while k > 0 && !self.file_of.contains_key(&path[..k]) {
            k -= 1;
        }
        if k == 0 {
            return None;
        }
        let module = &path[..k];
        let name = path.get(k).cloned().unwrap_or_else(|| module.last().unwrap().clone());
        // follow a re-export (possibly several levels)
        if let Some(next) = path.get(k).and_then(|n| self.reexports.get(module)?.get(n))
            && next.as_slice() != module
        {
            let mut p = next.clone();
            p.extend(path[k..].iter().cloned());
            if let Some(r) = self.resolve(&p) {
                return Some(r);
            }
        }
        Some((self.file_of[module].clone(), name))
    }

    /// Strongly connected components with more than one file (Tarjan).
    pub fn circles(&self) -> Vec<Vec<PathBuf>> {
        let nodes: Vec<&PathBuf> = self.module_of.keys().collect();
        let idx: BTreeMap<&PathBuf, usize> = nodes.iter().enumerate().map(|(i, f)| (*f, i)).collect();
        let adj: Vec<Vec<usize>> = nodes
            .iter()
            .map(|f| {
                self.edges
                    .get(*f)
                    .map(|e| e.keys().map(|t| idx[t]).collect())
                    .unwrap_or_default()
            })
            .collect();
        struct T {
            index: Vec<Option<usize>>,
            low: Vec<usize>,
            on: Vec<bool>,
            stack: Vec<usize>,
            next: usize,
            out: Vec<Vec<usize>>,
        }
        fn visit(v: usize, adj: &[Vec<usize>], t: &mut T) {
            t.index[v] = Some(t.next);
            t.low[v] = t.next;
            t.next += 1;
            t.stack.push(v);
            t.on[v] = true;
            for &w in &adj[v] {
                match t.index[w] {
                    None => {
                        visit(w, adj, t);
                        t.low[v] = t.low[v].min(t.low[w]);
                    }
                    Some(iw) if t.on[w] => t.low[v] = t.low[v].min(iw),
                    _ => {}
                }
            }
            if Some(t.low[v]) == t.index[v] {
                let mut c = Vec::new();
                loop {
                    let w = t.stack.pop().unwrap();
                    t.on[w] = false;
                    c.push(w);
                    if w == v {
                        break;
                    }
                }
                if c.len() > 1 {
                    t.out.push(c);
                }
            }
        }
        let n = nodes.len();
        let mut t = T {
            index: vec![None; n],
            low: vec![0; n],
            on: vec![false; n],
            stack: vec![],
            next: 0,
            out: vec![],
        };
        for v in 0..n {
            if t.index[v].is_none() {
                visit(v, &adj, &mut t);
            }
        }
        let mut out: Vec<Vec<PathBuf>> = t
            .out
            .into_iter()
            .map(|c| {
                let mut c: Vec<PathBuf> = c.into_iter().map(|i| nodes[i].clone()).collect();
                c.sort();
                c
            })
            .collect();
        out.sort();
        out
    }
}

/// Does `code` hold `name` as a whole identifier, other than in a `mod name;` declaration?
fn has_ident(code: &str, name: &str) -> bool {
    code.match_indices(name).any(|(k, _)| {
        let before = code[..k].chars().next_back();
        let after = code[k + name.len()..].chars().next();
        let head = code[..k].trim_end();
        let declared = head
            .strip_suffix("mod")
            .is_some_and(|h| !h.chars().next_back().is_some_and(is_ident));
        !declared && !before.is_some_and(is_ident) && !after.is_some_and(is_ident)
    })
}

/// The code without its `pub use` re-exports (structure, followed by `Graph::resolve`).
pub fn without_pub_use(code: &str) -> String {
    let mut out = String::new();
    let mut rest = code;
    while let Some(k) = rest.find("pub use ") {
        out.push_str(&rest[..k]);
        rest = &rest[k..];
        rest = &rest[rest.find(';').map_or(rest.len(), |e| e + 1)..];
    }
    out.push_str(rest);
    out
}

/// Where a type's methods live when they are not beside it: for each file `d` that defines
/// a type (`struct`, `enum`, `union`, `type` at the start of a line), the other files that
/// hold an `impl` block for that name (`impl N`, `impl T for N`, with any generics and path)
/// and import `d` or declare it as a submodule (an `impl` names its type, so its file imports the type's file; that
/// keeps two types of one name in different modules apart; a file's `impl N` of an `N` it
/// defines itself is its own). The import graph follows
/// names; a method call (`p.engine()`) names no file, so the results lock adds these edges
/// to each kind's source closure: a file that uses a type is built from its impls too.
pub fn impl_edges(g: &Graph) -> BTreeMap<PathBuf, BTreeSet<PathBuf>> {
    let mut defines: BTreeMap<String, BTreeSet<PathBuf>> = BTreeMap::new();
    let mut impls: Vec<(PathBuf, String)> = Vec::new();
    for f in g.module_of.keys() {
        let code = code_of(&std::fs::read_to_string(f).unwrap_or_default());
        for line in code.lines() {
            let t = strip_item_prefix(line.trim_start());
            for kw in ["struct ", "enum ", "union ", "type "] {
                if let Some(rest) = t.strip_prefix(kw) {
                    let name: String = rest.chars().take_while(|c| is_ident(*c)).collect();
                    if !name.is_empty() {
                        defines.entry(name).or_default().insert(f.clone());
                    }
                }
            }
            if let Some(name) = impl_self_type(t) {
                impls.push((f.clone(), name));
            }
        }
    }
    let mut edges: BTreeMap<PathBuf, BTreeSet<PathBuf>> = BTreeMap::new();
    for (f, name) in impls {
        let here = defines.get(&name).is_some_and(|ds| ds.contains(&f));
        if here {
            continue; // `impl N` of the file's own N, which shadows any imported one
        }
        for d in defines.get(&name).into_iter().flatten() {
            if *d != f && (g.edges.get(&f).is_some_and(|e| e.contains_key(d)) || is_ancestor(g, &f, d)) {
                edges.entry(d.clone()).or_default().insert(f.clone());
            }
        }
    }
    edges
}

/// Is `f` a module above `d` (`dem/world.rs` above `dem/world/data.rs`)? A parent names its
/// child's type through its own `pub use data::World`, a re-export, which is structure and
/// not an import, so `impl World` in `dem/world.rs` (the step, beside `mod data;`) left no
/// edge: the DEM's step and force passes (`dem/world.rs`, `dem/passes.rs`) were in no
/// kind's closure, and a change there left every committed DEM result "fresh".
fn is_ancestor(g: &Graph, f: &Path, d: &Path) -> bool {
    match (g.module_of.get(f), g.module_of.get(d)) {
        (Some(mf), Some(md)) => md.len() > mf.len() && md.starts_with(mf),
        _ => false,
    }
}

/// A line without its leading visibility and `unsafe`/`default` qualifiers.
fn strip_item_prefix(mut t: &str) -> &str {
    loop {
        let before = t;
        for p in ["pub(crate) ", "pub(super) ", "pub ", "unsafe ", "default "] {
            if let Some(r) = t.strip_prefix(p) {
                t = r.trim_start();
            }
        }
        if t == before {
            return t;
        }
    }
}

/// The self type's name of an `impl` header line (`impl<'a, T: X> Tr<U> for a::B<'a> {` →
/// `B`), or None when the line is not one.
pub fn impl_self_type(t: &str) -> Option<String> {
    let rest = t.strip_prefix("impl")?;
    if !(rest.starts_with(' ') || rest.starts_with('<')) {
        return None;
    }
    // skip the impl's own generics
    let mut s = rest.trim_start();
    if s.starts_with('<') {
        s = s[group_end(s, '<', '>', false)..].trim_start();
    }
    // the header up to `{` or `where`, and in it the part after a top-level ` for `
    let head = s.split(['{']).next().unwrap_or(s);
    let head = head.split(" where").next().unwrap_or(head);
    let mut depth = 0usize;
    let mut self_start = 0;
    let hb = head.as_bytes();
    for i in 0..hb.len() {
        match hb[i] {
            b'<' => depth += 1,
            b'>' => depth = depth.saturating_sub(1),
            b' ' if depth == 0 && head[i..].starts_with(" for ") => self_start = i + 5,
            _ => {}
        }
    }
    let ty = head[self_start..]
        .trim_start()
        .trim_start_matches(['&', '*'])
        .trim_start();
    let ty = ty.strip_prefix("mut ").unwrap_or(ty).trim_start();
    let ty = ty.strip_prefix("dyn ").unwrap_or(ty);
    let path: String = ty.chars().take_while(|c| is_ident(*c) || *c == ':').collect();
    let name = path.rsplit("::").next().unwrap_or("").to_string();
    (!name.is_empty() && name.chars().next().is_some_and(|c| c.is_ascii_uppercase())).then_some(name)
}

#[cfg(test)]
mod tests {
    use super::impl_self_type;

    #[test]
    fn the_self_type_of_an_impl_header() {
        let t = |s: &str| impl_self_type(s);
        assert_eq!(t("impl RunParams {"), Some("RunParams".into()));
        assert_eq!(t("impl<'a> PileEngine for CdPile<'a> {"), Some("CdPile".into()));
        assert_eq!(
            t("impl<T: Copy> fmt::Display for crate::dem::World<T> where T: X {"),
            Some("World".into())
        );
        assert_eq!(t("impl Validate for Params {"), Some("Params".into()));
        assert_eq!(t("impl<T> From<Vec<T>> for Series {"), Some("Series".into()));
        assert_eq!(t("impl Iterator for &mut Walker {"), Some("Walker".into()));
        // not an impl block
        assert_eq!(t("fn f(x: impl Fn(f64)) -> f64 {"), None);
        assert_eq!(t("implicit: bool,"), None);
        // a foreign type has a lower-case or no name we define
        assert_eq!(t("impl<T> Trait for f64 {"), None);
    }
}
