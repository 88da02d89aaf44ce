//! The command line (thin: parse, call the library, map errors to exit codes).
//! Exit codes: 0 ok, 1 a stage failed, 2 bad input (nothing run).

use std::path::{Path, PathBuf};

use clap::{Parser, Subcommand};

use crate::pipeline::run::{Freshness, Outcome, Project, RunError, RunOptions, status};
use crate::pipeline::{Override, load};

mod args;
mod bench;
mod commands;

pub use args::{BenchCaseArg, BenchEngine, DagFormat, ExportEngine, ProfileArg};

use bench::{BenchOpts, bench};
use commands::{clean, export_snakemake, plan_cmd, timings_cmd};

/// granrepro — regenerate the figures and tables of Kumar (2015), thesis chapter 4.
#[derive(Parser, Debug)]
#[command(name = "granrepro", version, about)]
pub struct Cli {
    /// Pipeline file.
    #[arg(long, global = true, default_value = "pipeline.yaml")]
    pub pipeline: PathBuf,
    /// Content-addressed cache directory (default `.granrepro/cache` next to the pipeline;
    /// also the environment variable GRANREPRO_CACHE). Many processes and machines may
    /// share one, e.g. on a shared filesystem.
    #[arg(long, global = true)]
    pub cache: Option<PathBuf>,
    /// Command.
    #[command(subcommand)]
    pub cmd: Cmd,
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
        /// Stages run at once (at least 1; default: the number of cores). Each stage gets
        /// its own thread pool, the cores shared among the stages running at once.
        #[arg(long, default_value_t = default_jobs(), value_parser = parse_jobs)]
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
        /// After the run, write DIR/<id>.<key>.done for every stage whose cache entry is in
        /// place (for workflow engines; see `export snakemake`).
        #[arg(long, value_name = "DIR")]
        markers: Option<PathBuf>,
    },
    /// The stages to run in a valid order with their cache keys and inputs (or, with
    /// --estimate, the CPU-hours they need).
    Plan {
        /// Target stage (repeatable; a matrix base id means all its members). Default: all.
        #[arg(long = "stage")]
        stages: Vec<String>,
        /// Profile.
        #[arg(long, value_enum, default_value = "quick")]
        profile: ProfileArg,
        /// One JSON document (profile, pipeline, cache, stages with id, kind, key, inputs, cached).
        #[arg(long)]
        json: bool,
        /// Estimated CPU-hours per stage family, scaled from the quick profile's run records.
        #[arg(long)]
        estimate: bool,
        /// Where the last run's time went, from the run records in the cache: each stage's
        /// start, wall time and threads, the span and the critical chain (run it after a
        /// cold `run` for the pipeline's cost).
        #[arg(long, conflicts_with = "estimate")]
        timings: bool,
        /// With --timings: list only stages at least this long [s] (the totals count all).
        #[arg(long, default_value_t = 0.0, requires = "timings")]
        min_wall: f64,
    },
    /// Export the stage graph to a workflow engine (written to stdout).
    Export {
        /// Engine.
        #[arg(value_enum)]
        engine: ExportEngine,
        /// Profile the rules run.
        #[arg(long, value_enum, default_value = "quick")]
        profile: ProfileArg,
        /// Target stage (repeatable; default: every stage).
        #[arg(long = "stage")]
        stages: Vec<String>,
        /// The granrepro the workers run (default: this binary's absolute path; pass
        /// `granrepro` to use the workers' PATH).
        #[arg(long)]
        bin: Option<String>,
        /// Threads of a solver stage (stages measured under 1 s get 1).
        #[arg(long, default_value_t = 2, value_parser = parse_jobs)]
        threads: usize,
        /// Memory request [MB] of a rule whose stage no earlier worker measured (markers
        /// record peak memory; run records do not).
        #[arg(long, default_value_t = 4000)]
        mem_mb: u64,
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
        /// Instead: which committed results a change to this file or directory would mark
        /// "built from changed code", which stages downstream read them, and what their runs
        /// cost as measured (repeatable; e.g. `--if-changed src/mpm`).
        #[arg(long = "if-changed", value_name = "PATH")]
        if_changed: Vec<String>,
    },
    /// Keep the profile's results in `results/<profile>/` (for the paper profile, committed
    /// to the repository): each stage with a complete cache entry, its published tables,
    /// figures and JSON, the index page, and a lock recording each stage's cache key and the
    /// hashes of the files and of the source code it was built from. Large files are left
    /// out (listed in the lock).
    Keep {
        /// Profile.
        #[arg(long, value_enum, default_value = "paper")]
        profile: ProfileArg,
        /// Largest file kept [MB] (per-particle snapshot tables and fields are larger).
        #[arg(long, default_value_t = 2.0)]
        max_file_mb: f64,
        /// Keep one on-demand study (a stage declared `on_demand: true`) in
        /// `results/<stage>/` instead: the on-demand stages it needs, under their own lock.
        #[arg(long)]
        stage: Option<String>,
    },
    /// The claims ledger (stages/ledger.yaml) judged on the profile's published results:
    /// one line per claim of the chapter, its value, ours (mean ± spread), the verdict.
    Claims {
        /// Profile.
        #[arg(long, value_enum, default_value = "quick")]
        profile: ProfileArg,
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
        /// Also print a per-phase timer table (like LAMMPS's "MPI task timing breakdown").
        #[arg(long)]
        phases: bool,
        /// Thread counts to measure (repeatable; default: 1 and all cores).
        #[arg(long = "threads")]
        threads: Vec<usize>,
        /// DEM only: time step [s] (default: 1e-6 s as LAMMPS if the pre-flight accepts it).
        #[arg(long)]
        dt: Option<f64>,
        /// DEM only: physics case (default: all three).
        #[arg(long, value_enum)]
        case: Vec<BenchCaseArg>,
        /// Best of this many repetitions (each reported).
        #[arg(long, default_value_t = 1)]
        repeat: usize,
        /// Scaling only: write the figure (SVG) here.
        #[arg(long)]
        svg: Option<PathBuf>,
        /// Scaling only: largest size (default 100000; 1000000 adds the DEM's 1e6 row, about
        /// a minute more).
        #[arg(long, default_value_t = 100_000)]
        max_n: usize,
        /// Scaling only: the DEM's grains in the lattice's order (neighbours in space near
        /// in memory), not shuffled.
        #[arg(long)]
        lattice_order: bool,
        /// Scaling only: the DEM's grains shuffled, then sorted by the engine along its
        /// Hilbert curve (the order a mixed flow has after a sort, `sort_every`).
        #[arg(long, conflicts_with = "lattice_order")]
        sorted: bool,
        /// Scaling only: the DEM row alone (no MPM, no CD).
        #[arg(long)]
        dem_only: bool,
        /// cd-dense only: the deposit's columns × rows of disks (default 40x25; the chapter's
        /// pile has 13,000 disks, e.g. 160x80).
        #[arg(long, default_value = "40x25")]
        dense_size: String,
        /// cd-dense only: write each timed scene here as CSV (`cd-dense-CASE.csv`: x, y, r, m,
        /// vx, vy per disk, SI per metre), the input of `bench/siconos/dense.py`.
        #[arg(long)]
        scene_out: Option<PathBuf>,
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

fn default_jobs() -> usize {
    std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)
}

fn parse_jobs(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(0) => Err("must be at least 1 (the number of stages run at once)".into()),
        Ok(n) => Ok(n),
        Err(_) => Err(format!("`{s}` is not a whole number >= 1")),
    }
}

fn project_of(pipeline: &Path) -> Project {
    let root = pipeline
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."));
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
    let shared_cache = match cli.cmd {
        Cmd::Run { .. }
        | Cmd::Status { .. }
        | Cmd::Clean { .. }
        | Cmd::Plan { .. }
        | Cmd::Export { .. }
        | Cmd::Keep { .. } => match cache_dir(cli.cache.clone()) {
            Ok(c) => c,
            Err(m) => {
                eprintln!("error: {m}");
                return 2;
            }
        },
        _ => None,
    };
    let proj = match &shared_cache {
        Some(d) => proj.with_cache(d),
        None => proj,
    };
    match cli.cmd {
        Cmd::Plan {
            stages,
            profile,
            json,
            estimate,
            timings,
            min_wall,
        } => {
            if timings {
                timings_cmd(&cli.pipeline, &proj, &stages, profile, json, min_wall)
            } else {
                plan_cmd(&cli.pipeline, &proj, &stages, profile, json, estimate)
            }
        }
        Cmd::Export {
            engine: ExportEngine::Snakemake,
            profile,
            stages,
            bin,
            threads,
            mem_mb,
        } => export_snakemake(
            &cli.pipeline,
            &proj,
            shared_cache.as_deref(),
            &stages,
            profile,
            bin,
            threads,
            mem_mb,
        ),
        Cmd::Run {
            stages,
            only,
            profile,
            force,
            dry_run,
            jobs,
            sets,
            quiet,
            explain,
            markers,
        } => {
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
            let opts = RunOptions {
                targets: stages,
                only,
                force,
                dry_run,
                jobs,
                quiet,
            };
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
                                Outcome::Served(from) => println!("  served     {}  ({from})", s.id),
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
                            if let Ok(v) = std::fs::read(&path)
                                .map(|b| serde_json::from_slice::<serde_json::Value>(&b).unwrap_or_default())
                            {
                                if let Some(sc) = v["scalars"].as_object() {
                                    let line: Vec<String> =
                                        sc.iter().take(12).map(|(k, v)| format!("{k} = {}", v)).collect();
                                    if !line.is_empty() {
                                        println!("{}: {}", s.id, line.join(", "));
                                    }
                                }
                                // Text results (a choice's rule and its reason).
                                for (k, t) in v.as_object().into_iter().flatten() {
                                    if let (Some(t), false) = (t.as_str(), k == "stage" || k == "profile") {
                                        println!("  {k}: {t}");
                                    }
                                }
                                for c in v["measurements"].as_array().into_iter().flatten() {
                                    println!(
                                        "  measurement {}: {} (judged in the ledger: `granrepro claims`)",
                                        c["id"].as_str().unwrap_or(""),
                                        c["ours"]
                                    );
                                }
                            }
                        }
                    }
                    if let Some(Err(e)) = markers
                        .as_ref()
                        .map(|dir| crate::pipeline::export::write_markers(dir, &p.profile, &summary))
                    {
                        eprintln!("error: {e}");
                        return 1;
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
                        println!(
                            "{:<28} {:<18} inputs: [{}]  {}",
                            s.id,
                            s.kind,
                            inputs.join(", "),
                            s.caption.clone().unwrap_or_default()
                        );
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
                        print!(
                            "# {} ({} v{}), profile {}\n{}",
                            s.id,
                            s.kind,
                            s.version,
                            p.profile,
                            serde_yaml::to_string(&s.params).unwrap_or_default()
                        );
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
                print!(
                    "{}",
                    match format {
                        DagFormat::Dot => crate::pipeline::dag::to_dot(&p),
                        DagFormat::Mermaid => crate::pipeline::dag::to_mermaid(&p),
                    }
                );
                0
            }
            Err(d) => {
                eprintln!("{d}");
                2
            }
        },
        Cmd::Status {
            profile,
            sets,
            if_changed,
        } => {
            let sets = match parse_sets(&sets) {
                Ok(s) => s,
                Err(c) => return c,
            };
            match load(&cli.pipeline, profile.name(), &sets) {
                Ok(p) if !if_changed.is_empty() => crate::cli::commands::print_impact(&p, &if_changed),
                Ok(p) => {
                    for (id, f) in status(&p, &proj) {
                        let on_demand = p.get(&id).is_some_and(|s| s.on_demand);
                        match f {
                            Freshness::Fresh => println!("  fresh    {id}"),
                            Freshness::Missing if on_demand => {
                                println!("  -        {id}: on demand (`run --stage {id}`)")
                            }
                            Freshness::Missing => println!("  missing  {id}"),
                            Freshness::Stale(r) => println!("  stale    {id}: {}", r.join("; ")),
                        }
                    }
                    crate::cli::commands::print_committed(&p)
                }
                Err(d) => {
                    eprintln!("{d}");
                    2
                }
            }
        }
        Cmd::Keep {
            profile,
            max_file_mb,
            stage,
        } => match load(&cli.pipeline, profile.name(), &[]) {
            Ok(p) => crate::cli::commands::keep(&p, &proj, max_file_mb, stage.as_deref()),
            Err(d) => {
                eprintln!("{d}");
                2
            }
        },
        Cmd::Claims { profile } => match load(&cli.pipeline, profile.name(), &[]) {
            Ok(p) => crate::cli::commands::print_claims(&p, &proj.reports.join(profile.name())),
            Err(d) => {
                eprintln!("{d}");
                2
            }
        },
        Cmd::Simulate { scene, out, quiet } if crate::scene_cd::is_cd_scene(&scene) => {
            crate::scene_cd::simulate_cd(&scene, &out, quiet)
        }
        Cmd::Simulate { scene, out, quiet } if crate::scene_mpm::is_mpm_scene(&scene) => {
            crate::scene_mpm::simulate_mpm(&scene, &out, quiet)
        }
        Cmd::Simulate { scene, out, quiet } => crate::scene::simulate(&scene, &out, quiet),
        Cmd::Bench {
            engine: BenchEngine::LeaveOut,
            steps,
            ..
        } => match load(&cli.pipeline, "quick", &[]) {
            Ok(p) => crate::bench_leave_out::run(&p, steps.unwrap_or(2000)),
            Err(d) => {
                eprintln!("{d}");
                2
            }
        },
        Cmd::Bench {
            engine,
            steps,
            phases,
            threads,
            dt,
            case,
            repeat,
            svg,
            max_n,
            lattice_order,
            sorted,
            dem_only,
            dense_size,
            scene_out,
        } => bench(
            engine,
            steps,
            &BenchOpts {
                phases,
                threads,
                dt,
                case,
                repeat,
                svg,
                max_n,
                lattice_order,
                sorted,
                dem_only,
                dense_size,
                scene_out,
            },
        ),
        Cmd::Clean { reports, profile } => clean(&cli.pipeline, &proj, reports, profile.map(ProfileArg::name)),
    }
}

/// The shared cache directory from `--cache` or `GRANREPRO_CACHE` (absolute), checked
/// before anything runs: it must be a writable directory, or not exist yet inside one.
fn cache_dir(opt: Option<PathBuf>) -> Result<Option<PathBuf>, String> {
    let (dir, from) = match opt {
        Some(d) => (d, "--cache"),
        None => match std::env::var_os("GRANREPRO_CACHE").filter(|v| !v.is_empty()) {
            Some(v) => (PathBuf::from(v), "GRANREPRO_CACHE"),
            None => return Ok(None),
        },
    };
    let dir = std::path::absolute(&dir).map_err(|e| format!("{from} {}: {e}", dir.display()))?;
    let help = "help: point --cache (or GRANREPRO_CACHE) at a directory every worker can write, e.g. on a shared filesystem; it is created if only its last component is missing";
    let writable = |d: &Path| tempfile::tempfile_in(d).is_ok();
    if dir.exists() {
        if !dir.is_dir() {
            return Err(format!("{from} {}: not a directory\n  {help}", dir.display()));
        }
        if !writable(&dir) {
            return Err(format!("{from} {}: directory is not writable\n  {help}", dir.display()));
        }
    } else {
        let parent = dir
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("/"));
        if !parent.is_dir() {
            return Err(format!(
                "{from} {}: its parent directory {} does not exist\n  {help}",
                dir.display(),
                parent.display()
            ));
        }
        if !writable(parent) {
            return Err(format!(
                "{from} {}: its parent directory {} is not writable\n  {help}",
                dir.display(),
                parent.display()
            ));
        }
    }
    Ok(Some(dir))
}
