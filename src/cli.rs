//! The command line (thin: parse, call the library, map errors to exit codes).
//! Exit codes: 0 ok, 1 a stage failed, 2 bad input (nothing run).

use std::path::{Path, PathBuf};

use clap::{Parser, Subcommand, ValueEnum};

use crate::pipeline::run::{Freshness, Outcome, Project, RunError, RunOptions, status};
use crate::pipeline::{Override, load};

/// granrepro — regenerate the figures and tables of Kumar (2015), thesis chapter 4.
#[derive(Parser, Debug)]
#[command(name = "granrepro", version, about)]
pub struct Cli {
    /// Pipeline file.
    #[arg(long, global = true, default_value = "pipeline.yaml")]
    pub pipeline: PathBuf,
    /// Command.
    #[command(subcommand)]
    pub cmd: Cmd,
}

/// Profiles.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum ProfileArg {
    /// Minutes on 2 cores (CI, golden snapshots).
    Quick,
    /// The chapter's resolution.
    Paper,
}

impl ProfileArg {
    fn name(self) -> &'static str {
        match self {
            ProfileArg::Quick => "quick",
            ProfileArg::Paper => "paper",
        }
    }
}

/// DAG output formats.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum DagFormat {
    /// Graphviz DOT.
    Dot,
    /// Mermaid flowchart.
    Mermaid,
}

/// Benchmarked engines.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum BenchEngine {
    /// ~3000-grain a = 1 DEM column, table 4.2 parameters.
    Dem,
    /// 40,000-point a = 1 MPM column, 16 PPC, 2 mm cells, Mohr–Coulomb.
    Mpm,
    /// CD deposit of the Siconos reference script (25 × 20 and 40 × 25 disks, h = 2e-3 s).
    Cd,
    /// Per-stage table of the optional terms and outputs each scene enables, and the step
    /// cost of its configuration against everything on (issue 12; README "Stability and cost").
    LeaveOut,
}

/// Subcommands.
#[derive(Subcommand, Debug)]
pub enum Cmd {
    /// Run stages (all, or the named ones and what they need).
    Run {
        /// Target stage (repeatable; a matrix base id means all its members).
        #[arg(long = "stage")]
        stages: Vec<String>,
        /// Run exactly this stage from inputs already in the cache (repeatable).
        #[arg(long)]
        only: Vec<String>,
        /// Profile.
        #[arg(long, value_enum, default_value = "quick")]
        profile: ProfileArg,
        /// Re-run the targets even if cached.
        #[arg(long)]
        force: bool,
        /// Print the plan only.
        #[arg(long)]
        dry_run: bool,
        /// Stages run at once (at least 1).
        #[arg(long, default_value_t = 1, value_parser = parse_jobs)]
        jobs: usize,
        /// Override a parameter: STAGE.KEY=VALUE (part of the cache key).
        #[arg(long = "set")]
        sets: Vec<String>,
        /// No progress bars.
        #[arg(long)]
        quiet: bool,
        /// Print the pre-flight stability table of every planned solver stage, run nothing.
        #[arg(long)]
        explain: bool,
    },
    /// List stages (id, kind, inputs, caption).
    List {
        /// Profile the params are resolved for.
        #[arg(long, value_enum, default_value = "quick")]
        profile: ProfileArg,
        /// List the stage kinds this build knows instead.
        #[arg(long)]
        kinds: bool,
    },
    /// Print a stage's resolved parameters (all layers merged, defaults filled) as YAML.
    Params {
        /// Stage id.
        id: String,
        /// Profile.
        #[arg(long, value_enum, default_value = "quick")]
        profile: ProfileArg,
        /// Override a parameter: STAGE.KEY=VALUE.
        #[arg(long = "set")]
        sets: Vec<String>,
    },
    /// Print the stage graph.
    Dag {
        /// Output format.
        #[arg(long, value_enum, default_value = "dot")]
        format: DagFormat,
    },
    /// Fresh / stale (and why) / missing for every stage.
    Status {
        /// Profile.
        #[arg(long, value_enum, default_value = "quick")]
        profile: ProfileArg,
        /// Override a parameter: STAGE.KEY=VALUE.
        #[arg(long = "set")]
        sets: Vec<String>,
    },
    /// Run one ad-hoc scene outside the pipeline: a DEM column (psd + column + run sections)
    /// or, with `engine: cd`, a CD shear cell or pile; with `engine: mpm`, an MPM column.
    Simulate {
        /// Scene file (YAML; see docs/pipeline.md).
        scene: PathBuf,
        /// Output directory (tables, figures, VTK, its own cache).
        #[arg(long)]
        out: PathBuf,
        /// No progress bars.
        #[arg(long)]
        quiet: bool,
    },
    /// Benchmarks (not tests): particle- or point-steps per second, one JSON line per case.
    Bench {
        /// Which engine.
        #[arg(value_enum)]
        engine: BenchEngine,
        /// Timed steps.
        #[arg(long)]
        steps: Option<u64>,
    },
    /// Remove what granrepro made: the cache and state (and with --reports, the files it
    /// published under reports/). Other files are never touched.
    Clean {
        /// Also remove the reports granrepro published (only its own files).
        #[arg(long)]
        reports: bool,
        /// Only this profile (default: every profile).
        #[arg(long, value_enum)]
        profile: Option<ProfileArg>,
    },
}

fn parse_jobs(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(0) => Err("must be at least 1 (the number of stages run at once)".into()),
        Ok(n) => Ok(n),
        Err(_) => Err(format!("`{s}` is not a whole number >= 1")),
    }
}

fn project_of(pipeline: &Path) -> Project {
    let root = pipeline.parent().filter(|p| !p.as_os_str().is_empty()).map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."));
    Project::new(&root)
}

fn parse_sets(sets: &[String]) -> Result<Vec<Override>, i32> {
    let mut out = Vec::new();
    let mut bad = false;
    for s in sets {
        match Override::parse(s) {
            Ok(o) => out.push(o),
            Err(e) => {
                eprintln!("error: <command line>: {e}");
                bad = true;
            }
        }
    }
    if bad { Err(2) } else { Ok(out) }
}

/// Entry point; returns the process exit code.
pub fn main() -> i32 {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return code;
        }
    };
    run_cli(cli)
}

/// Run a parsed command line.
pub fn run_cli(cli: Cli) -> i32 {
    let proj = project_of(&cli.pipeline);
    match cli.cmd {
        Cmd::Run { stages, only, profile, force, dry_run, jobs, sets, quiet, explain } => {
            let sets = match parse_sets(&sets) {
                Ok(s) => s,
                Err(c) => return c,
            };
            let p = match load(&cli.pipeline, profile.name(), &sets) {
                Ok(p) => p,
                Err(d) => {
                    eprintln!("{d}");
                    return 2;
                }
            };
            if explain {
                let ids = match crate::pipeline::dag::closure(&p, if only.is_empty() { &stages } else { &only }) {
                    Ok(ids) => ids,
                    Err(u) => {
                        eprintln!("error: unknown stage(s): {}", u.join(", "));
                        return 2;
                    }
                };
                for id in ids {
                    let st = p.get(&id).unwrap();
                    if let Some(f) = p.kinds[st.kind.as_str()].explain {
                        println!("== {id} ({}) ==\n{}", st.kind, f(&st.params));
                    }
                }
                return 0;
            }
            let opts = RunOptions { targets: stages, only, force, dry_run, jobs, quiet };
            match crate::pipeline::run::run(&p, &proj, &opts) {
                Err(RunError::BadInput(m)) => {
                    eprintln!("error: {m}");
                    2
                }
                Err(RunError::Io(e)) => {
                    eprintln!("error: {e}");
                    1
                }
                Ok(summary) => {
                    if dry_run {
                        for s in &summary.stages {
                            match &s.outcome {
                                Outcome::Cached => println!("  cached     {}", s.id),
                                Outcome::WouldRun(why) => println!("  would run  {}  ({why})", s.id),
                                _ => {}
                            }
                        }
                        return 0;
                    }
                    let failed: Vec<String> = summary
                        .stages
                        .iter()
                        .filter_map(|s| match &s.outcome {
                            Outcome::Failed(m) => Some(format!("  {}: {m}", s.id)),
                            Outcome::Skipped(m) => Some(format!("  {}: skipped ({m})", s.id)),
                            _ => None,
                        })
                        .collect();
                    // Headline scalars of the targets that completed in this run (a failed
                    // stage's previous results are not shown).
                    for s in &summary.stages {
                        let done = matches!(s.outcome, Outcome::Ran { .. } | Outcome::Cached);
                        if done && opts.targets.iter().any(|t| p.members(t).contains(&s.id.as_str())) {
                            let path = proj.reports.join(&p.profile).join(format!("{}.json", s.id));
                            if let Ok(v) = std::fs::read(&path).map(|b| serde_json::from_slice::<serde_json::Value>(&b).unwrap_or_default()) {
                                if let Some(sc) = v["scalars"].as_object() {
                                    let line: Vec<String> = sc.iter().take(12).map(|(k, v)| format!("{k} = {}", v)).collect();
                                    if !line.is_empty() {
                                        println!("{}: {}", s.id, line.join(", "));
                                    }
                                }
                                for c in v["claims"].as_array().into_iter().flatten() {
                                    println!("  claim {}: paper {} ours {} ({})", c["id"].as_str().unwrap_or(""), c["paper"], c["ours"], if c["pass"].as_bool() == Some(true) { "pass" } else { "FAIL" });
                                }
                            }
                        }
                    }
                    println!(
                        "{} ran, {} cached; reports in {}",
                        summary.ran().len(),
                        summary.cached().len(),
                        proj.reports.join(&p.profile).display()
                    );
                    if failed.is_empty() {
                        0
                    } else {
                        eprintln!("error: stage(s) failed:\n{}", failed.join("\n"));
                        1
                    }
                }
            }
        }
        Cmd::List { profile, kinds } => {
            if kinds {
                for (n, k) in crate::stages::registry() {
                    println!("{n:<20} v{}  {}", k.version, k.about);
                }
                return 0;
            }
            match load(&cli.pipeline, profile.name(), &[]) {
                Ok(p) => {
                    for s in &p.stages {
                        let inputs: Vec<String> = s.inputs.iter().flat_map(|(_, v)| v.iter().cloned()).collect();
                        println!("{:<28} {:<18} inputs: [{}]  {}", s.id, s.kind, inputs.join(", "), s.caption.clone().unwrap_or_default());
                    }
                    0
                }
                Err(d) => {
                    eprintln!("{d}");
                    2
                }
            }
        }
        Cmd::Params { id, profile, sets } => {
            let sets = match parse_sets(&sets) {
                Ok(s) => s,
                Err(c) => return c,
            };
            match load(&cli.pipeline, profile.name(), &sets) {
                Ok(p) => match p.get(&id) {
                    Some(s) => {
                        print!("# {} ({} v{}), profile {}\n{}", s.id, s.kind, s.version, p.profile, serde_yaml::to_string(&s.params).unwrap_or_default());
                        0
                    }
                    None => {
                        eprintln!("error: no stage `{id}` (see `granrepro list`)");
                        2
                    }
                },
                Err(d) => {
                    eprintln!("{d}");
                    2
                }
            }
        }
        Cmd::Dag { format } => match load(&cli.pipeline, "quick", &[]) {
            Ok(p) => {
                print!("{}", match format {
                    DagFormat::Dot => crate::pipeline::dag::to_dot(&p),
                    DagFormat::Mermaid => crate::pipeline::dag::to_mermaid(&p),
                });
                0
            }
            Err(d) => {
                eprintln!("{d}");
                2
            }
        },
        Cmd::Status { profile, sets } => {
            let sets = match parse_sets(&sets) {
                Ok(s) => s,
                Err(c) => return c,
            };
            match load(&cli.pipeline, profile.name(), &sets) {
                Ok(p) => {
                    for (id, f) in status(&p, &proj) {
                        match f {
                            Freshness::Fresh => println!("  fresh    {id}"),
                            Freshness::Missing => println!("  missing  {id}"),
                            Freshness::Stale(r) => println!("  stale    {id}: {}", r.join("; ")),
                        }
                    }
                    0
                }
                Err(d) => {
                    eprintln!("{d}");
                    2
                }
            }
        }
        Cmd::Simulate { scene, out, quiet } if crate::stages::cd_stages::is_cd_scene(&scene) => crate::stages::cd_stages::simulate_cd(&scene, &out, quiet),
        Cmd::Simulate { scene, out, quiet } if crate::scene_mpm::is_mpm_scene(&scene) => crate::scene_mpm::simulate_mpm(&scene, &out, quiet),
        Cmd::Simulate { scene, out, quiet } => crate::scene::simulate(&scene, &out, quiet),
        Cmd::Bench { engine: BenchEngine::LeaveOut, steps } => match load(&cli.pipeline, "quick", &[]) {
            Ok(p) => crate::bench_leave_out::run(&p, steps.unwrap_or(2000)),
            Err(d) => {
                eprintln!("{d}");
                2
            }
        },
        Cmd::Bench { engine, steps } => bench(engine, steps),
        Cmd::Clean { reports, profile } => clean(&cli.pipeline, &proj, reports, profile.map(ProfileArg::name)),
    }
}

/// `clean`: only in the project of an existing pipeline file; only what granrepro made.
fn clean(pipeline: &Path, proj: &Project, reports: bool, profile: Option<&str>) -> i32 {
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
    match crate::pipeline::run::clean_state(proj, profile) {
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
                Ok(r) => println!("removed {} published file(s) of profile `{p}` in {}", r.len(), dir.display()),
                Err(e) => {
                    eprintln!("error: {e}");
                    code = 1;
                }
            }
            if let Ok(rd) = std::fs::read_dir(&dir) {
                let left: Vec<String> = rd.flatten().map(|e| e.file_name().to_string_lossy().to_string()).collect();
                if !left.is_empty() {
                    println!("kept {} file(s) in {} that granrepro did not publish: {}", left.len(), dir.display(), left.join(", "));
                }
            }
        }
        if profile.is_none() && std::fs::read_dir(&proj.reports).is_ok_and(|mut r| r.next().is_none()) && std::fs::remove_dir(&proj.reports).is_ok() {
            println!("removed the empty {}", proj.reports.display());
        }
    }
    code
}

fn bench(engine: BenchEngine, steps: Option<u64>) -> i32 {
    let all = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let mut threads = vec![1];
    if all > 1 {
        threads.push(all);
    }
    match engine {
        BenchEngine::Dem => {
            use crate::dem::bench::{BenchCase, run};
            let steps = steps.unwrap_or(20_000);
            for case in [BenchCase::NoRollingNoLedger, BenchCase::Full] {
                for &t in &threads {
                    match run(case, t, steps) {
                        Ok(r) => println!(
                            "{}",
                            serde_json::json!({
                                "bench": "dem-column",
                                "case": match case { BenchCase::Full => "rolling+ledger", BenchCase::NoRollingNoLedger => "no-rolling-no-ledger" },
                                "threads": r.threads, "particles": r.grains, "steps": r.steps,
                                "wall_s": r.wall_s, "particle_steps_per_s": r.particle_steps_per_s,
                            })
                        ),
                        Err(e) => {
                            eprintln!("error: bench dem: {e}");
                            return 1;
                        }
                    }
                }
            }
            0
        }
        BenchEngine::Cd => {
            let steps = steps.unwrap_or(2000);
            for (ncol, nrow) in [(25, 20), (40, 25)] {
                for &t in &threads {
                    match crate::cd::bench::run(ncol, nrow, t, steps) {
                        Ok(r) => println!(
                            "{}",
                            serde_json::json!({
                                "bench": "cd-pile", "case": r.case, "threads": r.threads, "particles": r.particles,
                                "contacts": r.contacts, "contacts_last": r.contacts_last, "steps": r.steps,
                                "iterations": r.iterations, "wall_s": r.wall_s, "contact_iterations_per_s": r.contact_iterations_per_s,
                                "unconverged": r.unconverged, "max_residual": r.max_residual,
                                "packing_fraction": r.packing_fraction, "ke_over_mgd": r.ke_over_mgd,
                                "detect_s": r.timers.detect, "solve_s": r.timers.solve, "update_s": r.timers.update,
                            })
                        ),
                        Err(e) => {
                            eprintln!("error: bench cd: {e}");
                            return 1;
                        }
                    }
                }
            }
            0
        }
        BenchEngine::Mpm => {
            let steps = steps.unwrap_or(200);
            for &t in &threads {
                let r = crate::mpm::bench::run(t, steps);
                println!(
                    "{}",
                    serde_json::json!({
                        "bench": "mpm-column", "case": "a1-16ppc-2mm-mc",
                        "threads": r.threads, "points": r.points, "steps": r.steps,
                        "wall_s": r.wall_s, "point_steps_per_s": r.point_steps_per_s,
                        "p2g_s": r.p2g_s(), "stress_s": r.stress_s(), "g2p_s": r.g2p_s(),
                    })
                );
            }
            0
        }
        BenchEngine::LeaveOut => 2, // needs the pipeline: dispatched in run_cli
    }
}
