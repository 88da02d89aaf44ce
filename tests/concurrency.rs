//! Contract: many processes, one cache. Concurrent `granrepro run`s and `clean`s on one
//! project all succeed; every run publishes its outputs; the cache holds only complete
//! entries and no temp directories; an input entry removed under a run is recomputed (a
//! bounded number of times, then the run fails naming it).
//!
//! Issue 8, finding 1: concurrent `granrepro run`s on one project must all succeed and
//! leave only complete entries and no temp directories.
//!
//! Root cause of the failure this guards against: `Cache::store` removed a finished entry
//! and renamed a new one over it while another process was reading it ("cannot write the
//! cache entry: Directory not empty", "input `psd-col` has no table").
//!
//! `clean` is one of those processes (issue 29, finding 4): a `clean` during a run keeps
//! the entries the run uses (and says so), and the run succeeds and publishes. Root cause
//! of that failure: `clean` removed every entry, temp directory and the `.locks`
//! directory without taking any lock, so the run's input vanished before it was published
//! ("cannot publish the cache entry …: manifest.json missing (partial entry)").

mod common;
use common::{SMALL, TempProject};
use granrepro::pipeline::{Output, Project, RunOptions, StageCtx, load, run::key_records};
use std::process::{Child, Command, Stdio};

fn spawn(t: &TempProject, args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_granrepro"))
        .arg("--pipeline")
        .arg(t.pipeline())
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Start every command at once; return the failures (command, exit code, stderr).
fn race(t: &TempProject, cmds: &[&[&str]]) -> Vec<String> {
    let children: Vec<(String, Child)> = cmds.iter().map(|c| (c.join(" "), spawn(t, c))).collect();
    children
        .into_iter()
        .filter_map(|(c, ch)| {
            let out = ch.wait_with_output().unwrap();
            (!out.status.success()).then(|| {
                format!(
                    "`{c}` exit {:?}: {}",
                    out.status.code(),
                    String::from_utf8_lossy(&out.stderr)
                )
            })
        })
        .collect()
}

/// Every entry of the pipeline that exists is complete, and nothing temporary is left.
fn assert_cache_sound(t: &TempProject) {
    let proj = Project::new(t.path());
    let p = load(&t.pipeline(), "quick", &[]).unwrap();
    for (id, (_, key)) in key_records(&p) {
        let dir = proj.cache.entry_dir(&key);
        if dir.exists() {
            assert!(proj.cache.verify(&dir, &key).is_ok(), "entry of {id} is not complete");
        }
    }
    let leftovers: Vec<String> = std::fs::read_dir(proj.cache.root())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.starts_with(".tmp-") || n.starts_with(".trash-"))
        .collect();
    assert!(leftovers.is_empty(), "left behind: {leftovers:?}");
}

const ROUNDS: usize = 10;

#[test]
fn two_processes_on_an_empty_cache() {
    let mut failures = Vec::new();
    for _ in 0..ROUNDS {
        let t = TempProject::new(SMALL);
        failures.extend(race(
            &t,
            &[
                &["run", "--stage", "fig-a", "--quiet"],
                &["run", "--stage", "fig-a", "--quiet"],
            ],
        ));
        assert_cache_sound(&t);
    }
    assert!(
        failures.is_empty(),
        "{} of {} runs failed:\n{}",
        failures.len(),
        2 * ROUNDS,
        failures.join("\n")
    );
}

#[test]
fn two_forced_processes_on_a_warm_cache() {
    let t = TempProject::new(SMALL);
    let (code, _, err) = t.cli(&["run", "--stage", "fig-a", "--quiet"]);
    assert_eq!(code, 0, "{err}");
    let mut failures = Vec::new();
    for _ in 0..ROUNDS {
        let force: &[&str] = &["run", "--stage", "fig-a", "--force", "--quiet"];
        failures.extend(race(&t, &[force, force]));
    }
    assert_cache_sound(&t);
    assert!(
        failures.is_empty(),
        "{} of {} runs failed:\n{}",
        failures.len(),
        2 * ROUNDS,
        failures.join("\n")
    );
}

#[test]
fn four_processes_sharing_an_input() {
    let mut failures = Vec::new();
    for _ in 0..ROUNDS {
        let t = TempProject::new(SMALL);
        failures.extend(race(
            &t,
            &[
                &["run", "--stage", "fig-a", "--quiet"],
                &["run", "--stage", "tab", "--quiet"],
                &["run", "--stage", "fig-a", "--force", "--quiet"],
                &["run", "--stage", "tab", "--force", "--quiet", "--jobs", "2"],
            ],
        ));
        assert_cache_sound(&t);
    }
    assert!(
        failures.is_empty(),
        "{} of {} runs failed:\n{}",
        failures.len(),
        4 * ROUNDS,
        failures.join("\n")
    );
}

/// Finding 8: a reader that resolves a stage's published set sees the files of one run,
/// while two runs with different parameters publish over each other.
#[test]
fn a_reader_never_sees_files_of_two_runs() {
    let t = TempProject::new(SMALL);
    // The two sets the writers publish, made one at a time first.
    let mut sets = Vec::new();
    for seed in ["1", "2"] {
        let (code, _, err) = t.cli(&[
            "run",
            "--stage",
            "psd-a",
            "--quiet",
            "--set",
            &format!("psd-a.seed={seed}"),
        ]);
        assert_eq!(code, 0, "{err}");
        let dir = t.path().join("reports/quick");
        sets.push((
            std::fs::read(dir.join("psd-a.csv")).unwrap(),
            std::fs::read(dir.join("psd-a.json")).unwrap(),
        ));
    }
    assert_ne!(sets[0].0, sets[1].0);
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let reader = {
        let stop = stop.clone();
        let root = t.path().join("reports/quick/.sets");
        let sets = sets.clone();
        std::thread::spawn(move || {
            let (mut reads, mut mixed) = (0, 0);
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                // The documented way to read a consistent set: resolve the pointer once.
                let Ok(target) = std::fs::read_link(root.join("psd-a")) else {
                    continue;
                };
                let dir = root.join(target);
                let (Ok(csv), Ok(json)) = (
                    std::fs::read(dir.join("psd-a.csv")),
                    std::fs::read(dir.join("psd-a.json")),
                ) else {
                    continue;
                };
                reads += 1;
                if !sets.iter().any(|(c, j)| *c == csv && *j == json) {
                    mixed += 1;
                }
            }
            (reads, mixed)
        })
    };
    for i in 0..ROUNDS {
        let seed = if i % 2 == 0 { "1" } else { "2" };
        let a = spawn(
            &t,
            &[
                "run",
                "--stage",
                "psd-a",
                "--quiet",
                "--set",
                &format!("psd-a.seed={seed}"),
            ],
        );
        let b = spawn(
            &t,
            &[
                "run",
                "--stage",
                "psd-a",
                "--quiet",
                "--set",
                &format!("psd-a.seed={}", if seed == "1" { "2" } else { "1" }),
            ],
        );
        for ch in [a, b] {
            let out = ch.wait_with_output().unwrap();
            assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        }
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let (reads, mixed) = reader.join().unwrap();
    assert!(reads > 0, "the reader never saw a published set");
    assert_eq!(mixed, 0, "{mixed} of {reads} reads mixed two runs");
}

/// A short DEM chain as in `fig4-02`: PSD → column preparation (about a second) →
/// snapshot, with the repository's own parameter files.
fn column_project() -> TempProject {
    let t = TempProject::new(
        r#"version: 1
stages:
  - id: psd
    kind: psd
    params_file: psd-col.yaml
  - id: prep
    kind: dem-column-prep
    params_file: [dem=dem-column.yaml, col-dem-prep.yaml]
    params: { a: 0.8, area_m2: AREA }
    inputs: { psd: psd }
  - id: snap
    kind: dem-snapshot
    params: { colour_by_size: false, gate: true }
    inputs: { column: prep }
"#
        .replace("AREA", "2.5e-4")
        .as_str(),
    );
    t.write("psd-col.yaml", include_str!("../stages/psd-col.yaml"));
    t.write("dem-column.yaml", include_str!("../stages/dem-column.yaml"));
    t.write("col-dem-prep.yaml", include_str!("../stages/col-dem-prep.yaml"));
    t
}

/// Wait until the run has put a first entry in the cache (or has exited).
fn wait_for_an_entry(t: &TempProject, run: &mut Child) {
    let root = Project::new(t.path()).cache.root().to_path_buf();
    let t0 = std::time::Instant::now();
    while t0.elapsed() < std::time::Duration::from_secs(120) && run.try_wait().unwrap().is_none() {
        let entries = std::fs::read_dir(&root)
            .into_iter()
            .flatten()
            .flatten()
            .any(|e| e.file_name().len() == 32);
        if entries {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

#[test]
fn a_clean_during_a_run_never_breaks_the_run() {
    let mut failures = Vec::new();
    let mut kept = 0;
    for round in 0..ROUNDS {
        let t = column_project();
        let mut run = spawn(&t, &["run", "--stage", "snap", "--quiet"]);
        // The PSD is in; the preparation is running. Land the clean at a different
        // moment of it each round.
        wait_for_an_entry(&t, &mut run);
        std::thread::sleep(std::time::Duration::from_millis(60 * round as u64));
        let (code, out, err) = t.cli(&["clean"]);
        if code != 0 {
            failures.push(format!("round {round}: `clean` exit {code}: {err}"));
        }
        kept += usize::from(out.contains("in use by a running granrepro"));
        let done = run.wait_with_output().unwrap();
        if !done.status.success() {
            failures.push(format!(
                "round {round}: `run --stage snap` exit {:?}: {}",
                done.status.code(),
                String::from_utf8_lossy(&done.stderr)
            ));
            continue;
        }
        for f in ["psd.json", "prep.json", "snap.json", "snap.svg"] {
            if std::fs::read(t.path().join("reports/quick").join(f)).is_err() {
                failures.push(format!("round {round}: reports/quick/{f} was not published"));
            }
        }
        assert_cache_sound(&t);
        // Once the run is over, a clean removes everything: no lock file is left behind.
        let (code, _, err) = t.cli(&["clean"]);
        assert_eq!(code, 0, "{err}");
        assert!(
            !t.path().join(".granrepro").exists(),
            "a clean after the run left files"
        );
    }
    assert!(
        failures.is_empty(),
        "{} failure(s):\n{}",
        failures.len(),
        failures.join("\n")
    );
    // Otherwise every clean missed the run and this test raced nothing.
    assert!(kept > 0, "no clean of {ROUNDS} found the run's entries in use");
}

/// How many more times the wrapped `psd-figure` removes its input entry before it reads it.
static REMOVALS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// `psd-figure`, except that it first removes its input's cache entry (as a process
/// ignoring the cache's locks would) while `REMOVALS` > 0.
fn psd_figure_losing_its_input(ctx: &StageCtx) -> anyhow::Result<Output> {
    let dec = |n: usize| n.checked_sub(1);
    if REMOVALS
        .fetch_update(
            std::sync::atomic::Ordering::SeqCst,
            std::sync::atomic::Ordering::SeqCst,
            dec,
        )
        .is_ok()
    {
        std::fs::remove_dir_all(&ctx.inputs["psd"][0].dir)?;
    }
    (granrepro::stages::registry()["psd-figure"].run)(ctx)
}

/// An input entry that vanishes between planning and reading is recomputed, and a run
/// whose input keeps vanishing fails saying so (after `MAX_REPLANS` recomputations).
#[test]
fn an_input_that_vanished_is_recomputed_a_bounded_number_of_times() {
    use granrepro::pipeline::run::{MAX_REPLANS, run};
    let opts = RunOptions {
        targets: vec!["fig-a".into()],
        jobs: 1,
        quiet: true,
        ..RunOptions::default()
    };
    for (removals, ok) in [(1, true), (MAX_REPLANS, true), (MAX_REPLANS + 1, false)] {
        let t = TempProject::new(SMALL);
        let mut p = load(&t.pipeline(), "quick", &[]).unwrap();
        p.kinds.get_mut("psd-figure").unwrap().run = psd_figure_losing_its_input;
        REMOVALS.store(removals, std::sync::atomic::Ordering::SeqCst);
        let summary = run(&p, &Project::new(t.path()), &opts).unwrap();
        assert_eq!(summary.failed(), !ok, "{removals} removal(s): {:?}", summary.stages);
        if ok {
            assert!(t.path().join("reports/quick/fig-a.svg").is_file());
            assert!(t.path().join("reports/quick/psd-a.json").is_file());
            assert_cache_sound(&t);
        } else {
            let msg = format!("{:?}", summary.stages);
            assert!(msg.contains("input `psd-a`"), "{msg}");
            assert!(msg.contains("vanished from the cache"), "{msg}");
            assert!(msg.contains(&format!("{} times", MAX_REPLANS + 1)), "{msg}");
        }
    }
}
