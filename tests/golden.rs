//! Golden numbers: each implemented stage's quick-profile scalars and claim checks,
//! rounded to their stable digits, snapshot-tested under `golden/` (one snapshot per
//! stage). They come from real runs of the real pipeline.yaml; when a snapshot changes,
//! the change must be explained in the commit that accepts it.

use std::collections::BTreeMap;
use std::path::Path;

use granrepro::pipeline::{Project, RunOptions, load, run::run};

// Every stage of the shipped pipeline at the quick profile is pinned (solver stages to 4
// significant digits, the rest to 6): a new stage gets its snapshot by being declared.

/// The snapshot of the claims ledger judged on the whole quick run (not a stage: naming it in
/// `GRANREPRO_GOLDEN_ONLY` runs every stage and checks the ledger alone).
const LEDGER: &str = "claims-ledger";

/// Significant digits pinned for a stage.
fn digits(id: &str) -> usize {
    if id.starts_with("psd") || id.starts_with("tab") || id == "fig4-01b" || id == "laws" {
        6
    } else {
        4
    }
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let p = e.path();
        if p.is_dir() {
            copy_dir(&p, &to.join(e.file_name()));
        } else {
            std::fs::copy(&p, to.join(e.file_name())).unwrap();
        }
    }
}

/// Round to `sig` significant digits, as text (stable across platforms).
fn round(v: f64, sig: usize) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    format!("{:.*e}", sig - 1, v)
}

#[test]
fn golden_numbers_quick_profile() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().unwrap();
    std::fs::copy(root.join("pipeline.yaml"), tmp.path().join("pipeline.yaml")).unwrap();
    copy_dir(&root.join("stages"), &tmp.path().join("stages"));
    let p = load(&tmp.path().join("pipeline.yaml"), "quick", &[]).expect("the shipped pipeline.yaml is valid");
    // The quick profile's whole run: its on-demand studies (`on_demand: true`, e.g. the
    // 35-minute calibration study) are kept with their own lock in results/<study>/, not
    // pinned here.
    let all: Vec<String> = granrepro::pipeline::dag::closure(&p, &[]).expect("the whole run");
    // GRANREPRO_CACHE (development only, refused under CI): take the stages from a warm
    // shared cache — the numbers of a cache entry are the numbers of a cold run with the
    // same key, so accepting snapshots of a large change need not rerun the whole chapter.
    let proj = match std::env::var_os("GRANREPRO_CACHE") {
        Some(dir) => {
            assert!(
                std::env::var("CI").is_err(),
                "GRANREPRO_CACHE is for development; CI runs the quick pipeline cold"
            );
            Project::new(tmp.path()).with_cache(Path::new(&dir))
        }
        None => Project::new(tmp.path()),
    };
    // GRANREPRO_GOLDEN_ONLY=id,id… pins a subset (and runs only what it needs): for
    // accepting a new stage's snapshot without the whole quick pipeline. CI never sets it.
    let only: Option<Vec<String>> = std::env::var("GRANREPRO_GOLDEN_ONLY")
        .ok()
        .map(|s| s.split(',').map(|x| x.trim().to_string()).collect());
    if let Some(o) = &only {
        assert!(
            std::env::var("CI").is_err(),
            "GRANREPRO_GOLDEN_ONLY is for development; CI pins every stage"
        );
        for id in o {
            assert!(
                all.contains(id) || id == LEDGER,
                "GRANREPRO_GOLDEN_ONLY names {id}, which is neither a stage of the quick pipeline nor {LEDGER}"
            );
        }
    }
    // The ledger's snapshot needs every stage: naming it runs the whole pipeline (a ledger
    // row's YAML change re-judges it without re-pinning any stage).
    let check_ledger = only.as_ref().is_none_or(|o| o.iter().any(|x| x == LEDGER));
    if only.is_none() {
        // A snapshot whose stage left the pipeline is a stale golden number: remove it.
        let stale: Vec<String> = std::fs::read_dir(root.join("golden"))
            .unwrap()
            .filter_map(|e| e.ok()?.file_name().to_str()?.strip_suffix(".snap").map(str::to_string))
            .filter(|id| !all.contains(id) && id != LEDGER)
            .collect();
        assert!(
            stale.is_empty(),
            "golden/ has snapshots of stages no longer in pipeline.yaml: {stale:?}"
        );
    }
    let golden: Vec<&str> = all
        .iter()
        .map(|s| s.as_str())
        .filter(|id| only.as_ref().is_none_or(|o| o.iter().any(|x| x == id)))
        .collect();
    let targets: Vec<String> = if check_ledger {
        all.iter().cloned().collect()
    } else {
        golden.iter().map(|s| s.to_string()).collect()
    };
    let s = run(
        &p,
        &proj,
        &RunOptions {
            targets,
            jobs: 2,
            quiet: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(!s.failed(), "{:?}", s.stages);
    // The run's cost, stage by stage, from its run records (`granrepro plan --timings`):
    // a cold golden run is the cold quick pipeline (issue 13), so keep its table beside
    // the build (`target/tmp/golden-timings-quick.txt`; printed with `--nocapture`).
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let timings =
        granrepro::pipeline::timings::timings(&p, &proj, &s.stages.iter().map(|x| x.id.clone()).collect::<Vec<_>>())
            .unwrap()
            .to_text(cores, 0.0);
    std::fs::write(
        Path::new(env!("CARGO_TARGET_TMPDIR")).join("golden-timings-quick.txt"),
        &timings,
    )
    .unwrap();
    println!("{timings}");
    // Issue 25: the front rule both methods share (the gathered length, docs/definitions.md
    // D01) moves backward by no more than 0.5 L_0 between samples, at any a of the quick
    // sweep, for grains and material points alike. (The DEM's contact rule, the chapter's,
    // is published beside it and jumps by up to 1.5 L_0 at quick size while grains fly.)
    let mut jumps: Vec<(String, f64)> = Vec::new();
    for id in &golden {
        let v: serde_json::Value = serde_json::from_slice(
            &std::fs::read(tmp.path().join("reports/quick").join(format!("{id}.json"))).unwrap(),
        )
        .unwrap();
        if let Some(j) = v["scalars"]["front_gathered_max_backward_jump_over_l0"].as_f64() {
            jumps.push((id.to_string(), j));
        }
        let scalars: BTreeMap<String, String> = v["scalars"]
            .as_object()
            .unwrap()
            .iter()
            .map(|(k, x)| (k.clone(), round(x.as_f64().unwrap_or(f64::NAN), digits(id))))
            .collect();
        // Measurements (what a stage measures for the ledger): id and our value. Checks
        // keep their verdict. The chapter's values and the verdicts of the claims are
        // pinned once, in the ledger's snapshot below.
        let rows = |key: &str, verdict: bool| -> Vec<BTreeMap<String, String>> {
            v[key]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| {
                    let mut m = BTreeMap::new();
                    m.insert("id".into(), c["id"].as_str().unwrap().to_string());
                    m.insert("ours".into(), round(c["ours"].as_f64().unwrap_or(f64::NAN), digits(id)));
                    if verdict {
                        m.insert(
                            "paper".into(),
                            round(c["paper"].as_f64().unwrap_or(f64::NAN), digits(id)),
                        );
                        m.insert("pass".into(), c["pass"].to_string());
                        if c["calibrated"].as_bool() == Some(true) {
                            m.insert("calibrated".into(), "true".into());
                        }
                    }
                    m
                })
                .collect()
        };
        let (measurements, checks) = (rows("measurements", false), rows("checks", true));
        let mut snap = serde_json::json!({ "stage": id, "profile": "quick", "scalars": scalars, "measurements": measurements, "checks": checks });
        // Text results (a choice's rule): every other top-level string key of the JSON.
        for (k, t) in v.as_object().unwrap() {
            if t.is_string() && k != "stage" && k != "profile" {
                snap[k.as_str()] = t.clone();
            }
        }
        insta::with_settings!({ snapshot_path => root.join("golden"), prepend_module_to_snapshot => false, omit_expression => true }, {
            insta::assert_yaml_snapshot!(*id, snap);
        });
    }
    let back: Vec<&(String, f64)> = jumps.iter().filter(|(_, j)| !(*j <= 0.5)).collect();
    assert!(
        back.is_empty(),
        "fronts that move backward by more than 0.5 L_0 between samples (docs/definitions.md D01): {back:?}"
    );
    // The ledger judged on this run: each row's measurement, its mean and spread, and
    // its verdict, pinned once (the stages' snapshots hold only the measurements).
    if check_ledger {
        let judged =
            granrepro::claims::evaluate_dir(&p, &tmp.path().join("reports/quick")).expect("stages/ledger.yaml");
        let unmeasured: Vec<&str> = judged
            .iter()
            .filter(|j| j.verdict == granrepro::claims::judge::Verdict::NoMeasurement)
            .map(|j| j.id.as_str())
            .collect();
        assert!(
            unmeasured.is_empty(),
            "ledger rows whose stage publishes no such measurement: {unmeasured:?}"
        );
        // The published ledger (reports/quick/claims.json) judges each claim id once, and
        // no chapter sentence twice on the same measurement.
        let published: serde_json::Value =
            serde_json::from_slice(&std::fs::read(tmp.path().join("reports/quick/claims.json")).unwrap()).unwrap();
        let mut ids = std::collections::BTreeSet::new();
        let mut sentences = std::collections::BTreeSet::new();
        for (c, j) in published.as_array().unwrap().iter().zip(&judged) {
            assert!(
                ids.insert(c["id"].as_str().unwrap().to_string()),
                "claim id {} published twice",
                c["id"]
            );
            assert!(
                sentences.insert((j.row.chapter.clone(), j.row.measure.label())),
                "{}: a sentence judged twice on one measurement",
                j.id
            );
        }
        assert_eq!(ids.len(), judged.len());
        let rows: Vec<serde_json::Value> = judged
            .iter()
            .map(|j| {
                serde_json::json!({
                    "id": j.id,
                    "kind": j.kind,
                    "paper": round(j.paper, 4),
                    "ours": round(j.mean, 4),
                    "n": j.values.len(),
                    "sd": j.sd.map(|s| round(s, 2)),
                    "verdict": j.verdict.name(),
                    "calibrated": !j.calibrated.is_empty(),
                    // judged on a scene the quick profile runs too small (the ledger's `reduced`)
                    "not_comparable": j.not_comparable_here(),
                })
            })
            .collect();
        insta::with_settings!({ snapshot_path => root.join("golden"), prepend_module_to_snapshot => false, omit_expression => true }, {
            insta::assert_yaml_snapshot!(LEDGER, rows);
        });
    }
}
