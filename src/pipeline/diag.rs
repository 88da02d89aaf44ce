//! Diagnostics for bad input: every problem names the file, the line (where it can be
//! found), the key and what is allowed. Validation collects all of them before anything
//! runs; the CLI prints them together and exits with code 2.

use std::fmt;
use std::path::{Path, PathBuf};

/// One problem in the user's input.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnostic {
    /// File the problem is in (pipeline.yaml, a stages/*.yaml file, or `<command line>`).
    pub file: PathBuf,
    /// 1-based line, where known.
    pub line: Option<usize>,
    /// Key path, e.g. `stages[psd-col].params.d_min_mm`.
    pub key: String,
    /// What is wrong.
    pub message: String,
    /// How to fix it / what is allowed.
    pub help: String,
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "error: {}", self.file.display())?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        write!(f, ": {}: {}", self.key, self.message)?;
        if !self.help.is_empty() {
            write!(f, "\n  help: {}", self.help)?;
        }
        Ok(())
    }
}

/// All problems found while loading a pipeline.
#[derive(Debug, Clone, Default)]
pub struct Diagnostics(pub Vec<Diagnostic>);

impl Diagnostics {
    /// Add one problem.
    pub fn push(
        &mut self,
        file: &Path,
        line: Option<usize>,
        key: impl Into<String>,
        message: impl Into<String>,
        help: impl Into<String>,
    ) {
        self.0.push(Diagnostic {
            file: file.to_path_buf(),
            line,
            key: key.into(),
            message: message.into(),
            help: help.into(),
        });
    }
    /// No problems?
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl fmt::Display for Diagnostics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for d in &self.0 {
            writeln!(f, "{d}")?;
        }
        write!(f, "{} error(s); nothing was run", self.0.len())
    }
}

impl std::error::Error for Diagnostics {}

/// Find the 1-based line of a key path in a YAML text, starting the search at
/// `from_line` (1-based, inclusive). Each path segment must appear as `key:` (or
/// `- key:`) indented deeper than its parent. A best-effort locator for messages: it
/// returns the deepest segment it could find.
pub fn locate(text: &str, path: &[&str], from_line: usize) -> Option<usize> {
    let lines: Vec<&str> = text.lines().collect();
    let mut start = from_line.saturating_sub(1);
    let mut parent_indent: Option<usize> = None;
    let mut found = None;
    for seg in path {
        let mut hit = None;
        for (i, raw) in lines.iter().enumerate().skip(start) {
            let trimmed = raw.trim_start();
            if trimmed.is_empty() || trimmed.starts_with('#') {
                continue;
            }
            let indent = raw.len() - trimmed.len();
            if let Some(p) = parent_indent
                && indent <= p
                && i > start
                && !trimmed.starts_with("- ")
            {
                break; // left the parent block
            }
            let body = trimmed.strip_prefix("- ").unwrap_or(trimmed);
            let key = body
                .split(':')
                .next()
                .unwrap_or("")
                .trim()
                .trim_matches('"')
                .trim_matches('\'');
            if key == *seg && body.contains(':') {
                hit = Some((i, indent));
                break;
            }
        }
        match hit {
            Some((i, ind)) => {
                found = Some(i + 1);
                start = i + 1;
                parent_indent = Some(ind);
            }
            None => break,
        }
    }
    found
}

/// Line of the pipeline stage entry with the given id (`id: X` or `- id: X`).
pub fn locate_stage(text: &str, id: &str) -> Option<usize> {
    for (i, raw) in text.lines().enumerate() {
        let t = raw.trim_start();
        let t = t.strip_prefix("- ").unwrap_or(t).trim_start();
        if let Some(rest) = t.strip_prefix("id:") {
            let v = rest
                .split('#')
                .next()
                .unwrap_or("")
                .trim()
                .trim_matches('"')
                .trim_matches('\'');
            if v == id {
                return Some(i + 1);
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn locates_nested_keys() {
        let text = "stages:\n  - id: a\n    kind: psd\n    params:\n      n: 3\n  - id: b\n    params:\n      n: 4\n";
        assert_eq!(locate_stage(text, "b"), Some(6));
        assert_eq!(locate(text, &["params", "n"], 6), Some(8));
        assert_eq!(locate(text, &["params", "n"], 2), Some(5));
        assert_eq!(locate(text, &["kind"], 2), Some(3));
    }
}
