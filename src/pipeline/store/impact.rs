//! `granrepro status --profile P --if-changed PATH`: what a code change would cost the
//! committed results, before it is made.
//!
//! A committed result records the source files its kind is built from (its closure, in
//! the lock). A change to any of them marks the result "built from changed code" until
//! the stage re-runs (`status`), and the stages that read it may then change too. This
//! answers, from the lock alone: which committed stages have a file under PATH in their
//! closure (*built from it*), which stages downstream read them (*downstream*: they re-run
//! if the re-run changes what they read; a bit-identical change leaves them as they are),
//! and the wall time each group took when it ran (`wall_s` of the lock: the measured cost of
//! a re-run, at the thread counts the runs had).

use std::collections::{BTreeMap, BTreeSet, VecDeque};

use super::Lock;

/// A committed stage as the impact sees it: the files of its source closure and the wall
/// time [s] it ran.
pub type Built = (BTreeSet<String>, Option<f64>);

/// The committed stages of a lock (closures resolved, as [`super::read_lock`] returns them).
pub fn committed(lock: &Lock) -> BTreeMap<String, Built> {
    lock.stages
        .iter()
        .map(|(id, l)| (id.clone(), (l.sources.keys().cloned().collect(), l.wall_s)))
        .collect()
}

/// The committed stages a change under some paths touches.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Impact {
    /// Stages whose closure holds a changed file, with the files (sorted).
    pub built_from: BTreeMap<String, Vec<String>>,
    /// Committed stages downstream of those (reading them, directly or not), not in
    /// `built_from`.
    pub downstream: BTreeSet<String>,
    /// Wall time [s] of the stages built from the change, as they ran (a stage without a
    /// recorded wall counts 0).
    pub built_from_wall_s: f64,
    /// Wall time [s] of the downstream stages, as they ran.
    pub downstream_wall_s: f64,
}

/// Does `file` (a closure path, e.g. `src/mpm/solver.rs`) lie under `path` (a file or a
/// directory, `./` and a trailing `/` ignored)?
fn under(file: &str, path: &str) -> bool {
    let p = path.trim_start_matches("./").trim_end_matches('/');
    !p.is_empty() && (file == p || file.strip_prefix(p).is_some_and(|rest| rest.starts_with('/')))
}

/// The impact of changing `paths` on the `stages` committed ([`committed`]); `readers`
/// maps a stage id to the ids that read it.
pub fn impact(stages: &BTreeMap<String, Built>, readers: &BTreeMap<String, Vec<String>>, paths: &[String]) -> Impact {
    let mut out = Impact::default();
    for (id, (sources, wall)) in stages {
        let files: Vec<String> = sources
            .iter()
            .filter(|f| paths.iter().any(|p| under(f, p)))
            .cloned()
            .collect();
        if !files.is_empty() {
            out.built_from_wall_s += wall.unwrap_or(0.0);
            out.built_from.insert(id.clone(), files);
        }
    }
    let mut queue: VecDeque<&String> = out.built_from.keys().collect();
    let mut seen: BTreeSet<String> = out.built_from.keys().cloned().collect();
    while let Some(id) = queue.pop_front() {
        for r in readers.get(id).into_iter().flatten() {
            if seen.insert(r.clone()) {
                queue.push_back(r);
                if let Some((_, wall)) = stages.get(r) {
                    out.downstream_wall_s += wall.unwrap_or(0.0);
                    out.downstream.insert(r.clone());
                }
            }
        }
    }
    out
}

impl Impact {
    /// The report `status --if-changed` prints.
    pub fn to_text(&self, profile: &str, paths: &[String]) -> String {
        let h = |s: f64| s / 3600.0;
        let mut s = format!(
            "if {} changed: {} committed {profile} result(s) would be built from changed code ({:.1} h of runs as measured), and {} downstream of them would re-run if their inputs change ({:.1} h)\n",
            paths.join(", "),
            self.built_from.len(),
            h(self.built_from_wall_s),
            self.downstream.len(),
            h(self.downstream_wall_s),
        );
        // group the stages by the files that touch them: one line per set of files
        let mut by_files: BTreeMap<&Vec<String>, Vec<&str>> = BTreeMap::new();
        for (id, files) in &self.built_from {
            by_files.entry(files).or_default().push(id);
        }
        for (files, ids) in by_files {
            s.push_str(&format!("  built from {}: {}\n", files.join(", "), ids.join(", ")));
        }
        if !self.downstream.is_empty() {
            let ids: Vec<&str> = self.downstream.iter().map(String::as_str).collect();
            s.push_str(&format!("  downstream: {}\n", ids.join(", ")));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn locked(files: &[&str], wall: f64) -> Built {
        (files.iter().map(|f| f.to_string()).collect(), Some(wall))
    }

    #[test]
    fn a_change_reaches_the_stages_built_from_it_and_those_downstream() {
        let mut lock = BTreeMap::new();
        lock.insert(
            "mpm-run".into(),
            locked(&["src/mpm/solver.rs", "src/analysis/front.rs"], 3600.0),
        );
        lock.insert(
            "dem-run".into(),
            locked(&["src/dem/world.rs", "src/analysis/front.rs"], 7200.0),
        );
        lock.insert("fit".into(), locked(&["src/stages/generic/fit_stage.rs"], 1.0));
        lock.insert("figure".into(), locked(&["src/report/plot.rs"], 2.0));
        let readers: BTreeMap<String, Vec<String>> = [
            ("mpm-run".to_string(), vec!["fit".to_string()]),
            ("fit".to_string(), vec!["figure".to_string()]),
        ]
        .into_iter()
        .collect();
        // a directory: the MPM run, and what reads it, transitively
        let i = impact(&lock, &readers, &["src/mpm/".into()]);
        assert_eq!(i.built_from.keys().collect::<Vec<_>>(), ["mpm-run"]);
        assert_eq!(i.downstream.iter().collect::<Vec<_>>(), ["figure", "fit"]);
        assert_eq!((i.built_from_wall_s, i.downstream_wall_s), (3600.0, 3.0));
        // a shared file: both runs; the reader of one is downstream once
        let i = impact(&lock, &readers, &["./src/analysis/front.rs".into()]);
        assert_eq!(i.built_from.keys().collect::<Vec<_>>(), ["dem-run", "mpm-run"]);
        assert_eq!(i.built_from_wall_s, 10800.0);
        assert!(
            i.to_text("paper", &["src/analysis/front.rs".into()])
                .contains("2 committed paper result(s)")
        );
        // a prefix is a directory, not a string prefix: src/mp is not src/mpm
        assert_eq!(impact(&lock, &readers, &["src/mp".into()]), Impact::default());
        // a stage both built from the change and downstream of another counts once
        let i = impact(&lock, &readers, &["src/mpm".into(), "src/report/plot.rs".into()]);
        assert_eq!(i.built_from.len(), 2);
        assert_eq!(i.downstream.iter().collect::<Vec<_>>(), ["fit"]);
    }
}
