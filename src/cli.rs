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
    /// Content-addressed cache directory (default `.granrepro/cache` next to the pipeline;
    /// also the environment variable GRANREPRO_CACHE). Many processes and machines may
    /// share one, e.g. on a shared filesystem.
    #[arg(long, global = true)]
    pub cache: Option<PathBuf>,
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

/// Workflow engines `export` writes for.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum ExportEngine {
    /// A Snakefile: one rule per stage (`snakemake -j N`, `--executor slurm`).
    Snakemake,
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
    /// Cost growth: wall time per step against grain / point count (1e3 … 1e5) for DEM,
    /// CD and MPM, one thread; a table, JSON lines and `--svg FILE`.
    Scaling,
    /// In-step parallelism crossover: DEM step time on 1 thread and on every thread of the
    /// machine (thread team forced on) for the settled column cut to 250 … 5848 grains.
    DemCrossover,
    /// Per-stage table of the optional terms and outputs each scene enables, and the step
    /// cost of its configuration against everything on (issue 12; docs/stability.md).
    LeaveOut,
}

/// DEM benchmark physics.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum BenchCaseArg {
    /// Table 4.2: rolling resistance with the implicit dashpot, energy ledger.
    Full,
    /// Rolling resistance, no ledger.
    RollingNoLedger,
    /// LAMMPS `gran/hooke/history` physics: no rolling resistance, no ledger.
    NoRolling,
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
        /// Scaling only: largest size (default 100000).
        #[arg(long, default_value_t = 100_000)]
        max_n: usize,
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
        Cmd::Run { .. } | Cmd::Status { .. } | Cmd::Clean { .. } | Cmd::Plan { .. } | Cmd::Export { .. } => {
            match cache_dir(cli.cache.clone()) {
                Ok(c) => c,
                Err(m) => {
                    eprintln!("error: {m}");
                    return 2;
                }
            }
        }
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
                                for c in v["claims"].as_array().into_iter().flatten() {
                                    println!(
                                        "  claim {}: paper {} ours {} ({})",
                                        c["id"].as_str().unwrap_or(""),
                                        c["paper"],
                                        c["ours"],
                                        if c["pass"].as_bool() == Some(true) {
                                            "pass"
                                        } else {
                                            "FAIL"
                                        }
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

/// `plan`: the stages in order with keys (text or JSON), or the paper budget.
fn plan_cmd(
    pipeline: &Path,
    proj: &Project,
    stages: &[String],
    profile: ProfileArg,
    json: bool,
    estimate: bool,
) -> i32 {
    let p = match load(pipeline, profile.name(), &[]) {
        Ok(p) => p,
        Err(d) => {
            eprintln!("{d}");
            return 2;
        }
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
fn timings_cmd(
    pipeline: &Path,
    proj: &Project,
    stages: &[String],
    profile: ProfileArg,
    json: bool,
    min_wall: f64,
) -> i32 {
    let p = match load(pipeline, profile.name(), &[]) {
        Ok(p) => p,
        Err(d) => {
            eprintln!("{d}");
            return 2;
        }
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
fn export_snakemake(
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
    let p = match load(pipeline, profile.name(), &[]) {
        Ok(p) => p,
        Err(d) => {
            eprintln!("{d}");
            return 2;
        }
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

/// Options of `granrepro bench`.
pub struct BenchOpts {
    phases: bool,
    threads: Vec<usize>,
    dt: Option<f64>,
    case: Vec<BenchCaseArg>,
    repeat: usize,
    svg: Option<PathBuf>,
    max_n: usize,
}

/// A LAMMPS-style timer table: section, seconds, share of the total.
fn print_phase_table(title: &str, rows: &[(&str, f64)], steps: u64) {
    let total: f64 = rows.iter().map(|r| r.1).sum();
    println!("{title}");
    println!(
        "  {:<14} {:>10} {:>12} {:>7}",
        "section", "time [s]", "per step [us]", "%total"
    );
    for (name, t) in rows {
        println!(
            "  {:<14} {:>10.4} {:>12.3} {:>6.1}%",
            name,
            t,
            1e6 * t / steps.max(1) as f64,
            100.0 * t / total.max(1e-300)
        );
    }
    println!(
        "  {:<14} {:>10.4} {:>12.3} {:>6.1}%",
        "total",
        total,
        1e6 * total / steps.max(1) as f64,
        100.0
    );
}

fn bench(engine: BenchEngine, steps: Option<u64>, o: &BenchOpts) -> i32 {
    let all = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let threads: Vec<usize> = if !o.threads.is_empty() {
        o.threads.iter().map(|&t| t.max(1)).collect()
    } else if all > 1 {
        vec![1, all]
    } else {
        vec![1]
    };
    match engine {
        BenchEngine::Scaling => bench_scaling(steps, o),
        BenchEngine::DemCrossover => bench_dem_crossover(steps, o, all),
        BenchEngine::Dem => {
            use crate::dem::bench::{BenchCase, run};
            let steps = steps.unwrap_or(20_000);
            let cases: Vec<BenchCase> = if o.case.is_empty() {
                vec![
                    BenchCase::NoRollingNoLedger,
                    BenchCase::RollingNoLedger,
                    BenchCase::Full,
                ]
            } else {
                o.case
                    .iter()
                    .map(|c| match c {
                        BenchCaseArg::Full => BenchCase::Full,
                        BenchCaseArg::RollingNoLedger => BenchCase::RollingNoLedger,
                        BenchCaseArg::NoRolling => BenchCase::NoRollingNoLedger,
                    })
                    .collect()
            };
            for case in cases {
                for &t in &threads {
                    let mut best: Option<crate::dem::bench::BenchResult> = None;
                    for _ in 0..o.repeat.max(1) {
                        match run(case, t, steps, o.dt) {
                            Ok(r) => {
                                let tm = &r.timers;
                                println!(
                                    "{}",
                                    serde_json::json!({
                                        "bench": "dem-column", "case": case.name(),
                                        "threads": r.threads, "particles": r.grains, "steps": r.steps, "dt": r.dt,
                                        "preflight_limit_s": r.preflight_limit_s,
                                        "wall_s": r.wall_s, "cpu_s": r.cpu_s, "particle_steps_per_s": r.particle_steps_per_s,
                                        "best_block_particle_steps_per_s": r.best_block_particle_steps_per_s,
                                        "pairs_per_grain": r.pairs_per_grain, "contacts_per_grain": r.contacts_per_grain, "rebuilds": r.rebuilds,
                                        "neighbors_s": tm.neighbors, "contacts_s": tm.contacts, "gather_s": tm.gather, "walls_s": tm.walls,
                                        "rolling_s": tm.rolling, "integrate_s": tm.integrate, "ledger_s": tm.ledger, "digest": r.digest,
                                    })
                                );
                                if best.as_ref().is_none_or(|b| r.wall_s < b.wall_s) {
                                    best = Some(r);
                                }
                            }
                            Err(e) => {
                                eprintln!("error: bench dem: {e}");
                                return 1;
                            }
                        }
                    }
                    if let (true, Some(r)) = (o.phases, best) {
                        let tm = &r.timers;
                        let other = (r.wall_s - tm.total()).max(0.0);
                        print_phase_table(
                            &format!(
                                "dem-column {} | {} thread(s) | {} grains x {} steps, dt = {:.2e} s | {:.3} M particle-steps/s",
                                case.name(),
                                r.threads,
                                r.grains,
                                r.steps,
                                r.dt,
                                r.particle_steps_per_s / 1e6
                            ),
                            &[
                                ("neighbour", tm.neighbors),
                                ("contact pairs", tm.contacts),
                                ("force gather", tm.gather),
                                ("walls", tm.walls),
                                ("rolling solve", tm.rolling),
                                ("integrate", tm.integrate),
                                ("ledger", tm.ledger),
                                ("other", other + tm.watchdog),
                            ],
                            r.steps,
                        );
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
            for &t in &threads {
                let mut best: Option<crate::mpm::bench::BenchResult> = None;
                for _ in 0..o.repeat.max(1) {
                    let r = crate::mpm::bench::run(t, steps, 5.0);
                    let ph = &r.phases;
                    println!(
                        "{}",
                        serde_json::json!({
                            "bench": "mpm-column", "case": "a1-16ppc-2mm-mc",
                            "threads": r.threads, "points": r.points, "steps": r.steps,
                            "wall_s": r.wall_s, "point_steps_per_s": r.point_steps_per_s,
                            "p2g_s": r.p2g_s(), "grid_update_s": ph.grid_update.as_secs_f64(), "stress_s": r.stress_s(),
                            "g2p_s": r.g2p_s(), "relocate_s": ph.relocate.as_secs_f64(),
                        })
                    );
                    if best.as_ref().is_none_or(|b| r.point_steps_per_s > b.point_steps_per_s) {
                        best = Some(r);
                    }
                }
                if let (true, Some(r)) = (o.phases, best) {
                    let ph = &r.phases;
                    let other = (r.wall_s - ph.total().as_secs_f64()).max(0.0);
                    print_phase_table(
                        &format!(
                            "mpm-column a1-16ppc-2mm-mc | {} thread(s) | {} points x {} steps | best of {}: {:.3} M point-steps/s",
                            r.threads,
                            r.points,
                            r.steps,
                            o.repeat.max(1),
                            r.point_steps_per_s / 1e6
                        ),
                        &[
                            ("P2G", r.p2g_s()),
                            ("grid update", ph.grid_update.as_secs_f64()),
                            ("stress", r.stress_s()),
                            ("G2P", r.g2p_s()),
                            ("relocation", ph.relocate.as_secs_f64()),
                            ("other", other),
                        ],
                        r.steps,
                    );
                }
            }
            0
        }
        BenchEngine::LeaveOut => 2, // needs the pipeline: dispatched in run_cli
    }
}

/// `bench dem-crossover`: µs per step on 1 thread and on `all` threads (team forced on)
/// by grain count, best of `--repeat`, alternating the two at each size.
fn bench_dem_crossover(steps: Option<u64>, o: &BenchOpts, all: usize) -> i32 {
    use crate::dem::bench::{BenchCase, bench_dt, bench_scene, scaling_point_with};
    let (dt, _) = bench_dt(BenchCase::Full);
    let base = match bench_scene(BenchCase::Full, dt) {
        Ok(w) => w,
        Err(e) => {
            eprintln!("error: bench dem-crossover: {e}");
            return 1;
        }
    };
    let multi = o.threads.iter().copied().max().unwrap_or(all).max(2);
    println!(
        "dem-crossover | rolling + ledger | best of {} | µs per step",
        o.repeat.max(1)
    );
    println!(
        "  {:>6} {:>10} {:>10} {:>8}",
        "grains",
        "1 thread",
        format!("{multi} threads"),
        "speed-up"
    );
    for n in [250usize, 500, 750, 1000, 1500, 2000, 2924, 5848] {
        let st = steps.unwrap_or((2_000_000 / n as u64).clamp(200, 5000));
        let (mut t1, mut t2) = (f64::INFINITY, f64::INFINITY);
        for _ in 0..o.repeat.max(1) {
            for (t, best) in [(1, &mut t1), (multi, &mut t2)] {
                match scaling_point_with(&base, n, t, st, Some(0)) {
                    Ok(p) => *best = best.min(p.s_per_step),
                    Err(e) => {
                        eprintln!("error: bench dem-crossover ({n}): {e}");
                        return 1;
                    }
                }
            }
        }
        println!(
            "{}",
            serde_json::json!({"bench": "dem-crossover", "n": n, "steps": st, "s_per_step_1": t1, "threads": multi, "s_per_step_multi": t2})
        );
        println!("  {:>6} {:>10.1} {:>10.1} {:>7.2}x", n, 1e6 * t1, 1e6 * t2, t1 / t2);
    }
    0
}

/// `bench scaling`: seconds per step against size for the three engines, one thread.
fn bench_scaling(steps: Option<u64>, o: &BenchOpts) -> i32 {
    use crate::report::plot::{Chart, Series, Style};
    let threads = o.threads.first().copied().unwrap_or(1).max(1);
    let sizes: Vec<usize> = [1_000usize, 3_000, 10_000, 30_000, 100_000]
        .into_iter()
        .filter(|&n| n <= o.max_n)
        .collect();
    // work per size ~ n × steps: fewer steps for the big ones, at least 20
    let steps_for = |n: usize, base: u64| steps.unwrap_or((base * 10_000 / n as u64).clamp(20, base * 10));
    let best = |f: &mut dyn FnMut() -> f64| (0..o.repeat.max(1)).map(|_| f()).fold(f64::INFINITY, f64::min);
    let mut rows: Vec<(&str, usize, f64, String)> = Vec::new();
    // DEM
    let (dt, _) = crate::dem::bench::bench_dt(crate::dem::bench::BenchCase::Full);
    let base = match crate::dem::bench::bench_scene(crate::dem::bench::BenchCase::Full, dt) {
        Ok(w) => w,
        Err(e) => {
            eprintln!("error: bench scaling: {e}");
            return 1;
        }
    };
    for &n in &sizes {
        let st = steps_for(n, 200);
        let mut extra = String::new();
        let mut err = None;
        let s = best(&mut || match crate::dem::bench::scaling_point(&base, n, threads, st) {
            Ok(p) => {
                extra = format!(
                    "{:.2} pairs, {:.2} contacts per grain",
                    p.pairs_per_grain, p.contacts_per_grain
                );
                p.s_per_step
            }
            Err(e) => {
                err = Some(e.to_string());
                f64::NAN
            }
        });
        if let Some(e) = err {
            eprintln!("error: bench scaling (dem, {n}): {e}");
            return 1;
        }
        println!(
            "{}",
            serde_json::json!({"bench": "scaling", "engine": "dem", "n": n, "threads": threads, "steps": st, "s_per_step": s, "note": extra})
        );
        rows.push(("DEM", n, s, extra));
    }
    // MPM
    for &n in &sizes {
        let st = steps_for(n, 20);
        let mut pts = 0;
        let s = best(&mut || {
            let (p, s) = crate::mpm::bench::scaling_point(n, threads, st);
            pts = p;
            s
        });
        println!(
            "{}",
            serde_json::json!({"bench": "scaling", "engine": "mpm", "n": pts, "threads": threads, "steps": st, "s_per_step": s})
        );
        rows.push(("MPM", pts, s, String::new()));
    }
    // CD: the Siconos deposit, ncol × nrow ≈ n with ncol/nrow = 1.6 as its 40 × 25 case
    for &n in &sizes {
        let ncol = ((n as f64 * 1.6).sqrt().round() as usize).max(2);
        let nrow = (n / ncol).max(1);
        let st = steps_for(n, 20);
        let mut extra = String::new();
        let mut pts = ncol * nrow;
        let mut err = None;
        let s = best(&mut || match crate::cd::bench::run(ncol, nrow, threads, st) {
            Ok(r) => {
                pts = r.particles;
                extra = format!(
                    "{:.0} contacts, {:.1} NLGS sweeps per step",
                    r.contacts,
                    r.iterations as f64 / r.steps.max(1) as f64
                );
                r.wall_s / r.steps.max(1) as f64
            }
            Err(e) => {
                err = Some(e.to_string());
                f64::NAN
            }
        });
        if let Some(e) = err {
            eprintln!("error: bench scaling (cd, {n}): {e}");
            return 1;
        }
        println!(
            "{}",
            serde_json::json!({"bench": "scaling", "engine": "cd", "n": pts, "threads": threads, "steps": st, "s_per_step": s, "note": extra})
        );
        rows.push(("CD", pts, s, extra));
    }
    println!("cost growth, {threads} thread(s): wall time per step");
    println!(
        "  {:<5} {:>8} {:>12} {:>14} {:>8}  {}",
        "engine", "n", "ms/step", "ns/(n·step)", "vs 1e3", ""
    );
    for eng in ["DEM", "MPM", "CD"] {
        let r: Vec<_> = rows.iter().filter(|r| r.0 == eng).collect();
        let Some(first) = r.first() else { continue };
        let unit0 = first.2 / first.1 as f64;
        for x in &r {
            let unit = x.2 / x.1 as f64;
            println!(
                "  {:<5} {:>8} {:>12.3} {:>14.1} {:>8.2}  {}",
                x.0,
                x.1,
                1e3 * x.2,
                1e9 * unit,
                unit / unit0,
                x.3
            );
        }
    }
    if let Some(path) = &o.svg {
        let series: Vec<Series> = ["DEM", "MPM", "CD"]
            .iter()
            .enumerate()
            .map(|(c, eng)| {
                Series::new(
                    format!("{eng} (measured)"),
                    Style::LinePoints,
                    rows.iter().filter(|r| r.0 == *eng).map(|r| (r.1 as f64, r.2)).collect(),
                    c,
                )
            })
            .chain(rows.iter().find(|r| r.0 == "DEM").map(|r| {
                let k = r.2 / r.1 as f64;
                Series::new(
                    "linear in n (through DEM at 1e3)",
                    Style::Dashed,
                    sizes.iter().map(|&n| (n as f64, k * n as f64)).collect(),
                    7,
                )
            }))
            .collect();
        let chart = Chart::log_log(
            format!("Cost growth: wall time per step vs size ({threads} thread(s))"),
            "granrepro bench scaling; DEM: settled column with rolling resistance + ledger; MPM: GIMP + Mohr-Coulomb column; CD: Siconos deposit".into(),
            "grains / material points",
            "wall time per step [s]",
            series,
        );
        match chart
            .to_svg()
            .map_err(|e| e.to_string())
            .and_then(|svg| std::fs::write(path, svg).map_err(|e| e.to_string()))
        {
            Ok(()) => println!("figure: {}", path.display()),
            Err(e) => {
                eprintln!("error: {}: {e}", path.display());
                return 1;
            }
        }
    }
    0
}
