//! Contract: the repository stands alone. Nothing under `src/`, `stages/`, `docs/`,
//! `bench/`, `tests/`, nor `pipeline.yaml` or `README.md`, names a path outside the
//! repository: no reference to the shared work area or to the specification notes the
//! project was started from (the patterns are in [`FORBIDDEN`]), and no relative path
//! that climbs out of the repository — a Markdown link or path token in a `.md` file, or
//! an `include_str!` / `include_bytes!` argument in a `.rs` file, resolved from the file's
//! own folder.
//!
//! A user of the repository must be able to follow every reference: definitions and
//! choices are cited as `docs/definitions.md D07` (or `I15`, `SC-PILE`, `c.2`), the thesis
//! chapter by section, figure, table and equation, and reference inputs for other codes
//! live in `bench/`. On failure the test lists every offending `file:line` with the fix.

use std::path::{Component, Path, PathBuf};

/// Substrings no project file may contain. Built with `concat!` so that this file does
/// not contain them itself.
const FORBIDDEN: [&str; 6] = [
    concat!("..", "/shared"),
    concat!("/wo", "rk/"),
    concat!("figures", ".md"),
    concat!("shared", "/spec"),
    concat!("shared", "/seed"),
    concat!("shared", "/bench"),
];

/// What the repository's user-facing tree is made of (folders walked recursively).
const ROOTS: [&str; 7] = ["src", "stages", "docs", "bench", "tests", "pipeline.yaml", "README.md"];

fn files_under(p: &Path, out: &mut Vec<PathBuf>) {
    if p.is_dir() {
        let mut entries: Vec<_> = std::fs::read_dir(p).unwrap().map(|e| e.unwrap().path()).collect();
        entries.sort();
        for e in entries {
            files_under(&e, out);
        }
    } else if p.is_file() {
        out.push(p.to_path_buf());
    }
}

/// Depth of `rel` (a path relative to a folder `depth` levels below the repository root)
/// at its shallowest point: negative means it leaves the repository.
fn lowest_depth(depth: i64, rel: &str) -> i64 {
    let mut d = depth;
    let mut low = d;
    for c in Path::new(rel).components() {
        match c {
            Component::ParentDir => d -= 1,
            Component::Normal(_) => d += 1,
            _ => {}
        }
        low = low.min(d);
    }
    low
}

/// Path tokens starting with `../` in a line of Markdown (links, code spans, plain text).
fn md_relative_tokens(line: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let b = line.as_bytes();
    let mut i = 0;
    while let Some(k) = line[i..].find("../") {
        let s = i + k;
        let starts_token = s == 0 || matches!(b[s - 1], b'(' | b' ' | b'`' | b'"' | b'\'' | b'<' | b'[' | b'=');
        if starts_token {
            let end = line[s..]
                .find(|c: char| c.is_whitespace() || matches!(c, ')' | '`' | '"' | '\'' | '>' | ']' | '#'))
                .map_or(line.len(), |e| s + e);
            out.push(&line[s..end]);
            i = end.max(s + 3);
        } else {
            i = s + 3;
        }
    }
    out
}

/// Arguments of `include_str!("…")` / `include_bytes!("…")` in a line of Rust.
fn rust_include_paths(line: &str) -> Vec<&str> {
    let mut out = Vec::new();
    for mac in ["include_str!(\"", "include_bytes!(\""] {
        let mut rest = line;
        while let Some(k) = rest.find(mac) {
            let after = &rest[k + mac.len()..];
            if let Some(e) = after.find('"') {
                out.push(&after[..e]);
            }
            rest = after;
        }
    }
    out
}

/// Every violation in one file's text, as `file:line: what — fix`.
fn violations(rel_file: &str, text: &str) -> Vec<String> {
    let depth = Path::new(rel_file).components().count() as i64 - 1;
    let is_md = rel_file.ends_with(".md");
    let is_rs = rel_file.ends_with(".rs");
    let mut v = Vec::new();
    for (n, line) in text.lines().enumerate() {
        for pat in FORBIDDEN {
            if line.contains(pat) {
                v.push(format!(
                    "{rel_file}:{}: names `{pat}`, outside the repository — cite docs/definitions.md (D.., I.., SC-.., c.x) or the chapter (section, figure, equation), or bench/",
                    n + 1
                ));
            }
        }
        let mut rel_paths = Vec::new();
        if is_md {
            rel_paths.extend(md_relative_tokens(line));
        }
        if is_rs {
            rel_paths.extend(rust_include_paths(line));
        }
        for r in rel_paths {
            if lowest_depth(depth, r) < 0 {
                v.push(format!(
                    "{rel_file}:{}: relative path `{r}` climbs out of the repository — point inside it",
                    n + 1
                ));
            }
        }
    }
    v
}

#[test]
fn nothing_names_a_path_outside_the_repository() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for r in ROOTS {
        files_under(&root.join(r), &mut files);
    }
    assert!(
        files.len() > 100,
        "only {} files found under {ROOTS:?}: wrong root?",
        files.len()
    );
    let mut bad = Vec::new();
    for f in &files {
        let Ok(text) = std::fs::read_to_string(f) else { continue }; // binary files
        let rel = f.strip_prefix(root).unwrap().to_string_lossy().replace('\\', "/");
        bad.extend(violations(&rel, &text));
    }
    assert!(
        bad.is_empty(),
        "{} reference(s) outside the repository:\n{}",
        bad.len(),
        bad.join("\n")
    );
}

/// The scanner itself: each kind of violation is found, and paths that stay inside are not.
#[test]
fn the_scanner_finds_each_kind_of_violation() {
    let spec = concat!("see ", "figures", ".md D07");
    assert_eq!(violations("src/a.rs", spec).len(), 1);
    let up = concat!("run `..", "/shared/x/` first");
    assert_eq!(violations("README.md", up).len(), 2, "pattern and climbing path");
    assert_eq!(violations("docs/a.md", "[x](../../outside.md)").len(), 1);
    assert_eq!(
        violations("docs/a.md", "[x](../README.md) and `../src/lib.rs`").len(),
        0
    );
    assert_eq!(violations("README.md", "[x](docs/a.md)").len(), 0);
    assert_eq!(violations("tests/a.rs", "include_str!(\"../stages/x.yaml\")").len(), 0);
    assert_eq!(violations("tests/a.rs", "include_str!(\"../../x.yaml\")").len(), 1);
    // A test input that names an escaping id is not a reference (not Markdown, not an include).
    assert_eq!(violations("tests/a.rs", "id: ../../../escaped-laws").len(), 0);
}

/// Every relative Markdown link of the README and `docs/` names a file of the repository
/// (the anchor after `#` aside): a link to a committed result that a re-keep renamed or
/// left out fails here, not in a reader's browser.
#[test]
fn every_relative_markdown_link_resolves() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = vec![root.join("README.md")];
    files_under(&root.join("docs"), &mut files);
    let mut bad = Vec::new();
    for f in files.iter().filter(|f| f.extension().is_some_and(|e| e == "md")) {
        let text = std::fs::read_to_string(f).unwrap();
        let dir = f.parent().unwrap();
        for (n, line) in text.lines().enumerate() {
            let mut rest = line;
            while let Some(k) = rest.find("](") {
                let after = &rest[k + 2..];
                let end = after.find(')').unwrap_or(after.len());
                let target = after[..end].split('#').next().unwrap_or("").trim();
                rest = &after[end..];
                if target.is_empty() || target.contains("://") || target.starts_with("mailto:") {
                    continue;
                }
                if !dir.join(target).exists() {
                    let rel = f.strip_prefix(root).unwrap().display();
                    bad.push(format!("{rel}:{}: `{target}` does not exist", n + 1));
                }
            }
        }
    }
    assert!(bad.is_empty(), "{} broken link(s):\n{}", bad.len(), bad.join("\n"));
}
