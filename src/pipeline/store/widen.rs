//! A result's recorded source closure when the closure rule has grown since it was built.
//!
//! The lock records, per kept stage, the files its kind was built from
//! (`crate::provenance::sources::closure`). When the rule that computes a closure finds more
//! files than it used to (it learnt to follow `impl` blocks, say), a result kept earlier lists
//! fewer files than this build computes, and `status` would call it "built from changed
//! code" although no file changed. The added files' contents at build time were never
//! recorded; git knows them. A recorded closure is widened to this build's when:
//! - every file it records has the hash this build has (nothing recorded has changed), and
//! - no commit since the run started touched any added file, and the work tree has none of
//!   them modified (`git log --since`, `git status --porcelain`).
//!
//! Otherwise (a file changed, no git, not a repository) the recorded closure stays, and
//! `status` says what differs: never fresher than the evidence.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

/// This build's closure `now` for a result recorded with `recorded`, run at `started_unix_s`
/// in the repository at `root`, when the difference is files added to the rule and git shows
/// them unchanged since; None otherwise.
pub fn widened(
    root: &Path,
    recorded: &BTreeMap<String, String>,
    now: &BTreeMap<String, String>,
    started_unix_s: Option<f64>,
) -> Option<BTreeMap<String, String>> {
    let added = only_added(recorded, now)?;
    let since = started_unix_s.filter(|t| t.is_finite() && *t > 0.0)?;
    unchanged_since(root, &added, since).then(|| now.clone())
}

/// The files `now` holds and `recorded` does not, when every recorded file has its hash in
/// `now` and there is at least one; None otherwise.
pub fn only_added(recorded: &BTreeMap<String, String>, now: &BTreeMap<String, String>) -> Option<Vec<String>> {
    if recorded.is_empty() || recorded.iter().any(|(p, h)| now.get(p) != Some(h)) {
        return None;
    }
    let added: Vec<String> = now.keys().filter(|p| !recorded.contains_key(*p)).cloned().collect();
    (!added.is_empty()).then_some(added)
}

/// Did no commit after `since` (Unix seconds) touch `files`, and does the work tree hold
/// them as committed? False when git cannot tell.
fn unchanged_since(root: &Path, files: &[String], since: f64) -> bool {
    // Paths from the package root, as git takes them (the closure's `Cargo.lock` entry is
    // the file's own path).
    let all: Vec<&str> = files.iter().map(String::as_str).collect();
    let git = |args: &[&str]| -> Option<String> {
        let out = Command::new("git").arg("-C").arg(root).args(args).output().ok()?;
        out.status
            .success()
            .then(|| String::from_utf8_lossy(&out.stdout).into_owned())
    };
    let since_arg = format!("--since=@{}", since.floor() as i64);
    let mut log = vec!["log", "--format=%H", since_arg.as_str(), "--"];
    log.extend(&all);
    let mut st = vec!["status", "--porcelain", "--"];
    st.extend(&all);
    matches!((git(&log), git(&st)), (Some(l), Some(s)) if l.trim().is_empty() && s.trim().is_empty())
}

#[cfg(test)]
mod tests {
    use super::{only_added, widened};
    use std::collections::BTreeMap;
    use std::path::Path;
    use std::process::Command;

    /// git in `dir` with a fixed identity and both dates at `unix_s`.
    fn git(dir: &Path, unix_s: i64, args: &[&str]) {
        let date = format!("@{unix_s} +0000");
        let ok = Command::new("git")
            .arg("-C")
            .arg(dir)
            .args([
                "-c", "user.name=t", "-c", "user.email=t@example.org", "-c", "commit.gpgsign=false",
            ])
            .args(args)
            .env("GIT_AUTHOR_DATE", &date)
            .env("GIT_COMMITTER_DATE", &date)
            .output()
            .expect("git runs")
            .status
            .success();
        assert!(ok, "git {args:?}");
    }

    /// A scratch repository: `src/a.rs` (recorded) and `src/c.rs` (added to the rule later),
    /// both committed at t = 1.0e9 s; the run started at 1.5e9 s.
    #[test]
    fn git_decides_whether_the_added_files_are_untouched_since_the_run() {
        let dir = std::env::temp_dir().join(format!("granrepro-widen-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("src")).unwrap();
        std::fs::write(dir.join("src/a.rs"), "// a\n").unwrap();
        std::fs::write(dir.join("src/c.rs"), "// c\n").unwrap();
        git(&dir, 1_000_000_000, &["init", "-q"]);
        git(&dir, 1_000_000_000, &["add", "."]);
        git(&dir, 1_000_000_000, &["commit", "-q", "-m", "one"]);
        let rec = m(&[("src/a.rs", "1")]);
        let now = m(&[("src/a.rs", "1"), ("src/c.rs", "3")]);
        let started = Some(1.5e9);
        assert_eq!(
            widened(&dir, &rec, &now, started),
            Some(now.clone()),
            "untouched since the run"
        );
        // no start time on record: no evidence
        assert_eq!(widened(&dir, &rec, &now, None), None);
        // the added file edited in the work tree
        std::fs::write(dir.join("src/c.rs"), "// c, edited\n").unwrap();
        assert_eq!(widened(&dir, &rec, &now, started), None, "modified in the work tree");
        // ... and committed after the run started
        git(&dir, 1_600_000_000, &["commit", "-q", "-am", "two"]);
        assert_eq!(widened(&dir, &rec, &now, started), None, "committed after the run");
        // a run that started after that commit: untouched since
        assert_eq!(widened(&dir, &rec, &now, Some(1.7e9)), Some(now.clone()));
        // not a repository: git cannot tell
        std::fs::remove_dir_all(dir.join(".git")).unwrap();
        assert_eq!(widened(&dir, &rec, &now, Some(1.7e9)), None, "no repository");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn m(v: &[(&str, &str)]) -> BTreeMap<String, String> {
        v.iter().map(|(a, b)| (a.to_string(), b.to_string())).collect()
    }

    #[test]
    fn only_a_pure_addition_is_a_widening() {
        let rec = m(&[("src/a.rs", "1"), ("src/b.rs", "2")]);
        assert_eq!(
            only_added(&rec, &m(&[("src/a.rs", "1"), ("src/b.rs", "2"), ("src/c.rs", "3")])),
            Some(vec!["src/c.rs".to_string()])
        );
        // a recorded file changed: not a widening, whatever was added
        assert_eq!(
            only_added(&rec, &m(&[("src/a.rs", "1"), ("src/b.rs", "9"), ("src/c.rs", "3")])),
            None
        );
        // a recorded file gone: not a widening
        assert_eq!(only_added(&rec, &m(&[("src/a.rs", "1"), ("src/c.rs", "3")])), None);
        // nothing added: nothing to widen
        assert_eq!(only_added(&rec, &rec), None);
        assert_eq!(only_added(&m(&[]), &rec), None);
    }
}
