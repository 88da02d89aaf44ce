//! Planning and running stages: keys computed before anything runs, cached stages
//! served from the cache, the rest run in dependency order with up to `jobs` stages at
//! once, each writing its cache entry atomically and a run record, then published to
//! `reports/<profile>/`. Every entry of the plan is marked in use ([`Cache::hold`]) from
//! before the first lookup until it is published, so a concurrent `clean` keeps it. An
//! input entry that vanishes anyway before a stage has read it (removed by hand, or by a
//! process without working locks) is planned again and recomputed, at most
//! [`MAX_REPLANS`] times, before the stages needing it fail saying so.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::sync::mpsc;
use std::time::Instant;

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde_json::Value;

use super::cache::{KeyRecord, Lookup, STALE_TMP_AGE, write_atomic};
use super::context::{InputRef, Output, StageCtx};
use super::dag::closure;
pub use super::keys::{key_records, stale_reasons};
pub use super::project::Project;
use super::publish;
use super::spec::{Pipeline, Stage};
pub use super::status::{Freshness, status};

/// How to run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Target stage ids (matrix base ids allowed); empty = every stage.
    pub targets: Vec<String>,
    /// Run exactly these stages from inputs already cached (no upstream work).
    pub only: Vec<String>,
    /// Re-run the targets even when cached.
    pub force: bool,
    /// Plan only.
    pub dry_run: bool,
    /// Stages at once (≥ 1).
    pub jobs: usize,
    /// No progress bars or per-stage lines.
    pub quiet: bool,
}

/// What happened to one stage.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// Served from the cache.
    Cached,
    /// Computed now.
    Ran {
        /// Wall time [s].
        wall_s: f64,
    },
    /// Would run (dry run), with the reason.
    WouldRun(String),
    /// Would be served from the committed results (dry run), with where from.
    Served(String),
    /// Failed with this message.
    Failed(String),
    /// Not run because an input failed.
    Skipped(String),
}

/// Per-stage result of a run.
#[derive(Debug, Clone)]
pub struct StageReport {
    /// Stage id.
    pub id: String,
    /// Cache key.
    pub key: String,
    /// Outcome.
    pub outcome: Outcome,
}

/// Result of a run.
#[derive(Debug, Clone, Default)]
pub struct RunSummary {
    /// Stages in execution order.
    pub stages: Vec<StageReport>,
}

impl RunSummary {
    /// Ids of stages computed in this run.
    pub fn ran(&self) -> Vec<&str> {
        self.stages
            .iter()
            .filter(|s| matches!(s.outcome, Outcome::Ran { .. }))
            .map(|s| s.id.as_str())
            .collect()
    }
    /// Ids of stages served from cache.
    pub fn cached(&self) -> Vec<&str> {
        self.stages
            .iter()
            .filter(|s| s.outcome == Outcome::Cached)
            .map(|s| s.id.as_str())
            .collect()
    }
    /// Did any stage fail?
    pub fn failed(&self) -> bool {
        self.stages
            .iter()
            .any(|s| matches!(s.outcome, Outcome::Failed(_) | Outcome::Skipped(_)))
    }
}

/// Errors that stop a run before anything runs (exit code 2).
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// Bad request (unknown target, missing cached input for `--only`).
    #[error("{0}")]
    BadInput(String),
    /// I/O problem.
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

/// Plan and run.
pub fn run(p: &Pipeline, proj: &Project, opts: &RunOptions) -> Result<RunSummary, RunError> {
    let keys = key_records(p);
    let set: Vec<String> = if !opts.only.is_empty() {
        let mut v = Vec::new();
        for o in &opts.only {
            let m = p.members(o);
            if m.is_empty() {
                return Err(RunError::BadInput(format!(
                    "--only {o}: no such stage (see `granrepro list`)"
                )));
            }
            v.extend(m.into_iter().map(str::to_string));
        }
        // Every input must already be in the cache.
        let inside: HashSet<&String> = v.iter().collect();
        let mut missing = Vec::new();
        for id in &v {
            for (_, ids) in &p.get(id).unwrap().inputs {
                for d in ids {
                    if inside.contains(d) {
                        continue;
                    }
                    let k = &keys[d].1;
                    if !matches!(proj.cache.lookup(k), Lookup::Fresh(_)) {
                        missing.push(format!("{d} (needed by {id}, key {k})"));
                    }
                }
            }
        }
        if !missing.is_empty() {
            return Err(RunError::BadInput(format!(
                "--only: inputs not in the cache: {}\n  help: run them first (`granrepro run --stage ID`) or share the cache directory",
                missing.join(", ")
            )));
        }
        p.stages
            .iter()
            .filter(|s| v.contains(&s.id))
            .map(|s| s.id.clone())
            .collect()
    } else {
        closure(p, &opts.targets)
            .map_err(|u| RunError::BadInput(format!("unknown stage(s): {} (see `granrepro list`)", u.join(", "))))?
    };
    let forced: HashSet<String> = if opts.force {
        let t = if !opts.only.is_empty() {
            &opts.only
        } else {
            &opts.targets
        };
        if t.is_empty() {
            set.iter().cloned().collect()
        } else {
            t.iter()
                .flat_map(|x| p.members(x).into_iter().map(str::to_string))
                .collect()
        }
    } else {
        HashSet::new()
    };

    let mut summary = RunSummary::default();
    if opts.dry_run {
        // what the committed results would serve, and what their partial entries force to
        // run (exactly as `prepare` decides before a real run)
        let serving = super::store::plan_serving(p, proj, &set, &keys, &forced)
            .map_err(|e| RunError::BadInput(format!("the committed results: {e:#}")))?;
        for id in &set {
            let key = keys[id].1.clone();
            let outcome = if forced.contains(id) {
                Outcome::WouldRun("forced".into())
            } else if let Some(super::store::Serving::Run(why, _)) = serving.get(id)
                && why != "never ran"
            {
                Outcome::WouldRun(why.clone())
            } else if let Some(super::store::Serving::Import { store, left_out, .. }) = serving.get(id) {
                Outcome::Served(if left_out.is_empty() {
                    format!("from {}", store.display())
                } else {
                    format!("from {}, partial: {} left out", store.display(), left_out.join(", "))
                })
            } else if proj.cache.verify(&proj.cache.entry_dir(&key), &key).is_ok() {
                Outcome::Cached
            } else {
                Outcome::WouldRun(
                    match std::fs::read(proj.state_file(&p.profile, id))
                        .ok()
                        .and_then(|b| serde_json::from_slice::<KeyRecord>(&b).ok())
                    {
                        Some(old) => stale_reasons(&old, &keys[id].0).join("; "),
                        None => "never ran".into(),
                    },
                )
            };
            summary.stages.push(StageReport {
                id: id.clone(),
                key,
                outcome,
            });
        }
        return Ok(summary);
    }

    proj.cache.sweep_stale(STALE_TMP_AGE);
    // The profile's committed results (`results/<profile>/`) serve as a second cache.
    super::store::prepare(p, proj, &set, &keys, &forced, opts.quiet)
        .map_err(|e| RunError::BadInput(format!("the committed results: {e:#}")))?;
    // Every entry this run reads or writes is marked in use before any is looked up and
    // until all are published, so a concurrent `clean` keeps them.
    let _in_use = proj.cache.hold(
        set.iter()
            .flat_map(|id| {
                let ins = p.get(id).unwrap().inputs.iter().flat_map(|(_, v)| v.iter());
                std::iter::once(id).chain(ins)
            })
            .map(|id| keys[id].1.as_str()),
    )?;
    let mp = MultiProgress::with_draw_target(if opts.quiet {
        ProgressDrawTarget::hidden()
    } else {
        ProgressDrawTarget::stderr()
    });
    let jobs = opts.jobs.max(1); // the CLI refuses 0
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let in_set: HashSet<&String> = set.iter().collect();
    let mut done: HashMap<String, bool> = HashMap::new(); // id -> ok
    // running stage -> threads of its pool
    let mut running: HashMap<String, usize> = HashMap::new();
    // input id -> how many times it was recomputed because it vanished from the cache
    let mut replanned: HashMap<String, usize> = HashMap::new();
    let (tx, rx) = mpsc::channel::<(String, Result<(f64, Vec<String>), StageError>)>();
    std::thread::scope(|scope| {
        loop {
            let mut progressed = false;
            let mut ready: Vec<&String> = Vec::new();
            for id in &set {
                if done.contains_key(id) || running.contains_key(id) {
                    continue;
                }
                let st = p.get(id).unwrap();
                let deps: Vec<&String> = st
                    .inputs
                    .iter()
                    .flat_map(|(_, v)| v.iter())
                    .filter(|d| in_set.contains(d))
                    .collect();
                if let Some(bad) = deps.iter().find(|d| done.get(**d) == Some(&false)) {
                    done.insert(id.clone(), false);
                    summary.stages.push(StageReport {
                        id: id.clone(),
                        key: keys[id].1.clone(),
                        outcome: Outcome::Skipped(format!("input `{bad}` failed")),
                    });
                    progressed = true;
                    continue;
                }
                if !deps.iter().all(|d| done.get(*d) == Some(&true)) {
                    continue;
                }
                let key = keys[id].1.clone();
                if !forced.contains(id) {
                    match proj.cache.lookup(&key) {
                        Lookup::Fresh(_) => {
                            write_state(proj, &p.profile, id, &keys[id].0);
                            done.insert(id.clone(), true);
                            summary.stages.push(StageReport {
                                id: id.clone(),
                                key,
                                outcome: Outcome::Cached,
                            });
                            if !opts.quiet {
                                say(&mp, format!("  cached  {id}"));
                            }
                            progressed = true;
                            continue;
                        }
                        Lookup::Corrupt(why) => {
                            say(
                                &mp,
                                format!("warning: cache entry of `{id}` was corrupt ({why}); recomputing"),
                            );
                        }
                        Lookup::Missing => {}
                    }
                }
                if running.len() + ready.len() < jobs {
                    ready.push(id);
                }
            }
            // Each stage runs in its own rayon pool: the cores not used by the stages
            // already running, shared equally by the stages starting now (at least one
            // thread each). Two small stages side by side then run single-threaded on
            // one core each instead of both waking a 2-thread pool at every parallel
            // region; a stage that runs alone gets every core. Results do not depend on
            // the thread count (bit-identical), only the wall time does.
            let mut free = cores.saturating_sub(running.values().sum::<usize>());
            for (k, id) in ready.iter().enumerate() {
                let id = *id;
                let threads = (free / (ready.len() - k)).max(1);
                free = free.saturating_sub(threads);
                let st = p.get(id).unwrap();
                running.insert(id.clone(), threads);
                progressed = true;
                let tx = tx.clone();
                let pb = mp.add(ProgressBar::new(1000));
                pb.set_style(
                    ProgressStyle::with_template("{prefix:>24} [{bar:30}] {percent:>3}% {elapsed_precise} ETA {eta}")
                        .unwrap()
                        .progress_chars("=> "),
                );
                pb.set_prefix(id.clone());
                let keys = &keys;
                let stage = st.clone();
                let replace = forced.contains(id);
                scope.spawn(move || {
                    let r = match rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .thread_name(|i| format!("stage-worker-{i}"))
                        .build()
                    {
                        Ok(pool) => pool.install(|| run_one(p, proj, &stage, keys, pb.clone(), replace)),
                        Err(e) => Err(StageError::Failed(format!(
                            "cannot start a thread pool of {threads} thread(s): {e}"
                        ))),
                    };
                    pb.finish_and_clear();
                    let _ = tx.send((stage.id.clone(), r));
                });
            }
            if running.is_empty() && !progressed {
                break;
            }
            if !running.is_empty() && !progressed {
                let (id, r) = rx.recv().expect("worker channel");
                running.remove(&id);
                let key = keys[&id].1.clone();
                // The stage's failure message, if it failed (recorded once, below).
                let failure = match r {
                    Ok((wall_s, changed)) => {
                        if !opts.quiet {
                            say(&mp, format!("  ran     {id}  ({wall_s:.2} s)"));
                        }
                        if !changed.is_empty() {
                            // Deterministic stages reproduce their entry byte for byte; a
                            // difference is a code change without a version bump, or a
                            // stage whose outputs hold measured times (work-precision).
                            say(
                                &mp,
                                format!(
                                    "  note    {id}: the forced re-run replaced its cache entry; files that differ from the old one: {}",
                                    changed.join(", ")
                                ),
                            );
                        }
                        done.insert(id.clone(), true);
                        summary.stages.push(StageReport {
                            id: id.clone(),
                            key: key.clone(),
                            outcome: Outcome::Ran { wall_s },
                        });
                        None
                    }
                    Err(StageError::InputGone { input, why }) => {
                        // Another process removed an input entry between planning and
                        // reading: plan that input again (recomputed unless someone has
                        // put it back meanwhile); this stage waits for it once more.
                        let n = replanned.entry(input.clone()).or_insert(0);
                        *n += 1;
                        let (n, again) = (*n, in_set.contains(&input) && *n <= MAX_REPLANS);
                        let msg = format!(
                            "input `{input}` (key {}) vanished from the cache while this run needed it ({why})",
                            keys[&input].1
                        );
                        if again {
                            say(&mp, format!("  note    {id}: {msg}; recomputing it"));
                            if done.remove(&input).is_some() {
                                summary.stages.retain(|s| s.id != input);
                            }
                            None
                        } else if in_set.contains(&input) {
                            Some(format!(
                                "{msg}, {n} times; another process keeps removing it (a `granrepro clean` on a filesystem without working flock, or by hand)"
                            ))
                        } else {
                            Some(format!(
                                "{msg}; run it again (`granrepro run --stage {input}`) and then this stage"
                            ))
                        }
                    }
                    Err(StageError::Failed(msg)) => Some(msg),
                };
                if let Some(msg) = failure {
                    say(&mp, format!("  FAILED  {id}: {msg}"));
                    done.insert(id.clone(), false);
                    summary.stages.push(StageReport {
                        id,
                        key,
                        outcome: Outcome::Failed(msg),
                    });
                }
            }
        }
    });
    publish_all(p, proj, &mut summary, &mp, opts.quiet)?;
    Ok(summary)
}

/// Withdraw the outputs of stages no longer in the pipeline, publish every stage with a
/// valid entry (each as one set), withdraw the outputs of failed or skipped stages
/// (nothing stale stays on show), then rebuild the index from the pipeline's stage list.
/// A stage whose entry has vanished since it ran (removed by a process ignoring the locks)
/// is marked failed, and withdrawn.
fn publish_all(
    p: &Pipeline,
    proj: &Project,
    summary: &mut RunSummary,
    mp: &MultiProgress,
    quiet: bool,
) -> Result<(), RunError> {
    let dir = proj.report_dir(&p.profile);
    publish::sweep_stale(&dir, STALE_TMP_AGE);
    let ids: HashSet<&str> = p.stages.iter().map(|s| s.id.as_str()).collect();
    for gone in publish::drop_removed(&dir, &ids)? {
        if !quiet {
            say(
                mp,
                format!("  removed the reports of `{gone}` (no longer in {})", p.path.display()),
            );
        }
    }
    // Measured errors for the figures: the atlas stage's table (a kind that declares
    // `atlas`), from this run's entry, else as last published.
    let atlas = p.atlas();
    let errors = atlas
        .and_then(|(id, table)| {
            let done = |r: &&StageReport| matches!(r.outcome, Outcome::Cached | Outcome::Ran { .. });
            let entry = summary.stages.iter().filter(done).find(|r| r.id == id);
            entry
                .and_then(|r| std::fs::read_to_string(proj.cache.entry_dir(&r.key).join(format!("{table}.csv"))).ok())
                .or_else(|| std::fs::read_to_string(dir.join(format!("{id}-{table}.csv"))).ok())
        })
        .map(|t| crate::report::measured::parse_profile_csv(&t))
        .unwrap_or_default();
    let methods = publish::stage_methods(p);
    let measured = publish::Measured {
        methods: &methods,
        profile: &p.profile,
        errors: &errors,
        atlas: atlas.map(|a| a.0),
    };
    for r in &mut summary.stages {
        if matches!(r.outcome, Outcome::Cached | Outcome::Ran { .. }) {
            // Only a process ignoring the cache's locks removes an entry this run holds.
            if let Err(why) = proj.cache.present(&r.key) {
                let msg = format!(
                    "its cache entry vanished before it was published ({why}): another process removed it; run again"
                );
                say(mp, format!("  FAILED  {}: {msg}", r.id));
                r.outcome = Outcome::Failed(msg);
            }
        }
        match r.outcome {
            Outcome::Cached | Outcome::Ran { .. } => {
                let overrides = p.get(&r.id).map(|s| s.overrides.as_slice()).unwrap_or(&[]);
                publish::publish(&proj.cache, &dir, &r.id, &r.key, overrides, Some(&measured))?;
            }
            Outcome::Failed(_) | Outcome::Skipped(_) => {
                if !publish::unpublish(&dir, &r.id)?.is_empty() {
                    say(
                        mp,
                        format!(
                            "  withdrew the previous reports of `{}` (it did not complete; its old results stay in the cache)",
                            r.id
                        ),
                    );
                }
            }
            Outcome::WouldRun(_) | Outcome::Served(_) => {}
        }
    }
    if dir.is_dir() {
        let all: Vec<String> = p.stages.iter().map(|s| s.id.clone()).collect();
        // The claims ledger judged once on what is published, for the index, claims.json
        // and claims.csv; and on the committed paper results, for the headline table.
        let judged = crate::claims::evaluate_dir(p, &dir);
        if let Some(j) = &judged {
            crate::report::ledger::write_files(&dir, j)?;
        }
        let committed = p.root.join("results/paper");
        let paper = (p.profile != "paper" && committed.is_dir())
            .then(|| crate::pipeline::load(&p.path, "paper", &[]).ok())
            .flatten()
            .and_then(|pp| super::store::fresh_judged(&pp, &committed));
        crate::report::html::write_index_of(
            &dir,
            &p.profile,
            &all,
            judged.as_deref(),
            paper.as_deref(),
            p.atlas(),
            &Default::default(),
            &crate::pipeline::publish::stage_methods(p),
        )?;
    }
    Ok(())
}

/// Print a line above the progress bars, or plainly to stderr when they are hidden.
fn say(mp: &MultiProgress, msg: String) {
    if mp.is_hidden() {
        eprintln!("{msg}");
    } else {
        let _ = mp.println(msg);
    }
}

fn write_state(proj: &Project, profile: &str, id: &str, rec: &KeyRecord) {
    if let Ok(b) = serde_json::to_vec_pretty(rec) {
        let _ = write_atomic(&proj.state_file(profile, id), &b);
    }
}

/// How often a run recomputes one input entry that vanished from the cache under it
/// before it gives up on the stages that need it.
pub const MAX_REPLANS: usize = 3;

/// Why [`run_one`] did not produce an entry.
enum StageError {
    /// The stage failed; the message.
    Failed(String),
    /// An input's entry was no longer complete when the stage read it (removed by
    /// another process): the input's id, and what was wrong with the entry.
    InputGone { input: String, why: String },
}

/// Run one stage and store its entry; the wall time and, for a forced re-run (`replace`),
/// the files whose bytes differ from the entry it replaced.
fn run_one(
    p: &Pipeline,
    proj: &Project,
    st: &Stage,
    keys: &HashMap<String, (KeyRecord, String)>,
    pb: ProgressBar,
    replace: bool,
) -> Result<(f64, Vec<String>), StageError> {
    let (rec, key) = &keys[&st.id];
    // The first input whose entry is no longer complete, if any.
    let gone = || {
        st.inputs.iter().flat_map(|(_, ids)| ids.iter()).find_map(|id| {
            let why = proj.cache.present(&keys[id].1).err()?;
            Some(StageError::InputGone { input: id.clone(), why })
        })
    };
    if let Some(g) = gone() {
        return Err(g);
    }
    // Clear the old state first so an interrupted run can never look fresh.
    let _ = std::fs::remove_file(proj.state_file(&p.profile, &st.id));
    let kind = p.kinds[st.kind.as_str()];
    let mut inputs: BTreeMap<String, Vec<InputRef>> = BTreeMap::new();
    for (role, ids) in &st.inputs {
        let v = ids
            .iter()
            .map(|id| InputRef {
                id: id.clone(),
                dir: proj.cache.entry_dir(&keys[id].1),
                params: p.get(id).unwrap().params.clone(),
            })
            .collect();
        inputs.insert(role.clone(), v);
    }
    let ctx = StageCtx {
        id: st.id.clone(),
        profile: p.profile.clone(),
        caption: st.caption.clone(),
        params: st.params.clone(),
        inputs,
        progress: pb,
        threads: rayon::current_num_threads(),
    };
    let started = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0);
    let t0 = Instant::now();
    let res = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| (kind.run)(&ctx)));
    let wall_s = t0.elapsed().as_secs_f64();
    let mut out: Output = match res {
        Ok(Ok(o)) => o,
        // A stage that failed because an input vanished while it read it is run again.
        Ok(Err(e)) => return Err(gone().unwrap_or_else(|| StageError::Failed(format!("{e:#}")))),
        Err(panic) => {
            let msg = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "panic".into());
            return Err(gone().unwrap_or_else(|| StageError::Failed(format!("internal error (panic): {msg}"))));
        }
    };
    // A kind publishes only what it declares: what a plot or ledger row was checked against.
    super::reads::require_declared(&kind, &out).map_err(StageError::Failed)?;
    let input_hashes: Vec<Value> = st
        .inputs
        .iter()
        .flat_map(|(role, ids)| ids.iter().map(move |id| (role, id)))
        .map(|(role, id)| serde_json::json!({"role": role, "id": id, "key": keys[id].1, "manifest_blake3": proj.cache.manifest_hash(&keys[id].1)}))
        .collect();
    let record = serde_json::json!({
        "stage": st.id, "kind": st.kind, "solver_version": st.version, "key": key,
        "profile": p.profile, "params": rec.params, "inputs": input_hashes,
        "wall_s": wall_s, "threads": ctx.threads, "started_unix_s": started,
        "granrepro_version": env!("CARGO_PKG_VERSION"), "caption": st.caption, "notes": out.notes,
        // The source files this entry was computed by (the kind's closure in this build):
        // `keep` locks these, not the keeping binary's, so a result kept by a later build
        // of changed code is still reported as built from the code that made it.
        "sources": crate::provenance::sources::closure(kind.source),
    });
    let (_, changed) = proj
        .cache
        .store(key, &st.id, &p.profile, &mut out, &record, replace)
        .map_err(|e| StageError::Failed(format!("cannot write the cache entry: {e:#}")))?;
    write_state(proj, &p.profile, &st.id, rec);
    Ok((wall_s, changed))
}
