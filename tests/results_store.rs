//! Contract of the committed results (`results/<profile>/`, `granrepro keep`): they serve a
//! fresh cache as a read-only second cache, `status` says which are fresh, stale (which
//! input), built from changed code (which files) or corrupt (which file), a partial entry is
//! recomputed when a stage that must run reads it, and the repository's own committed
//! results match their lock and re-run byte for byte.

mod common;
use common::{SMALL, TempProject, opts, sorted};
use granrepro::pipeline::store::{self, Caps, Committed};
use granrepro::pipeline::{Override, Project, RunOptions, load, run::run};

/// SMALL run in the paper profile and kept under `results/paper/`.
fn kept(caps: Caps) -> TempProject {
    let t = TempProject::new(SMALL);
    let proj = Project::new(t.path());
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    run(&p, &proj, &opts()).unwrap();
    let k = store::keep(&p, &proj, caps, None).unwrap();
    assert_eq!(k.kept.len(), 5, "{k:?}");
    t
}

/// Keep `t` again under `caps` from an empty cache (another machine): every stage is
/// carried from the committed store.
fn rekept(t: &TempProject, caps: Caps) -> store::Kept {
    let empty = tempfile::tempdir().unwrap();
    let proj = Project::new(t.path()).with_cache(empty.path());
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    store::keep(&p, &proj, caps, None).unwrap()
}

fn state(p: &granrepro::pipeline::Pipeline, t: &TempProject, id: &str) -> Committed {
    let dir = store::dir_of(t.path(), "paper");
    let lock = store::read_lock(&dir).unwrap().unwrap();
    store::status(p, &dir, &lock)
        .into_iter()
        .find(|(i, _)| i == id)
        .unwrap()
        .1
}

#[test]
fn kept_results_serve_an_empty_cache_and_a_changed_param_reruns_exactly_its_dependants() {
    let t = kept(Caps::default());
    let dir = store::dir_of(t.path(), "paper");
    assert!(dir.join("index.html").is_file());
    let lock = store::read_lock(&dir).unwrap().unwrap();
    assert!(store::verify(&dir, &lock).is_empty());
    // A figure is committed once, in the store; the index shows that copy, and its stamped
    // published twin is listed (with its hash) as left out.
    let f = &lock.stages["fig-a"];
    let shown = format!("store/{}/figure.svg", f.key);
    assert!(dir.join(&shown).is_file() && !dir.join("fig-a.svg").exists());
    assert!(f.left_out.contains_key("fig-a.svg"), "{:?}", f.left_out);
    let index = std::fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(
        index.contains(&format!("<img src=\"{shown}\"")),
        "the index shows the store's figure"
    );
    // The run record is committed once too: the store's `record.json`, which the index
    // links and reads (wall, kind); the published twin is listed as left out.
    for id in ["fig-a", "psd-a", "tab"] {
        let l = &lock.stages[id];
        let twin = format!("{id}.record.json");
        assert!(!dir.join(&twin).exists() && l.left_out.contains_key(&twin), "{id}: {:?}", l.left_out);
        assert!(index.contains(&format!("<a href=\"store/{}/record.json\">run record</a>", l.key)), "{id}");
    }
    assert!(index.contains(" · kind psd-figure v"), "the index read the record from the store");
    // The CSV twin of a table is left out of the store (Parquet is what stages read).
    let l = &lock.stages["psd-a"];
    assert!(l.store.contains_key("table.parquet") && l.left_out.contains_key("store/table.csv"));
    assert!(l.complete() && l.sources.contains_key("src/stages/generic/psd.rs"));

    // Another machine: the same repository, an empty cache.
    let empty = tempfile::tempdir().unwrap();
    let proj = Project::new(t.path()).with_cache(empty.path());
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    for id in ["psd-a", "psd-b", "fig-a", "tab", "laws"] {
        assert_eq!(state(&p, &t, id), Committed::Fresh, "{id}");
    }
    let s = run(&p, &proj, &opts()).unwrap();
    assert!(s.ran().is_empty(), "ran {:?}", s.ran());
    assert_eq!(s.cached().len(), 5);
    assert!(
        t.path().join("reports/paper/fig-a.svg").exists(),
        "the figure is published from the store"
    );

    // A changed parameter: exactly its dependants are stale, and only they run.
    let sets = vec![Override::parse("psd-a.seed=3").unwrap()];
    let p2 = load(&t.pipeline(), "paper", &sets).unwrap();
    for id in ["psd-a", "fig-a", "tab"] {
        assert!(matches!(state(&p2, &t, id), Committed::Stale(_)), "{id}");
    }
    match state(&p2, &t, "fig-a") {
        Committed::Stale(r) => assert!(r.iter().any(|x| x.contains("input `psd-a` changed")), "{r:?}"),
        other => panic!("{other:?}"),
    }
    for id in ["psd-b", "laws"] {
        assert_eq!(state(&p2, &t, id), Committed::Fresh, "{id}");
    }
    let s2 = run(&p2, &proj, &opts()).unwrap();
    assert_eq!(sorted(s2.ran()), ["fig-a", "psd-a", "tab"]);
}

#[test]
fn a_hand_edited_result_is_detected_by_its_hash() {
    let t = kept(Caps::default());
    let f = store::dir_of(t.path(), "paper").join("psd-a.json");
    let mut text = std::fs::read_to_string(&f).unwrap();
    text = text.replacen('1', "2", 1);
    std::fs::write(&f, text).unwrap();
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    match state(&p, &t, "psd-a") {
        Committed::Corrupt(r) => assert!(r[0].contains("psd-a.json: content differs"), "{r:?}"),
        other => panic!("{other:?}"),
    }
    assert_eq!(state(&p, &t, "psd-b"), Committed::Fresh);
    let (code, out, err) = t.cli(&["status", "--profile", "paper"]);
    assert_eq!(code, 1, "{out}\n{err}");
    assert!(
        out.contains("CORRUPT  psd-a") && err.contains("restore"),
        "{out}\n{err}"
    );
    // and `keep` refuses to build on it
    let (code, _, err) = t.cli(&["keep", "--profile", "paper"]);
    assert_ne!(code, 0);
    assert!(err.contains("psd-a.json"), "{err}");
}

#[test]
fn a_result_built_from_changed_code_names_the_files_and_marks_its_dependants() {
    let t = kept(Caps::default());
    let dir = store::dir_of(t.path(), "paper");
    // As if psd.rs had changed since psd-a was kept: the lock holds an older hash.
    let mut lock = store::read_lock(&dir).unwrap().unwrap();
    lock.stages
        .get_mut("psd-a")
        .unwrap()
        .sources
        .insert("src/stages/generic/psd.rs".into(), "0".repeat(64));
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    let states = store::status(&p, &dir, &lock);
    let get = |id: &str| states.iter().find(|(i, _)| i == id).unwrap().1.clone();
    assert_eq!(
        get("psd-a"),
        Committed::ChangedCode(vec!["src/stages/generic/psd.rs".into()])
    );
    for id in ["fig-a", "tab"] {
        match get(id) {
            Committed::ChangedCode(r) => assert!(
                r.contains(&"input `psd-a` built from changed code".to_string()),
                "{r:?}"
            ),
            other => panic!("{id}: {other:?}"),
        }
    }
    assert_eq!(get("psd-b"), Committed::Fresh);
    assert_eq!(get("laws"), Committed::Fresh);
}

#[test]
fn a_partial_entry_serves_its_figure_but_is_recomputed_when_a_consumer_must_run() {
    // A cap that leaves psd-a's table out of the store.
    let t = kept(Caps {
        file: 64,
        csv: 64,
        ..Caps::default()
    });
    let lock = store::read_lock(&store::dir_of(t.path(), "paper")).unwrap().unwrap();
    assert!(!lock.stages["psd-a"].complete());
    let empty = tempfile::tempdir().unwrap();
    let proj = Project::new(t.path()).with_cache(empty.path());
    // Nothing needs psd-a's table: nothing runs.
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    assert!(run(&p, &proj, &opts()).unwrap().ran().is_empty());
    // fig-a's own setting changes: it must run, so psd-a's table is needed: psd-a runs too.
    let sets = vec![Override::parse("fig-a.curve_points=50").unwrap()];
    let p2 = load(&t.pipeline(), "paper", &sets).unwrap();
    let s = run(&p2, &proj, &opts()).unwrap();
    assert_eq!(sorted(s.ran()), ["fig-a", "psd-a"]);
}

/// CI: the repository's committed results match their lock (a hand-edited or corrupted
/// file fails here), and every stage they hold is still in the pipeline.
#[test]
fn the_repositorys_committed_results_match_their_lock() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for profile in ["paper", "quick"] {
        let dir = store::dir_of(root, profile);
        let Some(lock) = store::read_lock(&dir).unwrap() else {
            continue;
        };
        let bad = store::verify(&dir, &lock);
        assert!(bad.is_empty(), "{}:\n{}", dir.display(), bad.join("\n"));
        let p = load(&root.join("pipeline.yaml"), profile, &[]).unwrap();
        let gone: Vec<&String> = lock.stages.keys().filter(|id| p.get(id).is_none()).collect();
        assert!(gone.is_empty(), "kept stages no longer in the pipeline: {gone:?}");
        // every figure and link the committed index shows is a committed file
        let index = std::fs::read_to_string(dir.join("index.html")).unwrap();
        let missing: Vec<&str> = index
            .split("src=\"")
            .skip(1)
            .chain(index.split("href=\"").skip(1))
            .filter_map(|r| r.split('"').next())
            .filter(|f| !f.contains("://") && !f.starts_with('#') && !f.is_empty())
            .map(|f| f.split('#').next().unwrap())
            .filter(|f| !dir.join(f).exists())
            .collect();
        assert!(
            missing.is_empty(),
            "{}: the index names missing files: {missing:?}",
            dir.display()
        );
    }
}

/// The cheapest committed paper stages re-run from an empty cache in a copy of the
/// project give the committed store files byte for byte.
#[test]
fn committed_paper_stages_rerun_byte_for_byte() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = store::dir_of(root, "paper");
    let lock = store::read_lock(&dir)
        .unwrap()
        .expect("results/paper/lock.json: the paper profile's committed results (issue 28)");
    let t = TempProject::new(&std::fs::read_to_string(root.join("pipeline.yaml")).unwrap());
    copy_tree(&root.join("stages"), &t.path().join("stages"));
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    let proj = Project::new(t.path());
    let ids: Vec<String> = ["psd-col", "psd-pile", "laws"]
        .into_iter()
        .filter(|id| lock.stages.contains_key(*id))
        .map(String::from)
        .collect();
    assert!(!ids.is_empty(), "no cheap stage among the committed results");
    let s = run(
        &p,
        &proj,
        &RunOptions {
            targets: ids.clone(),
            ..opts()
        },
    )
    .unwrap();
    assert_eq!(sorted(s.ran()), sorted(ids.iter().map(String::as_str).collect()));
    for id in &ids {
        let l = &lock.stages[id];
        let key = &s.stages.iter().find(|r| &r.id == id).unwrap().key;
        assert_eq!(
            key, &l.key,
            "{id}: the committed result is stale (`granrepro status --profile paper`)"
        );
        for (name, h) in &l.store {
            if name == "record.json" || name == "manifest.json" {
                continue; // wall times
            }
            let got = blake3::hash(&std::fs::read(proj.cache.entry_dir(key).join(name)).unwrap());
            assert_eq!(&got.to_hex().to_string(), h, "{id}/{name}");
        }
    }
}

fn copy_tree(from: &std::path::Path, to: &std::path::Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        let (a, b) = (e.path(), to.join(e.file_name()));
        if a.is_dir() {
            copy_tree(&a, &b);
        } else {
            std::fs::copy(&a, &b).unwrap();
        }
    }
}

/// A re-keep that carries committed results whose key changed since (a parameter changed,
/// not yet re-run) marks them in the index as not current and lists them; before, the
/// index showed them, and judged claims on them, as current.
#[test]
fn a_rekeep_marks_carried_stale_results_as_not_current() {
    let t = kept(Caps::default());
    let empty = tempfile::tempdir().unwrap();
    let proj = Project::new(t.path()).with_cache(empty.path());
    let sets = vec![Override::parse("psd-a.seed=3").unwrap()];
    let p2 = load(&t.pipeline(), "paper", &sets).unwrap();
    let k = store::keep(&p2, &proj, Caps::default(), None).unwrap();
    assert!(k.kept.is_empty(), "{k:?}");
    assert_eq!(
        sorted(k.not_current.iter().map(String::as_str).collect()),
        ["fig-a", "psd-a", "tab"]
    );
    let index = std::fs::read_to_string(store::dir_of(t.path(), "paper").join("index.html")).unwrap();
    let marked = |id: &str| index.contains(&format!("<h3>{id}</h3><p class=\"fail\">Not current — stale"));
    assert!(marked("psd-a") && marked("fig-a") && marked("tab"), "{index}");
    assert!(!marked("psd-b") && !marked("laws"));
}

/// Two stages declared with the same work share one cache key (the paper profile's
/// calib-prep-a0.4 is col-dem-prep-a0.4): keep stores the entry once and locks both.
/// Before, the second copy failed with "File exists" and nothing was kept.
#[test]
fn two_stages_with_one_key_share_one_store_entry() {
    let t = TempProject::new(&format!(
        "{SMALL}  - id: psd-a-again\n    kind: psd\n    params: {{ n: 300, seed: 1 }}\n"
    ));
    let proj = Project::new(t.path());
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    run(&p, &proj, &opts()).unwrap();
    let k = store::keep(&p, &proj, Caps::default(), None).unwrap();
    assert_eq!(k.kept.len(), 6, "{k:?}");
    let dir = store::dir_of(t.path(), "paper");
    let lock = store::read_lock(&dir).unwrap().unwrap();
    assert_eq!(lock.stages["psd-a"].key, lock.stages["psd-a-again"].key);
    assert!(store::verify(&dir, &lock).is_empty());
    assert_eq!(state(&p, &t, "psd-a-again"), Committed::Fresh);
}

/// SMALL with an on-demand study: a `psd` stage and a figure of it, both `on_demand`.
fn with_study() -> String {
    format!(
        "{SMALL}  - id: study-psd\n    kind: psd\n    params: {{ n: 120, seed: 9 }}\n    on_demand: true\n  - id: study\n    kind: psd-figure\n    inputs: {{ psd: study-psd }}\n    on_demand: true\n"
    )
}

/// On-demand studies: left out of the whole run and the whole `keep`; run when named; kept
/// by `keep --stage` in `results/<study>/` under their own lock, which serves and is
/// checked as `results/<profile>/` is; a stage that is not on demand is refused there.
#[test]
fn an_on_demand_study_runs_when_named_and_is_kept_apart() {
    let t = TempProject::new(&with_study());
    let proj = Project::new(t.path());
    let p = load(&t.pipeline(), "quick", &[]).unwrap();
    let whole = run(&p, &proj, &opts()).unwrap();
    assert_eq!(sorted(whole.ran()), ["fig-a", "laws", "psd-a", "psd-b", "tab"]);
    let named = run(
        &p,
        &proj,
        &RunOptions {
            targets: vec!["study".into()],
            ..opts()
        },
    )
    .unwrap();
    assert_eq!(sorted(named.ran()), ["study", "study-psd"]);

    let k = store::keep(&p, &proj, Caps::default(), None).unwrap();
    assert!(!k.kept.iter().any(|id| id.starts_with("study")), "{k:?}");
    let k = store::keep(&p, &proj, Caps::default(), Some("study")).unwrap();
    assert_eq!(
        sorted(k.kept.iter().map(String::as_str).collect()),
        ["study", "study-psd"]
    );
    let dir = t.path().join("results/study");
    let lock = store::read_lock(&dir).unwrap().unwrap();
    assert_eq!(lock.profile, "quick");
    let fig = format!("store/{}/figure.svg", lock.stages["study"].key);
    assert!(store::verify(&dir, &lock).is_empty() && dir.join(fig).is_file());
    let dirs: Vec<_> = store::committed_dirs(&p).unwrap().into_iter().map(|d| d.0).collect();
    assert_eq!(dirs, [store::dir_of(t.path(), "quick"), dir.clone()]);
    assert!(store::keep(&p, &proj, Caps::default(), Some("psd-a")).is_err());

    // Another machine: the study is served from results/study/, nothing of it reruns.
    let empty = tempfile::tempdir().unwrap();
    let proj2 = Project::new(t.path()).with_cache(empty.path());
    let again = run(
        &p,
        &proj2,
        &RunOptions {
            targets: vec!["study".into()],
            ..opts()
        },
    )
    .unwrap();
    assert!(again.ran().is_empty(), "ran {:?}", again.ran());
}

/// A result is locked with the code that computed it, not the code that keeps it: the run
/// record holds the kind's source closure, and `keep` copies it. Before, `keep` stamped the
/// keeping binary's hashes, so an entry computed by an older build of changed code was
/// kept as fresh (seen after a formatting change to a kind's file).
#[test]
fn keep_locks_the_code_that_computed_an_entry_not_the_code_that_keeps_it() {
    let t = TempProject::new(SMALL);
    let proj = Project::new(t.path());
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    let s = run(&p, &proj, &opts()).unwrap();
    let key = &s.stages.iter().find(|r| r.id == "laws").unwrap().key;
    let entry = proj.cache.entry_dir(key);
    // As if `laws` had been computed by a build whose laws.rs differed from this one.
    let mut rec: serde_json::Value =
        serde_json::from_slice(&std::fs::read(entry.join("record.json")).unwrap()).unwrap();
    assert!(
        rec["sources"]["src/stages/generic/laws.rs"].is_string(),
        "the run record holds the kind's source closure"
    );
    rec["sources"]["src/stages/generic/laws.rs"] = serde_json::json!("0".repeat(64));
    let bytes = serde_json::to_vec_pretty(&rec).unwrap();
    std::fs::write(entry.join("record.json"), &bytes).unwrap();
    let mut man: serde_json::Value =
        serde_json::from_slice(&std::fs::read(entry.join("manifest.json")).unwrap()).unwrap();
    man["record"] = serde_json::json!(blake3::hash(&bytes).to_hex().to_string());
    std::fs::write(entry.join("manifest.json"), serde_json::to_vec_pretty(&man).unwrap()).unwrap();

    store::keep(&p, &proj, Caps::default(), None).unwrap();
    assert_eq!(
        state(&p, &t, "laws"),
        Committed::ChangedCode(vec!["src/stages/generic/laws.rs".into()])
    );
    assert_eq!(state(&p, &t, "psd-a"), Committed::Fresh);
}

/// The CSV cap applies to results carried from an earlier keep too: a re-keep from an
/// empty cache under a smaller cap moves each published CSV over it to the lock's left-out
/// list (hash kept), the lock still verifies, and the index links the table's Parquet in
/// the store instead. Before, carried files were copied whatever the cap, so lowering it
/// never shrank what was already committed.
#[test]
fn a_rekeep_applies_the_csv_cap_to_carried_results() {
    let t = kept(Caps::default());
    let dir = store::dir_of(t.path(), "paper");
    let csv = dir.join("psd-a.csv");
    let size = std::fs::metadata(&csv).unwrap().len();
    assert!(size > 1024, "the test needs psd-a.csv over 1 KB: {size}");
    let k = rekept(
        &t,
        Caps {
            csv: 1024,
            ..Caps::default()
        },
    );
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    assert!(k.kept.is_empty() && k.carried.len() == 5, "{k:?}");
    assert!(
        !csv.exists(),
        "psd-a.csv ({size} B) is over the 1 KB cap and must be left out"
    );
    let lock = store::read_lock(&dir).unwrap().unwrap();
    assert!(lock.stages["psd-a"].left_out.contains_key("psd-a.csv"));
    assert!(!lock.stages["psd-a"].published.contains_key("psd-a.csv"));
    assert!(store::verify(&dir, &lock).is_empty());
    assert_eq!(state(&p, &t, "psd-a"), Committed::Fresh);
    let index = std::fs::read_to_string(dir.join("index.html")).unwrap();
    let key = &lock.stages["psd-a"].key;
    assert!(
        index.contains(&format!("store/{key}/table.parquet\">table (Parquet)")),
        "{index}"
    );
}

/// A dry run says what a real run would do with the committed results: the stages they
/// serve, and those their partial entries force to run (with the consumer that needs them).
/// Before, the dry run looked at the cache only and listed every committed stage as "would
/// run (never ran)" on a fresh clone.
#[test]
fn a_dry_run_reports_what_the_committed_results_serve_and_what_must_run() {
    use granrepro::pipeline::run::Outcome;
    let t = kept(Caps {
        file: 64,
        csv: 64,
        ..Caps::default()
    });
    let empty = tempfile::tempdir().unwrap();
    let proj = Project::new(t.path()).with_cache(empty.path());
    let dry = RunOptions {
        dry_run: true,
        ..opts()
    };
    let outcome = |p: &granrepro::pipeline::Pipeline, id: &str| {
        run(p, &proj, &dry)
            .unwrap()
            .stages
            .into_iter()
            .find(|s| s.id == id)
            .unwrap()
            .outcome
    };
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    assert!(matches!(outcome(&p, "psd-b"), Outcome::Served(ref w) if w.contains("store")));
    assert!(matches!(outcome(&p, "psd-a"), Outcome::Served(ref w) if w.contains("partial")));
    let sets = vec![Override::parse("fig-a.curve_points=50").unwrap()];
    let p2 = load(&t.pipeline(), "paper", &sets).unwrap();
    assert!(matches!(outcome(&p2, "psd-a"), Outcome::WouldRun(ref w) if w.contains("fig-a")));
    // and the dry run changed nothing: the real run still serves psd-b
    let s = run(&p2, &proj, &opts()).unwrap();
    assert_eq!(sorted(s.ran()), ["fig-a", "psd-a"]);
}

/// A forced re-run that reproduces an entry byte for byte, by code other than the code that
/// made it, replaces the entry's record of which code built it (what the committed results'
/// lock reads). Before, the identical entry was kept with its old record, so a result
/// re-run by the committed code still read "built from changed code".
#[test]
fn a_forced_rerun_by_other_code_refreshes_the_record_of_what_built_it() {
    let t = TempProject::new(SMALL);
    let proj = Project::new(t.path());
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    let s = run(&p, &proj, &opts()).unwrap();
    let key = s.stages.iter().find(|r| r.id == "psd-a").unwrap().key.clone();
    let dir = proj.cache.entry_dir(&key);
    // Another build made this entry: its record names other sources (manifest kept valid).
    let other = serde_json::json!({ "src/other.rs": "0" });
    let mut rec: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("record.json")).unwrap()).unwrap();
    let ours = rec["sources"].clone();
    assert!(ours.is_object() && ours != other);
    rec["sources"] = other.clone();
    let bytes = serde_json::to_vec_pretty(&rec).unwrap();
    std::fs::write(dir.join("record.json"), &bytes).unwrap();
    let mut man: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap();
    man["record"] = serde_json::Value::String(blake3::hash(&bytes).to_hex().to_string());
    std::fs::write(dir.join("manifest.json"), serde_json::to_vec_pretty(&man).unwrap()).unwrap();
    assert!(proj.cache.verify(&dir, &key).is_ok());
    let forced = RunOptions {
        force: true,
        targets: vec!["psd-a".into()],
        ..opts()
    };
    run(&p, &proj, &forced).unwrap();
    let rec: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("record.json")).unwrap()).unwrap();
    assert_eq!(rec["sources"], ours, "the record names the build that re-ran it");
    assert!(proj.cache.verify(&dir, &key).is_ok());
}

/// A figure over the figure cap is left out of the store (listed with its hash) without
/// making the entry partial: no stage reads another's figure, so consumers are still served.
#[test]
fn a_figure_over_its_cap_leaves_the_entry_complete() {
    let t = kept(Caps {
        figure: 64,
        ..Caps::default()
    });
    let dir = store::dir_of(t.path(), "paper");
    let lock = store::read_lock(&dir).unwrap().unwrap();
    let f = &lock.stages["fig-a"];
    assert!(
        f.left_out.contains_key("store/figure.svg") && !f.store.contains_key("figure.svg"),
        "{f:?}"
    );
    assert!(f.complete());
    assert!(store::verify(&dir, &lock).is_empty());
}

/// A partial entry is recomputed only for a reader of what it left out: a plot of its
/// scalars runs on it as served, a plot of its table makes it run again (the rule reads the
/// readers' declared tables, `Kind::reads`).
#[test]
fn a_partial_entry_reruns_only_for_a_reader_of_what_it_left_out() {
    let yaml = r#"version: 1
stages:
  - id: psd-a
    kind: psd
    params: { n: 300, seed: 1 }
  - id: by-scalars
    kind: plot
    params: { panels: [ { x: { label: "n" }, y: { label: "d50" }, series: [ { from: psd, source: scalars, x: n, y: d50_m, label: "a" } ] } ] }
    inputs: { psd: psd-a }
  - id: by-table
    kind: plot
    params: { panels: [ { x: { label: "grain" }, y: { label: "d" }, series: [ { from: psd, x: grain, y: d_m, label: "a" } ] } ] }
    inputs: { psd: psd-a }
"#;
    let t = TempProject::new(yaml);
    let proj = Project::new(t.path());
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    run(&p, &proj, &opts()).unwrap();
    // a cap that leaves psd-a's table (and nothing else it publishes) out of the store
    store::keep(
        &p,
        &proj,
        Caps {
            file: 2048,
            csv: 64,
            ..Caps::default()
        },
        None,
    )
    .unwrap();
    let lock = store::read_lock(&store::dir_of(t.path(), "paper")).unwrap().unwrap();
    let l = &lock.stages["psd-a"];
    assert!(l.left_out.contains_key("store/table.parquet") && !l.complete(), "{l:?}");

    let empty = tempfile::tempdir().unwrap();
    let proj = Project::new(t.path()).with_cache(empty.path());
    let label = |id: &str, v: &str| vec![Override::parse(&format!("{id}.columns={v}")).unwrap()];
    // the scalars' plot changes and runs; psd-a, served without its table, does not
    let p2 = load(&t.pipeline(), "paper", &label("by-scalars", "2")).unwrap();
    assert_eq!(sorted(run(&p2, &proj, &opts()).unwrap().ran()), ["by-scalars"]);
    // the table's plot changes: it reads what was left out, so psd-a runs again
    let p3 = load(&t.pipeline(), "paper", &label("by-table", "2")).unwrap();
    assert_eq!(sorted(run(&p3, &proj, &opts()).unwrap().ran()), ["by-table", "psd-a"]);
}

/// A re-keep under a smaller figure cap trims what it carries too: the carried entry's
/// figure leaves the store (its manifest rewritten, so the entry still verifies and serves)
/// and the lock stays consistent.
#[test]
fn a_rekeep_applies_the_figure_cap_to_carried_results() {
    let t = kept(Caps::default());
    let k = rekept(
        &t,
        Caps {
            figure: 64,
            ..Caps::default()
        },
    );
    let p = load(&t.pipeline(), "paper", &[]).unwrap();
    assert!(k.kept.is_empty() && k.carried.len() == 5, "{k:?}");
    let dir = store::dir_of(t.path(), "paper");
    let lock = store::read_lock(&dir).unwrap().unwrap();
    let f = &lock.stages["fig-a"];
    assert!(
        f.left_out.contains_key("store/figure.svg") && !f.store.contains_key("figure.svg"),
        "{f:?}"
    );
    assert!(
        store::verify(&dir, &lock).is_empty(),
        "{:?}",
        store::verify(&dir, &lock)
    );
    // still served to an empty cache: nothing runs
    let other = tempfile::tempdir().unwrap();
    let proj2 = Project::new(t.path()).with_cache(other.path());
    assert!(run(&p, &proj2, &opts()).unwrap().ran().is_empty());
}
