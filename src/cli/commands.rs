//! The pipeline commands beyond `run`: `plan` (with `--estimate`), `plan --timings`,
//! `export snakemake` and `clean`.

use std::path::Path;

use super::args::ProfileArg;
use crate::pipeline::load;
use crate::pipeline::run::Project;

/// `plan`: the stages in order with keys (text or JSON), or the paper budget.
pub(super) fn plan_cmd(
    pipeline: &Path,
    proj: &Project,
    stages: &[String],
    profile: ProfileArg,
    json: bool,
    estimate: bool,
) -> i32 {
    let Some(p) = load_or_report(pipeline, profile) else {
        return 2;
    };
    if estimate {
        return match crate::pipeline::estimate::estimate(&p, proj, stages) {
            Ok(e) => {
                if json {
                    println!("{}", serde_json::to_string_pretty(&e.to_json()).unwrap_or_default());
                } else {
                    print!("{}", e.to_text());
                }
                0
            }
            Err(m) => {
                eprintln!("error: {m}");
                2
            }
        };
    }
    match crate::pipeline::plan::plan(&p, proj, stages) {
        Ok(st) => {
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&crate::pipeline::plan::to_json(&p, proj, &st)).unwrap_or_default()
                );
            } else {
                print!("{}", crate::pipeline::plan::to_text(&st));
            }
            0
        }
        Err(e) => {
            eprintln!("error: {e}");
            2
        }
    }
}

/// `plan --timings`: the run records of the plan's stages (see `pipeline::timings`).
pub(super) fn timings_cmd(
    pipeline: &Path,
    proj: &Project,
    stages: &[String],
    profile: ProfileArg,
    json: bool,
    min_wall: f64,
) -> i32 {
    let Some(p) = load_or_report(pipeline, profile) else {
        return 2;
    };
    if !(min_wall.is_finite() && min_wall >= 0.0) {
        eprintln!("error: --min-wall {min_wall}: expected seconds ≥ 0");
        return 2;
    }
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    match crate::pipeline::timings::timings(&p, proj, stages) {
        Ok(t) => {
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&t.to_json(cores)).unwrap_or_default()
                );
            } else {
                print!("{}", t.to_text(cores, min_wall));
            }
            0
        }
        Err(e) => {
            eprintln!("error: {e}");
            2
        }
    }
}

/// `export snakemake`: the Snakefile of the plan on stdout.
#[allow(clippy::too_many_arguments)]
pub(super) fn export_snakemake(
    pipeline: &Path,
    proj: &Project,
    cache: Option<&Path>,
    stages: &[String],
    profile: ProfileArg,
    bin: Option<String>,
    threads: usize,
    mem_mb: u64,
) -> i32 {
    use crate::pipeline::export::{ExportOptions, measured_from_record, snakefile};
    let Some(p) = load_or_report(pipeline, profile) else {
        return 2;
    };
    let plan = match crate::pipeline::plan::plan(&p, proj, stages) {
        Ok(st) => st,
        Err(e) => {
            eprintln!("error: {e}");
            return 2;
        }
    };
    let abs = |q: &Path| {
        std::fs::canonicalize(q)
            .or_else(|_| std::path::absolute(q))
            .unwrap_or_else(|_| q.to_path_buf())
    };
    let bin = match bin {
        Some(b) => b,
        None => match std::env::current_exe() {
            Ok(b) => abs(&b).display().to_string(),
            Err(_) => "granrepro".into(),
        },
    };
    // Wall times: this profile's run records, else (for the paper profile) the budget's
    // estimate scaled from the quick records.
    let estimated = if profile == ProfileArg::Paper {
        crate::pipeline::estimate::estimate(&p, proj, stages).ok()
    } else {
        None
    };
    let mut measured = std::collections::BTreeMap::new();
    for s in &plan {
        let m = measured_from_record(&proj.report_dir(&p.profile), &s.id)
            .or_else(|| estimated.as_ref().and_then(|e| e.measured(&s.id)));
        if let Some(m) = m {
            measured.insert(s.id.clone(), m);
        }
    }
    let o = ExportOptions {
        profile: p.profile.clone(),
        bin,
        pipeline: abs(pipeline),
        root: abs(&proj.root),
        cache: cache.map(Path::to_path_buf),
        threads,
        mem_mb,
        peak_mb: plan
            .iter()
            .filter_map(|s| {
                Some((
                    s.id.clone(),
                    crate::pipeline::export::peak_from_markers(
                        &proj.root.join(crate::pipeline::export::marker_dir(&p.profile)),
                        &s.id,
                    )?,
                ))
            })
            .collect(),
        default_runtime_min: 720,
        measured,
    };
    print!("{}", snakefile(&plan, &o));
    0
}

/// `clean`: only in the project of an existing pipeline file; only what granrepro made.
pub(super) fn clean(pipeline: &Path, proj: &Project, reports: bool, profile: Option<&str>) -> i32 {
    if !pipeline.is_file() {
        eprintln!(
            "error: {}: no such pipeline file; nothing removed\n  help: `clean` works in the project of an existing pipeline file: pass --pipeline PATH or run from its directory",
            pipeline.display()
        );
        return 2;
    }
    let profiles: Vec<&str> = match profile {
        Some(p) => vec![p],
        None => crate::pipeline::spec::PROFILES.to_vec(),
    };
    let mut code = 0;
    match crate::pipeline::clean::clean_state(proj, profile) {
        Ok(msgs) => msgs.iter().for_each(|m| println!("{m}")),
        Err(e) => {
            eprintln!("error: {e}");
            code = 1;
        }
    }
    if reports {
        for p in &profiles {
            let dir = proj.report_dir(p);
            match crate::pipeline::publish::clean_reports(&dir) {
                Ok(r) if r.is_empty() => {}
                Ok(r) => println!(
                    "removed {} published file(s) of profile `{p}` in {}",
                    r.len(),
                    dir.display()
                ),
                Err(e) => {
                    eprintln!("error: {e}");
                    code = 1;
                }
            }
            if let Ok(rd) = std::fs::read_dir(&dir) {
                let left: Vec<String> = rd
                    .flatten()
                    .map(|e| e.file_name().to_string_lossy().to_string())
                    .collect();
                if !left.is_empty() {
                    println!(
                        "kept {} file(s) in {} that granrepro did not publish: {}",
                        left.len(),
                        dir.display(),
                        left.join(", ")
                    );
                }
            }
        }
        if profile.is_none()
            && std::fs::read_dir(&proj.reports).is_ok_and(|mut r| r.next().is_none())
            && std::fs::remove_dir(&proj.reports).is_ok()
        {
            println!("removed the empty {}", proj.reports.display());
        }
    }
    code
}

/// The pipeline of `profile`, or its diagnostics printed (the caller exits 2).
fn load_or_report(pipeline: &Path, profile: ProfileArg) -> Option<crate::pipeline::Pipeline> {
    load(pipeline, profile.name(), &[]).map_err(|d| eprintln!("{d}")).ok()
}

/// `granrepro claims`: the ledger judged on `dir`'s published results, one line per row.
pub(crate) fn print_claims(p: &crate::pipeline::Pipeline, dir: &std::path::Path) -> i32 {
    use crate::report::ledger::n4;
    let Some(judged) = crate::claims::evaluate_dir(p, dir) else {
        eprintln!(
            "error: {}: no claims ledger\n  help: the ledger is stages/ledger.yaml beside pipeline.yaml",
            p.root.display()
        );
        return 2;
    };
    for j in &judged {
        let ours = crate::report::ledger::ours_text(j);
        println!(
            "{:<34} {:<12} paper {:<10} ours {:<28} {}{}{}",
            j.id,
            j.kind,
            n4(j.paper),
            ours,
            j.verdict.name(),
            if j.calibrated.is_empty() { "" } else { " (calibrated)" },
            if j.not_comparable_here() {
                " [not comparable with the chapter at this size]"
            } else {
                ""
            }
        );
    }
    let c = crate::claims::judge::counts(&judged);
    for ((k, v), n) in c {
        println!("  {} {}: {n}", k.name(), v.name());
    }
    0
}

/// `status`, second part: the committed results of the profile (`results/<profile>/` and
/// the studies kept for it), when there are any. Exit 1 when a committed file does not
/// match its lock.
/// `status --if-changed PATH…`: what a change under the paths would cost each committed
/// results directory (`crate::pipeline::store::impact`).
pub(crate) fn print_impact(p: &crate::pipeline::Pipeline, paths: &[String]) -> i32 {
    use crate::pipeline::store::{self, impact};
    let dirs = match store::committed_dirs(p) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("error: {e:#}");
            return 2;
        }
    };
    let readers = crate::pipeline::dag::readers(p);
    if dirs.is_empty() {
        println!("no committed results for profile {}", p.profile);
    }
    for (dir, lock) in &dirs {
        println!("committed results ({}):", dir.display());
        let i = impact::impact(&impact::committed(lock), &readers, paths);
        print!("{}", i.to_text(&p.profile, paths));
    }
    0
}

pub(crate) fn print_committed(p: &crate::pipeline::Pipeline) -> i32 {
    use crate::pipeline::store::{self, Committed};
    let dirs = match store::committed_dirs(p) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("error: {e:#}");
            return 2;
        }
    };
    let mut corrupt = false;
    for (dir, lock) in &dirs {
        println!("committed results ({}):", dir.display());
        let states = store::status(p, dir, lock);
        for (id, st) in &states {
            match st {
                Committed::Fresh => println!("  fresh    {id}"),
                Committed::Stale(r) => println!("  stale    {id}: {}", r.join("; ")),
                Committed::ChangedCode(r) => println!("  code     {id}: built from changed code: {}", r.join(", ")),
                Committed::Corrupt(r) => {
                    corrupt = true;
                    println!("  CORRUPT  {id}: {}", r.join("; "));
                }
            }
        }
        let gone: Vec<&String> = lock.stages.keys().filter(|id| p.get(id).is_none()).collect();
        for id in gone {
            println!("  removed  {id}: no longer in the pipeline");
        }
    }
    if corrupt {
        eprintln!(
            "error: committed results do not match their lock (hand-edited or corrupted)\n  help: restore them from version control, or re-run the stages and `granrepro keep`"
        );
        1
    } else {
        0
    }
}

/// `keep`: write `results/<profile>/` (or `results/<study>/`) from the cache.
pub(super) fn keep(p: &crate::pipeline::Pipeline, proj: &Project, max_file_mb: f64, study: Option<&str>) -> i32 {
    if !(max_file_mb > 0.0) {
        eprintln!("error: --max-file-mb {max_file_mb}: must be a positive size in MB\n  help: e.g. --max-file-mb 2");
        return 2;
    }
    let caps = crate::pipeline::store::Caps {
        file: (max_file_mb * 1048576.0) as u64,
        ..Default::default()
    };
    let dir = match crate::pipeline::store::keep_dir(p, study) {
        Ok((d, _)) => d,
        Err(e) => {
            eprintln!("error: keep --stage: {e:#}");
            return 2;
        }
    };
    match crate::pipeline::store::keep(p, proj, caps, study) {
        Ok(k) => {
            println!(
                "kept {} stage(s) from the cache, carried {} committed, {} with nothing to keep; {:.1} MB in {}",
                k.kept.len(),
                k.carried.len(),
                k.missing.len(),
                k.bytes as f64 / 1048576.0,
                dir.display()
            );
            if !k.widened.is_empty() {
                println!(
                    "  source closure widened to this build's for {} carried stage(s): the files it adds are unchanged (git) since their runs",
                    k.widened.len()
                );
            }
            if !k.not_current.is_empty() {
                println!(
                    "  carried but not current (shown marked, judged as not run; `granrepro status --profile {}`): {}",
                    p.profile,
                    k.not_current.join(", ")
                );
            }
            for (id, f, n, c) in &k.compacted {
                println!(
                    "  compact {id}: {f} ({:.1} MB) published as its compact form ({:.1} MB: one path per marker size and colour); `granrepro run --profile {} --stage {id}` regenerates the original",
                    *n as f64 / 1048576.0,
                    *c as f64 / 1048576.0,
                    p.profile
                );
            }
            for (id, f, n) in &k.left_out {
                println!(
                    "  left out {id}: {f} ({:.1} MB; `granrepro run --profile {} --stage {id}` regenerates it)",
                    *n as f64 / 1048576.0,
                    p.profile
                );
            }
            0
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            1
        }
    }
}
