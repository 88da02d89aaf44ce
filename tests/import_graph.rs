//! Contract: the modules of `src/` import each other without circles, and no source file
//! grows past the size the project allows.
//!
//! The graph (`granrepro::provenance::imports`, the parser the results lock also uses) has one node per file of `src/`. An edge `a → b` is any path in `a` that names
//! an item of `b`: `use crate::…` trees (with their `{…}` groups), inline `crate::…` paths
//! `super::…` and `self::…` paths, and paths through a child module (`world::World` in
//! `dem/mod.rs`). A re-export (`pub use world::World`) is structure, not an import: a name
//! is followed through it to the file that defines it. `#[cfg(test)]` modules are left out
//! (tests may reach anywhere). Comments and string literals are ignored.
//!
//! `KNOWN_CIRCLES` lists the circles that are still to be broken (issue 23); the test fails
//! on any other circle, and on a listed circle that no longer exists (delete its line), so
//! the list only shrinks. `cargo test --test import_graph -- --nocapture` prints the graph's
//! circles with the names that tie each.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use granrepro::provenance::imports::{Graph, code_of, rust_files, use_tree};

/// Circles not yet broken: the files of each, sorted, joined by spaces.
const KNOWN_CIRCLES: &[&str] = &[];

/// Largest source file allowed, in lines (issue 23: "no file over ~800 lines").
const MAX_LINES: usize = 800;

/// Files over `MAX_LINES` today, with the count they may not exceed (only shrinks).
const KNOWN_LONG: &[(&str, usize)] = &[];

fn src_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rel(f: &Path) -> String {
    f.strip_prefix(Path::new(env!("CARGO_MANIFEST_DIR")))
        .unwrap()
        .to_string_lossy()
        .to_string()
}

#[test]
fn no_import_circles_beyond_the_known_ones() {
    let g = Graph::build(&src_root());
    let circles = g.circles();
    let mut report = String::new();
    let mut seen = BTreeSet::new();
    for c in &circles {
        let key = c.iter().map(|f| rel(f)).collect::<Vec<_>>().join(" ");
        report.push_str(&format!("circle of {} files: {key}\n", c.len()));
        let set: BTreeSet<&PathBuf> = c.iter().collect();
        for a in c {
            for (b, names) in g.edges.get(a).into_iter().flatten() {
                if set.contains(b) {
                    let names: Vec<&str> = names.iter().map(String::as_str).collect();
                    report.push_str(&format!("  {} -> {}: {}\n", rel(a), rel(b), names.join(", ")));
                }
            }
        }
        seen.insert(key);
    }
    println!("{report}");
    let known: BTreeSet<String> = KNOWN_CIRCLES.iter().map(|s| s.to_string()).collect();
    let new: Vec<&String> = seen.difference(&known).collect();
    let gone: Vec<&String> = known.difference(&seen).collect();
    assert!(
        new.is_empty(),
        "new import circles (break them; see the module doc):\n{report}\nnew: {new:#?}"
    );
    assert!(
        gone.is_empty(),
        "these known circles are broken or changed: update KNOWN_CIRCLES\n{gone:#?}\n{report}"
    );
}

#[test]
fn no_source_file_over_the_line_limit() {
    let root = src_root();
    let mut files = Vec::new();
    rust_files(&root, &mut files);
    let known: BTreeMap<&str, usize> = KNOWN_LONG.iter().copied().collect();
    let mut bad = Vec::new();
    for f in &files {
        let n = std::fs::read_to_string(f).unwrap().lines().count();
        let r = rel(f);
        let limit = known.get(r.as_str()).copied().unwrap_or(MAX_LINES);
        if n > limit {
            bad.push(format!("{r}: {n} lines > {limit}"));
        }
    }
    assert!(
        bad.is_empty(),
        "split these files along their concerns:\n{}",
        bad.join("\n")
    );
}

/// The parser itself: leaves of a `use` group, and no path from a comment, a string or a test module.
#[test]
fn the_parser_reads_use_groups_and_skips_comments_strings_and_tests() {
    let (leaves, _) = use_tree("dem::{world::{Ptr, X}, passes::Rd};");
    assert_eq!(
        leaves,
        vec![
            vec!["dem", "world", "Ptr"],
            vec!["dem", "world", "X"],
            vec!["dem", "passes", "Rd"]
        ]
        .into_iter()
        .map(|v| v.into_iter().map(String::from).collect::<Vec<_>>())
        .collect::<Vec<_>>()
    );
    let code = code_of("// use crate::a;\nlet s = \"crate::b\"; #[cfg(test)] mod t { use crate::c; }\nuse crate::d;");
    assert!(!code.contains("crate::a") && !code.contains("crate::b") && !code.contains("crate::c"));
    assert!(code.contains("crate::d"));
}
