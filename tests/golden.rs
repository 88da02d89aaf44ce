//! Golden numbers: each implemented stage's quick-profile scalars and claim checks,
//! rounded to their stable digits, snapshot-tested under `golden/` (one snapshot per
//! stage). They come from real runs of the real pipeline.yaml; when a snapshot changes,
//! the change must be explained in the commit that accepts it.

use std::collections::BTreeMap;
use std::path::Path;

use granrepro::pipeline::{Project, RunOptions, load, run::run};

/// Stages whose numbers are pinned: every stage of the shipped pipeline at the quick
/// profile (solver stages to 4 significant digits, the rest to 6).
const GOLDEN: &[&str] = &[
    "psd-col", "psd-pile", "psd-shear", "fig4-01b", "tab4-01", "tab4-02", "tab4-03", "laws",
    "col-dem-prep-a0.4", "col-dem-prep-a0.8", "col-dem-prep-a1", "col-dem-prep-a6", "col-dem-prep-hex",
    "col-dem-prep-loose", "col-dem-prep-dense", "calib-point-mu_r0.1", "calib-point-mu_r0.3",
    "calib-point-capped-mu_r0.1", "calib-point-capped-mu_r0.3", "calib-dem", "fig4-01a", "fig4-02", "fig4-03",
    "compress-dem", "col-dem-a0.4", "col-dem-a6", "col-dem-no-rolling-damper", "wp-dem-column", "fig4-23",
    "fig4-04", "col-mpm-a0.4", "wp-mpm-column", "shear-cd", "fig4-25", "wp-cd-pile",
    "wp-summary",
];

/// Significant digits pinned for a stage.
fn digits(id: &str) -> usize {
    if id.starts_with("psd") || id.starts_with("tab") || id == "fig4-01b" || id == "laws" { 6 } else { 4 }
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
    let proj = Project::new(tmp.path());
    // GRANREPRO_GOLDEN_ONLY=id,id… pins a subset (and runs only what it needs): for
    // accepting a new stage's snapshot without the whole quick pipeline. CI never sets it.
    let only: Option<Vec<String>> = std::env::var("GRANREPRO_GOLDEN_ONLY").ok().map(|s| s.split(',').map(|x| x.trim().to_string()).collect());
    if let Some(o) = &only {
        assert!(std::env::var("CI").is_err(), "GRANREPRO_GOLDEN_ONLY is for development; CI pins every stage");
        for id in o {
            assert!(GOLDEN.contains(&id.as_str()), "GRANREPRO_GOLDEN_ONLY names {id}, which is not in GOLDEN");
        }
    }
    let golden: Vec<&str> = GOLDEN.iter().copied().filter(|id| only.as_ref().is_none_or(|o| o.iter().any(|x| x == id))).collect();
    let targets: Vec<String> = golden.iter().map(|s| s.to_string()).collect();
    let s = run(&p, &proj, &RunOptions { targets, jobs: 2, quiet: true, ..Default::default() }).unwrap();
    assert!(!s.failed(), "{:?}", s.stages);
    for id in &golden {
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(tmp.path().join("reports/quick").join(format!("{id}.json"))).unwrap()).unwrap();
        let scalars: BTreeMap<String, String> = v["scalars"].as_object().unwrap().iter().map(|(k, x)| (k.clone(), round(x.as_f64().unwrap_or(f64::NAN), digits(id)))).collect();
        let rows = |key: &str| -> Vec<BTreeMap<String, String>> {
            v[key]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| {
                    let mut m = BTreeMap::new();
                    m.insert("id".into(), c["id"].as_str().unwrap().to_string());
                    m.insert("paper".into(), round(c["paper"].as_f64().unwrap_or(f64::NAN), digits(id)));
                    m.insert("ours".into(), round(c["ours"].as_f64().unwrap_or(f64::NAN), digits(id)));
                    m.insert("pass".into(), c["pass"].to_string());
                    if c["calibrated"].as_bool() == Some(true) {
                        m.insert("calibrated".into(), "true".into());
                    }
                    m
                })
                .collect()
        };
        let (claims, checks) = (rows("claims"), rows("checks"));
        let snap = serde_json::json!({ "stage": id, "profile": "quick", "scalars": scalars, "claims": claims, "checks": checks });
        insta::with_settings!({ snapshot_path => root.join("golden"), prepend_module_to_snapshot => false, omit_expression => true }, {
            insta::assert_yaml_snapshot!(*id, snap);
        });
    }
}
