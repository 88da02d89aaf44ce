//! Cache contract: a changed parameter re-runs exactly its dependants; everything else is
//! served from the cache; a corrupt or partial entry is recomputed, never used.

mod common;
use common::{SMALL, TempProject, opts, sorted};
use granrepro::pipeline::{Override, Project, RunOptions, load, run::run};

#[test]
fn changing_one_param_reruns_exactly_its_dependants() {
    let t = TempProject::new(SMALL);
    let proj = Project::new(t.path());
    let p = load(&t.pipeline(), "quick", &[]).unwrap();
    let s1 = run(&p, &proj, &opts()).unwrap();
    assert_eq!(sorted(s1.ran()), ["fig-a", "laws", "psd-a", "psd-b", "tab"]);
    // Same inputs: everything cached.
    let s2 = run(&p, &proj, &opts()).unwrap();
    assert!(s2.ran().is_empty(), "{:?}", s2.ran());
    assert_eq!(s2.cached().len(), 5);
    // Change psd-a's seed through --set: psd-a, fig-a and tab re-run; psd-b and laws do not.
    let sets = vec![Override::parse("psd-a.seed=3").unwrap()];
    let p2 = load(&t.pipeline(), "quick", &sets).unwrap();
    let s3 = run(&p2, &proj, &opts()).unwrap();
    assert_eq!(sorted(s3.ran()), ["fig-a", "psd-a", "tab"]);
    assert_eq!(sorted(s3.cached()), ["laws", "psd-b"]);
    // The run records say so too: fig-a's record names the new psd-a key.
    let rec: serde_json::Value =
        serde_json::from_slice(&std::fs::read(t.path().join("reports/quick/fig-a.record.json")).unwrap()).unwrap();
    let psd_key = s3.stages.iter().find(|s| s.id == "psd-a").unwrap().key.clone();
    assert_eq!(rec["inputs"][0]["key"].as_str().unwrap(), psd_key);
    // A different profile is a different key.
    let pq = load(&t.pipeline(), "paper", &[]).unwrap();
    let s4 = run(
        &pq,
        &proj,
        &RunOptions {
            targets: vec!["laws".into()],
            ..opts()
        },
    )
    .unwrap();
    assert_eq!(s4.ran(), ["laws"]);
}

#[test]
fn status_names_the_changed_param() {
    let t = TempProject::new(SMALL);
    let proj = Project::new(t.path());
    let p = load(&t.pipeline(), "quick", &[]).unwrap();
    run(&p, &proj, &opts()).unwrap();
    let sets = vec![Override::parse("psd-a.n=301").unwrap()];
    let p2 = load(&t.pipeline(), "quick", &sets).unwrap();
    let st = granrepro::pipeline::run::status(&p2, &proj);
    let get = |id: &str| st.iter().find(|(i, _)| i == id).unwrap().1.clone();
    use granrepro::pipeline::run::Freshness;
    match get("psd-a") {
        Freshness::Stale(r) => assert!(r.iter().any(|l| l.contains("params.n changed (300 → 301)")), "{r:?}"),
        other => panic!("{other:?}"),
    }
    match get("fig-a") {
        Freshness::Stale(r) => assert!(r.iter().any(|l| l.contains("input `psd-a` changed")), "{r:?}"),
        other => panic!("{other:?}"),
    }
    assert!(matches!(get("psd-b"), Freshness::Fresh));
}

#[test]
fn corrupt_entry_is_recomputed() {
    let t = TempProject::new(SMALL);
    let proj = Project::new(t.path());
    let p = load(&t.pipeline(), "quick", &[]).unwrap();
    let s1 = run(
        &p,
        &proj,
        &RunOptions {
            targets: vec!["fig-a".into()],
            ..opts()
        },
    )
    .unwrap();
    let key = s1.stages.iter().find(|s| s.id == "psd-a").unwrap().key.clone();
    let entry = proj.cache.entry_dir(&key);
    // Flip bytes in an artifact.
    let pq = entry.join("table.parquet");
    let mut bytes = std::fs::read(&pq).unwrap();
    let n = bytes.len();
    bytes[n / 2] ^= 0xff;
    std::fs::write(&pq, bytes).unwrap();
    let s2 = run(
        &p,
        &proj,
        &RunOptions {
            targets: vec!["fig-a".into()],
            ..opts()
        },
    )
    .unwrap();
    assert!(s2.ran().contains(&"psd-a"), "corrupt psd-a was reused: {:?}", s2.stages);
    assert!(proj.cache.verify(&entry, &key).is_ok());
    // Same numbers as before: the stage is deterministic.
    let a = std::fs::read(t.path().join("reports/quick/psd-a.csv")).unwrap();
    let s3 = run(
        &p,
        &proj,
        &RunOptions {
            targets: vec!["psd-a".into()],
            force: true,
            ..opts()
        },
    )
    .unwrap();
    assert_eq!(s3.ran(), ["psd-a"]);
    assert_eq!(a, std::fs::read(t.path().join("reports/quick/psd-a.csv")).unwrap());
}

/// `--force` recomputes and replaces the entry. An entry complete by its manifest but made
/// by other code (here: a table edited and the manifest re-hashed) must not survive a
/// forced re-run; before the fix the fresh result was dropped in favour of the old entry,
/// so a "forced re-run, outputs compared" check compared the cache with itself.
#[test]
fn forced_run_replaces_a_complete_entry() {
    let t = TempProject::new(SMALL);
    let proj = Project::new(t.path());
    let p = load(&t.pipeline(), "quick", &[]).unwrap();
    let s1 = run(
        &p,
        &proj,
        &RunOptions {
            targets: vec!["psd-a".into()],
            ..opts()
        },
    )
    .unwrap();
    let entry = proj.cache.entry_dir(&s1.stages[0].key);
    let fresh = std::fs::read(entry.join("table.csv")).unwrap();
    let edited = [fresh.as_slice(), b"0.5\n"].concat();
    std::fs::write(entry.join("table.csv"), &edited).unwrap();
    let mpath = entry.join("manifest.json");
    let mut m: serde_json::Value = serde_json::from_slice(&std::fs::read(&mpath).unwrap()).unwrap();
    m["files"]["table.csv"] = blake3::hash(&edited).to_hex().to_string().into();
    std::fs::write(&mpath, serde_json::to_vec_pretty(&m).unwrap()).unwrap();
    assert!(
        proj.cache.verify(&entry, &s1.stages[0].key).is_ok(),
        "the edited entry is complete"
    );
    // Unforced: the complete entry is reused as it is.
    let s2 = run(
        &p,
        &proj,
        &RunOptions {
            targets: vec!["psd-a".into()],
            ..opts()
        },
    )
    .unwrap();
    assert_eq!(s2.cached(), ["psd-a"]);
    assert_eq!(std::fs::read(entry.join("table.csv")).unwrap(), edited);
    // Forced: recomputed and put in place of the old entry.
    let s3 = run(
        &p,
        &proj,
        &RunOptions {
            targets: vec!["psd-a".into()],
            force: true,
            ..opts()
        },
    )
    .unwrap();
    assert_eq!(s3.ran(), ["psd-a"]);
    assert_eq!(std::fs::read(entry.join("table.csv")).unwrap(), fresh);
    assert_eq!(std::fs::read(t.path().join("reports/quick/psd-a.csv")).unwrap(), fresh);
    assert!(proj.cache.verify(&entry, &s1.stages[0].key).is_ok());
}

#[test]
fn killed_run_leaves_nothing_taken_as_valid() {
    let t = TempProject::new(SMALL);
    let proj = Project::new(t.path());
    let p = load(&t.pipeline(), "quick", &[]).unwrap();
    let s1 = run(
        &p,
        &proj,
        &RunOptions {
            targets: vec!["psd-a".into()],
            ..opts()
        },
    )
    .unwrap();
    let key = s1.stages[0].key.clone();
    let fig_key = granrepro::pipeline::run::key_records(&p)["fig-a"].1.clone();
    // What a kill between writing artifacts and the manifest would leave: (a) a temp
    // directory (never an entry), (b) an entry directory without its manifest.
    std::fs::create_dir_all(proj.cache.root().join(format!(".tmp-{fig_key}-x"))).unwrap();
    let partial = proj.cache.entry_dir(&fig_key);
    std::fs::create_dir_all(&partial).unwrap();
    std::fs::write(partial.join("table.csv"), "d_mm\n1.0\n").unwrap();
    let s2 = run(
        &p,
        &proj,
        &RunOptions {
            targets: vec!["fig-a".into()],
            ..opts()
        },
    )
    .unwrap();
    assert_eq!(s2.ran(), ["fig-a"], "{:?}", s2.stages);
    assert_eq!(s2.cached(), ["psd-a"]);
    assert!(proj.cache.verify(&partial, &fig_key).is_ok());
    assert!(proj.cache.verify(&proj.cache.entry_dir(&key), &key).is_ok());
}

#[test]
fn only_runs_one_stage_from_the_cache_or_refuses() {
    let t = TempProject::new(SMALL);
    // Nothing cached: --only fig-a must refuse with exit 2 naming the missing input.
    let (code, _, err) = t.cli(&["run", "--only", "fig-a", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("psd-a"), "{err}");
    let (code, _, err) = t.cli(&["run", "--stage", "psd-a", "--quiet"]);
    assert_eq!(code, 0, "{err}");
    let (code, out, err) = t.cli(&["run", "--only", "fig-a", "--quiet"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("1 ran, 0 cached"), "{out}");
}

#[test]
fn results_are_identical_whatever_the_job_count() {
    let t1 = TempProject::new(SMALL);
    let t2 = TempProject::new(SMALL);
    let p1 = load(&t1.pipeline(), "quick", &[]).unwrap();
    let p2 = load(&t2.pipeline(), "quick", &[]).unwrap();
    run(
        &p1,
        &Project::new(t1.path()),
        &RunOptions {
            jobs: 1,
            quiet: true,
            ..Default::default()
        },
    )
    .unwrap();
    run(
        &p2,
        &Project::new(t2.path()),
        &RunOptions {
            jobs: 4,
            quiet: true,
            ..Default::default()
        },
    )
    .unwrap();
    for f in [
        "psd-a.parquet", "psd-a.csv", "fig-a.csv", "fig-a.svg", "tab.csv", "laws.parquet", "fig-a.json",
    ] {
        let a = std::fs::read(t1.path().join("reports/quick").join(f)).unwrap();
        let b = std::fs::read(t2.path().join("reports/quick").join(f)).unwrap();
        assert!(a == b, "{f} differs between --jobs 1 and --jobs 4");
    }
}
