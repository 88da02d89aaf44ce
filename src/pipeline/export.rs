//! `granrepro export snakemake`: the stage graph as a Snakefile, so Snakemake's executors
//! (local, Slurm through `snakemake-executor-plugin-slurm`, others) spread the stages over
//! machines. granrepro stays the only definition of the work: each rule runs one stage
//! with `granrepro run --only ID`, which reads its inputs from and writes its entry to the
//! content-addressed cache — shared by every worker (`--cache DIR` or `GRANREPRO_CACHE`,
//! on a shared filesystem), never copied around by the workflow.
//!
//! **Files Snakemake sees**: one marker per stage, `.granrepro/markers/<profile>/<id>.<key>.done`,
//! written atomically by `run --markers DIR` once the stage's cache entry is in place (ran
//! or found cached). A rule's inputs are its input stages' markers, its output its own.
//! The key is in the name, so a changed stage (parameters, solver version, an input
//! upstream) is a marker Snakemake does not have: it runs that stage and its dependants
//! and nothing else. The Snakefile holds the keys it was exported with: re-export after
//! editing the pipeline (a worker whose key differs writes a marker under its own key and
//! Snakemake stops with the missing output, rather than mixing two versions).
//!
//! **Threads and resources**: from the stage's run record (`reports/<profile>/<id>.record.json`)
//! when there is one, else from the caller's estimate (the paper budget, see
//! [`super::estimate`]), else stated defaults ([`ExportOptions`]). Run records hold no
//! memory figure; markers do (the worker's peak resident memory), so memory requests
//! come from an earlier worker's markers, else the default.

use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};

use super::fsio::write_atomic;
use super::plan::Planned;
use super::run::{Outcome, RunSummary};

/// How long and on how many threads a stage ran (or is estimated to run).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    /// Wall time [s].
    pub wall_s: f64,
    /// Threads it ran on.
    pub threads: usize,
}

/// Export settings.
#[derive(Debug, Clone)]
pub struct ExportOptions {
    /// Profile the rules run.
    pub profile: String,
    /// The granrepro the workers run (absolute path, or a name on their PATH).
    pub bin: String,
    /// Pipeline file (absolute).
    pub pipeline: PathBuf,
    /// Project directory (absolute): Snakemake's working directory.
    pub root: PathBuf,
    /// Shared cache directory baked into the rules (absolute), when one was given.
    pub cache: Option<PathBuf>,
    /// Threads of a stage without a record, and the cap for stages that have one.
    pub threads: usize,
    /// Memory request [MB] of a stage whose peak is not known.
    pub mem_mb: u64,
    /// Peak memory [MB] of each stage measured by an earlier worker (its markers).
    pub peak_mb: BTreeMap<String, f64>,
    /// Runtime request [min] of a stage with neither a record nor an estimate.
    pub default_runtime_min: u64,
    /// Measured or estimated wall time of each stage.
    pub measured: BTreeMap<String, Measured>,
}

/// Stages that ran under this many seconds get one thread (they are bookkeeping: a
/// table, a figure, a sampled PSD).
pub const CHEAP_S: f64 = 1.0;

/// Marker directory of a profile, relative to the project directory.
pub fn marker_dir(profile: &str) -> PathBuf {
    Path::new(".granrepro").join("markers").join(profile)
}

/// File name of a stage's marker.
pub fn marker_name(id: &str, key: &str) -> String {
    format!("{id}.{key}.done")
}

/// After a run: one marker per stage whose cache entry is in place (ran or cached),
/// written atomically into `dir`.
pub fn write_markers(dir: &Path, profile: &str, summary: &RunSummary) -> std::io::Result<usize> {
    let mut n = 0;
    for s in &summary.stages {
        if matches!(s.outcome, Outcome::Ran { .. } | Outcome::Cached) {
            let body =
                serde_json::json!({ "stage": s.id, "key": s.key, "profile": profile, "peak_rss_mb": peak_rss_mb() });
            write_atomic(&dir.join(marker_name(&s.id, &s.key)), format!("{body}\n").as_bytes())?;
            n += 1;
        }
    }
    Ok(n)
}

/// Peak resident memory of this process so far [MB] (Linux `VmHWM`; None elsewhere). A
/// workflow job runs one stage per process, so this is that stage's peak.
pub fn peak_rss_mb() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let kb: f64 = s
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kb / 1024.0)
}

/// The largest peak memory [MB] recorded in the markers of stage `id` (any key) in `dir`.
pub fn peak_from_markers(dir: &Path, id: &str) -> Option<f64> {
    let prefix = format!("{id}.");
    std::fs::read_dir(dir)
        .ok()?
        .flatten()
        .filter(|e| {
            e.file_name()
                .to_string_lossy()
                .strip_prefix(&prefix)
                .is_some_and(|rest| rest.len() == 32 + ".done".len() && rest.ends_with(".done"))
        })
        .filter_map(|e| {
            serde_json::from_slice::<serde_json::Value>(&std::fs::read(e.path()).ok()?)
                .ok()?
                .get("peak_rss_mb")?
                .as_f64()
        })
        .reduce(f64::max)
}

/// The run record of a stage under `reports/<profile>/`, when there is one.
pub fn measured_from_record(report_dir: &Path, id: &str) -> Option<Measured> {
    measured_from_record_file(&report_dir.join(format!("{id}.record.json")))
}

/// Wall time and threads of a run record file.
pub fn measured_from_record_file(path: &Path) -> Option<Measured> {
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(path).ok()?).ok()?;
    Some(Measured {
        wall_s: v.get("wall_s")?.as_f64()?,
        threads: v.get("threads").and_then(|t| t.as_u64()).unwrap_or(1).max(1) as usize,
    })
}

/// Single-quote for the shell.
fn sh(s: &str) -> String {
    format!("'{}'", s.replace('\'', "'\\''"))
}

/// A Python string literal (double quotes; Snakemake formats `{…}` in shell strings, so
/// braces in paths are doubled by the caller where needed).
fn py(s: &str) -> String {
    format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""))
}

/// Rule names must be Python identifiers and unique.
fn rule_names(stages: &[Planned]) -> Vec<String> {
    let mut seen = HashSet::new();
    stages
        .iter()
        .map(|s| {
            let base: String = format!(
                "stage_{}",
                s.id.chars()
                    .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
                    .collect::<String>()
            );
            let mut name = base.clone();
            let mut i = 2;
            while !seen.insert(name.clone()) {
                name = format!("{base}_{i}");
                i += 1;
            }
            name
        })
        .collect()
}

/// The Snakefile of `stages` (a plan: inputs first).
pub fn snakefile(stages: &[Planned], o: &ExportOptions) -> String {
    let md = marker_dir(&o.profile);
    let marker = |s: &Planned| md.join(marker_name(&s.id, &s.key)).display().to_string();
    let names = rule_names(stages);
    let by_id: BTreeMap<&str, &Planned> = stages.iter().map(|s| (s.id.as_str(), s)).collect();
    let mut f = String::new();
    f.push_str(&format!(
        "# Generated by `granrepro export snakemake --profile {}` from {} — do not edit;\n\
         # re-export after changing the pipeline (the cache keys below are this version's).\n\
         # One rule per stage: `granrepro run --only ID` reads its inputs from the shared\n\
         # content-addressed cache and writes its entry there; the marker\n\
         # {}/<id>.<key>.done lands after the entry. Run: snakemake -j N\n\
         # (Slurm: snakemake --executor slurm -j N, with snakemake-executor-plugin-slurm).\n\
         # Then `granrepro run --profile {}` anywhere assembles reports/ from the cache.\n\n",
        o.profile,
        o.pipeline.display(),
        md.display(),
        o.profile
    ));
    f.push_str(&format!("workdir: {}\n\n", py(&o.root.display().to_string())));
    f.push_str("localrules: all\n\n");
    f.push_str("rule all:\n    default_target: True\n    input:\n");
    for s in stages {
        f.push_str(&format!("        {},\n", py(&marker(s))));
    }
    f.push('\n');
    let mut cmd_head = format!("{} --pipeline {}", sh(&o.bin), sh(&o.pipeline.display().to_string()));
    if let Some(c) = &o.cache {
        cmd_head.push_str(&format!(" --cache {}", sh(&c.display().to_string())));
    }
    for (s, name) in stages.iter().zip(&names) {
        let m = o.measured.get(&s.id);
        let threads = match m {
            Some(m) if m.wall_s < CHEAP_S => 1,
            Some(m) => m.threads.min(o.threads).max(1),
            None => o.threads.max(1),
        };
        // Requested time: twice the measured (or estimated) wall at that many threads,
        // plus 10 minutes for start-up and a loaded node.
        let runtime = match m {
            Some(m) => (2.0 * m.wall_s * m.threads as f64 / threads as f64 / 60.0).ceil() as u64 + 10,
            None => o.default_runtime_min,
        };
        f.push_str(&format!("rule {name}:\n"));
        let ins: Vec<String> = s
            .inputs
            .iter()
            .filter_map(|i| by_id.get(i.as_str()))
            .map(|d| py(&marker(d)))
            .collect();
        if !ins.is_empty() {
            f.push_str("    input:\n");
            for i in ins {
                f.push_str(&format!("        {i},\n"));
            }
        }
        f.push_str(&format!("    output:\n        {},\n", py(&marker(s))));
        f.push_str(&format!("    threads: {threads}\n"));
        // Memory: twice the peak an earlier worker measured, at least 1000 MB.
        let mem_mb = o
            .peak_mb
            .get(&s.id)
            .map(|p| ((2.0 * p).ceil() as u64).max(1000))
            .unwrap_or(o.mem_mb);
        f.push_str(&format!(
            "    resources:\n        runtime={runtime},\n        mem_mb={mem_mb},\n"
        ));
        let cmd = format!(
            "RAYON_NUM_THREADS={{threads}} {} run --only {} --profile {} --quiet --markers {}",
            cmd_head.replace('{', "{{").replace('}', "}}"),
            sh(&s.id),
            sh(&o.profile),
            sh(&md.display().to_string())
        );
        f.push_str(&format!("    shell:\n        {}\n\n", py(&cmd)));
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    fn st(id: &str, key: &str, inputs: &[&str]) -> Planned {
        Planned {
            id: id.into(),
            kind: "psd".into(),
            key: key.into(),
            inputs: inputs.iter().map(|s| s.to_string()).collect(),
            cached: false,
            why: None,
        }
    }

    #[test]
    fn rules_chain_markers_and_take_resources_from_records() {
        let mut measured = BTreeMap::new();
        measured.insert(
            "b".to_string(),
            Measured {
                wall_s: 600.0,
                threads: 2,
            },
        );
        measured.insert(
            "a".to_string(),
            Measured {
                wall_s: 0.01,
                threads: 2,
            },
        );
        let o = ExportOptions {
            profile: "quick".into(),
            bin: "/opt/granrepro".into(),
            pipeline: "/p/pipeline.yaml".into(),
            root: "/p".into(),
            cache: Some("/shared/cache".into()),
            threads: 4,
            mem_mb: 2000,
            peak_mb: [("b".to_string(), 700.2)].into_iter().collect(),
            default_runtime_min: 720,
            measured,
        };
        let s = snakefile(
            &[st("a", "k1", &[]), st("b", "k2", &["a"]), st("c-1", "k3", &["a", "b"])],
            &o,
        );
        assert!(s.contains("rule stage_b:\n    input:\n        \".granrepro/markers/quick/a.k1.done\",\n    output:\n        \".granrepro/markers/quick/b.k2.done\",\n    threads: 2\n"), "{s}");
        // a cheap stage gets one thread; b: 2 × 600 s → 20 min + 10.
        assert!(s.contains("rule stage_a:\n    output:\n        \".granrepro/markers/quick/a.k1.done\",\n    threads: 1\n    resources:\n        runtime=11,"), "{s}");
        assert!(s.contains("runtime=30,\n        mem_mb=1401,"), "{s}");
        assert!(s.contains("runtime=11,\n        mem_mb=2000,"), "{s}");
        // no record: the stated defaults.
        assert!(
            s.contains("rule stage_c_1:") && s.contains("    threads: 4\n    resources:\n        runtime=720,"),
            "{s}"
        );
        assert!(s.contains("--cache '/shared/cache' run --only 'c-1' --profile 'quick' --quiet --markers '.granrepro/markers/quick'"), "{s}");
    }

    #[test]
    fn markers_only_for_stages_whose_entry_is_in_place() {
        use crate::pipeline::run::StageReport;
        let dir = tempfile::tempdir().unwrap();
        let summary = RunSummary {
            stages: vec![
                StageReport {
                    id: "a".into(),
                    key: "0123456789abcdef0123456789abcdef".into(),
                    outcome: Outcome::Cached,
                },
                StageReport {
                    id: "b".into(),
                    key: "k2".into(),
                    outcome: Outcome::Ran { wall_s: 1.0 },
                },
                StageReport {
                    id: "c".into(),
                    key: "k3".into(),
                    outcome: Outcome::Failed("x".into()),
                },
            ],
        };
        assert_eq!(write_markers(dir.path(), "quick", &summary).unwrap(), 2);
        assert!(
            dir.path().join("a.0123456789abcdef0123456789abcdef.done").is_file()
                && dir.path().join("b.k2.done").is_file()
        );
        assert!(!dir.path().join("c.k3.done").exists());
        if cfg!(target_os = "linux") {
            let peak = peak_from_markers(dir.path(), "a");
            assert!(peak.is_some_and(|p| p > 1.0), "{peak:?}");
        }
    }
}
