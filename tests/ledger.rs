//! Contract: the chapter's claims are judged once, from one ledger (`stages/ledger.yaml`,
//! `src/claims`). Stages publish measurements, never verdicts; no sentence is judged twice
//! on one measurement; a claim about a method is judged on that method; preparation
//! targets are checks; the chapter's stated ± is the tolerance, never widened; everything
//! downstream of a tuned stage carries the calibrated flag. Each test here fails on the
//! tree before the ledger (stage-level verdicts, duplicates, wrong references).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use granrepro::claims::judge::{Verdict, ancestors, judge};
use granrepro::claims::{self, Kind, Ledger, Tolerance};
use granrepro::pipeline::{Pipeline, load};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn pipeline(profile: &str) -> Pipeline {
    load(&root().join("pipeline.yaml"), profile, &[]).expect("the shipped pipeline and its ledger load")
}

fn ledger() -> Ledger {
    claims::read(root())
        .expect("the ledger parses")
        .expect("stages/ledger.yaml exists")
        .0
}

/// Every stage id of both profiles.
fn all_ids() -> BTreeSet<String> {
    ["quick", "paper"]
        .iter()
        .flat_map(|p| pipeline(p).stages.into_iter().map(|s| s.id))
        .collect()
}

#[test]
fn the_shipped_ledger_is_valid_against_every_profile() {
    let (l, file, text) = claims::read(root()).unwrap().unwrap();
    let d = claims::validate(&l, &file, &text, Some(&all_ids()));
    assert!(d.is_empty(), "{d:#?}");
    assert!(l.claims.len() >= 60, "{} rows", l.claims.len());
    // every headline result of the chapter is there
    let heads: BTreeSet<&str> = l.claims.iter().filter_map(|r| r.headline.as_deref()).collect();
    for h in [
        "col-runout-low-exponent", "col-runout-high-exponent", "col-height-eq47", "col-phases", "col-energy-short",
        "col-energy-tall", "col-phi-cs", "col-modulus", "col-failure-angle", "col-mu-e", "col-inertial",
        "col-dense-loose", "pile-cd-mu", "pile-alpha", "pile-alpha-prime", "pile-beta-prime", "pile-tf-plateau",
        "pile-beta-dprime", "pile-k", "pile-ke-dissipated", "pile-base-friction",
    ] {
        assert!(heads.contains(h), "headline `{h}` missing");
    }
}

#[test]
fn stage_snapshots_carry_measurements_not_verdicts() {
    // Before the ledger every stage judged its own claims (`claims:` with `pass:` in its
    // golden snapshot), so the same sentence was judged in several places.
    for e in std::fs::read_dir(root().join("golden")).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        if name == "claims-ledger.snap" {
            continue;
        }
        let t = std::fs::read_to_string(&p).unwrap();
        assert!(!t.contains("\nclaims:"), "{name} still judges claims itself");
    }
}

#[test]
fn a_duplicate_sentence_on_one_measurement_is_refused() {
    let (mut l, file, text) = claims::read(root()).unwrap().unwrap();
    let mut twice = l.claims[0].clone();
    twice.id = "the-same-again".into();
    l.claims.push(twice);
    let d = claims::validate(&l, &file, &text, Some(&all_ids()));
    assert!(d.iter().any(|x| x.message.contains("same chapter sentence")), "{d:#?}");
    let mut l2 = ledger();
    let first = l2.claims[0].id.clone();
    l2.claims[1].id = first;
    let d = claims::validate(&l2, &file, &text, Some(&all_ids()));
    assert!(d.iter().any(|x| x.message.contains("used twice")), "{d:#?}");
}

#[test]
fn the_duplicates_of_the_old_report_are_judged_once() {
    let l = ledger();
    let judged: Vec<(String, String)> = l
        .claims
        .iter()
        .flat_map(|r| {
            let what = r
                .measure
                .measurement
                .clone()
                .or(r.measure.scalar.clone())
                .unwrap_or_default();
            // One entry per run condition: an ensemble's members are one condition.
            let m = &r.measure;
            std::iter::once(m.stage.clone())
                .chain(m.minus.iter().chain(m.over.iter()).map(|o| o.stage.clone()))
                .map(move |s| (s, what.clone()))
        })
        .collect();
    let has = |s: &str, m: &str| judged.iter().any(|(a, b)| a == s && b == m);
    // pairs that measured one sentence twice (the old index counted both)
    for (a, b) in [
        (
            ("column-claims", "mpm-longer-runout-tall"),
            ("energy-runout", "column-mpm-longer-tall"),
        ),
        (
            ("column-claims", "mpm-dem-short-runout"),
            ("energy-runout", "column-similar-short"),
        ),
        (("fit-pile-tfp", "exponent"), ("pile-series-mpm", "beta1-tfp")),
        (("fit-pile-tau", "exponent"), ("pile-series-mpm", "beta2-tau")),
        (("fit-pile-k", "prefactor"), ("pile-series-mpm", "k")),
        (
            ("inertial-column", "mui-dense-regime"),
            ("col-mpm-mui-a6", "inertial-number-dense"),
        ),
        (("fig4-03", "friction-angle"), ("calib-dem", "friction-angle")),
    ] {
        assert!(
            !(has(a.0, a.1) && has(b.0, b.1)),
            "{a:?} and {b:?} judge the same sentence"
        );
    }
    // per-run measurements: judged at the chapter's conditions only
    let on = |m: &str| judged.iter().filter(|(_, b)| b == m).count();
    assert!(
        on("motion-persists-6tau") <= 1,
        "motion-persists-6tau judged on {} runs",
        on("motion-persists-6tau")
    );
    assert!(
        on("comes-to-rest") <= 1,
        "comes-to-rest judged on {} runs",
        on("comes-to-rest")
    );
    assert_eq!(
        on("height-undisturbed"),
        0,
        "eq 4.7's low branch is judged on fit-height"
    );
    assert!(
        !judged.iter().any(|(s, _)| s == "col-dem-no-rolling-damper"),
        "the c_r = 0 variant re-counts the a = 0.4 claims"
    );
    // hexagonal and μ(I) columns: no per-run claim; they enter only as a side of a
    // comparison the chapter makes (hexagonal against random packing)
    for r in l.claims.iter().filter(|r| r.measure.over.is_none() && r.measure.minus.is_none()) {
        let s = &r.measure.stage;
        assert!(
            !(s.starts_with("col-dem-hex-") || s.starts_with("col-mpm-mui-a")),
            "{} judges a per-run measurement of {s}",
            r.id
        );
    }
    for r in l.claims.iter().filter(|r| r.measure.stage.starts_with("col-dem-hex-")) {
        let over = r.measure.over.as_deref().map(|o| o.stage.as_str());
        assert!(
            over.is_some_and(|o| o.starts_with("col-dem-a")),
            "{}: a hexagonal column is judged against the random one",
            r.id
        );
    }
}

/// The method a stage simulates, from its kind (or its `method:`), when it is a run.
fn method_of(p: &Pipeline, id: &str) -> Option<&'static str> {
    let s = p.get(id)?;
    let k = s.kind.as_str();
    let from_param = s.params.get("method").and_then(|m| m.as_str()).unwrap_or("");
    if k.starts_with("dem-") || k.starts_with("shear-dem") || from_param == "dem" {
        Some("DEM")
    } else if k.starts_with("mpm-") || from_param == "mpm" {
        Some("MPM")
    } else if k.starts_with("cd-") || from_param == "cd" {
        Some("CD")
    } else {
        None
    }
}

#[test]
fn a_claim_about_one_method_is_judged_on_that_method() {
    let p = pipeline("quick");
    let l = ledger();
    for r in &l.claims {
        if !["DEM", "MPM", "CD"].contains(&r.method.as_str()) {
            continue;
        }
        for s in r.measure.all_stages() {
            if let Some(m) = method_of(&p, s) {
                assert_eq!(m, r.method, "`{}` is about {} but reads {s}, a {m} run", r.id, r.method);
            }
        }
    }
    // The MPM dense-regime bound is not applied to DEM runs, and a DEM statistic is not
    // judged against two opposite statements.
    for r in &l.claims {
        if r.measure.measurement.as_deref() == Some("inertial-number-dense") {
            for s in r.measure.all_stages() {
                assert_ne!(
                    method_of(&p, s),
                    Some("DEM"),
                    "{}: the MPM dense-regime bound on a DEM run",
                    r.id
                );
            }
        }
    }
    // "ceases at around 6τ_c" is the chapter's MPM a = 6 statement, not its DEM 3τ_c
    for r in l.claims.iter().filter(|r| r.measure.stage == "col-mpm-a6") {
        if r.measure.measurement.as_deref() == Some("spreading-ceases-3tau") {
            assert_eq!(r.paper, 6.0, "{}", r.id);
        }
    }
}

#[test]
fn a_stop_rule_that_cannot_end_early_makes_no_claim() {
    // motion-persists-6tau on a run whose stop rule forbids an end before 6 τ_c cannot fail
    for p in [pipeline("quick"), pipeline("paper")] {
        for r in ledger()
            .claims
            .iter()
            .filter(|r| r.measure.measurement.as_deref() == Some("motion-persists-6tau"))
        {
            // Ensemble members absent from a profile are not judged there.
            for s in r.measure.all_stages().into_iter().filter(|s| p.get(s).is_some()) {
                let t_min = p.get(s).unwrap().params["run"]["stop"]["t_min"].as_f64().unwrap();
                assert!(t_min < 0.85 * r.paper, "{}: {s} cannot stop before {t_min} τ_c", r.id);
            }
        }
    }
}

#[test]
fn preparation_targets_and_calibration_targets_are_checks() {
    for r in &ledger().claims {
        let prep = r.measure.all_stages().iter().any(|s| s.contains("-prep-"))
            && r.measure.measurement.as_deref() == Some("packing-fraction");
        if prep || r.measure.stage == "calib-dem" || r.id == "pile-slope" {
            assert_eq!(r.kind, Kind::Check, "{} is a target our inputs decide", r.id);
        }
    }
}

#[test]
fn the_stated_plus_minus_is_the_tolerance_never_widened() {
    let (mut l, file, text) = claims::read(root()).unwrap().unwrap();
    for r in &l.claims {
        if let Some(pm) = r.stated {
            assert_eq!(r.tolerance, Tolerance::Abs(pm), "{}", r.id);
        }
    }
    // fit-pile-tfp's old tolerance: 2 s.e. + the chapter's ± = 0.223 from three runs
    let r = l.claims.iter_mut().find(|r| r.id == "pile-tfp-exponent").unwrap();
    r.tolerance = Tolerance::Abs(0.223);
    let d = claims::validate(&l, &file, &text, Some(&all_ids()));
    assert!(d.iter().any(|x| x.message.contains("states ±")), "{d:#?}");
}

#[test]
fn the_calibrated_flag_reaches_everything_downstream_of_a_tuned_stage() {
    let p = pipeline("quick");
    let l = ledger();
    // every stage "ran" and measured 1.0
    let fake = |id: &str| -> Option<serde_json::Value> {
        p.get(id)?;
        let mut ms = Vec::new();
        let mut sc = serde_json::Map::new();
        for r in &l.claims {
            let mut sides = vec![&r.measure];
            sides.extend(r.measure.minus.as_deref().into_iter().chain(r.measure.over.as_deref()));
            for m in sides {
                if let Some(x) = &m.measurement {
                    ms.push(serde_json::json!({"id": x, "ours": 1.0}));
                }
                for s in m.scalar.iter().chain(m.se.iter()) {
                    sc.insert(s.clone(), 1.0.into());
                }
            }
        }
        Some(serde_json::json!({"measurements": ms, "scalars": sc}))
    };
    let graph: BTreeMap<String, Vec<String>> = claims::graph(&p);
    let anc = ancestors(&graph);
    let j = judge(&l, &fake, &anc);
    assert!(j.iter().all(|x| x.verdict != Verdict::NoMeasurement));
    for x in &j {
        let downstream = x.row.measure.all_stages().iter().any(|s| anc[*s].contains("calib-dem"));
        if downstream {
            assert!(
                x.calibrated.iter().any(|c| c.starts_with("calib-dem")),
                "{} rests on calib-dem's μ_r but is not flagged calibrated",
                x.id
            );
        }
    }
    let col = j.iter().find(|x| x.id == "col-phases-acc-a0.4").unwrap();
    assert!(!col.calibrated.is_empty(), "a DEM column rests on calib-dem");
    let stop = j.iter().find(|x| x.id == "col-motion-6tau").unwrap();
    assert!(
        stop.calibrated.iter().any(|c| c.contains("stop threshold")),
        "{:?}",
        stop.calibrated
    );
}

#[test]
fn a_bad_ledger_is_refused_before_anything_runs_naming_the_file_and_key() {
    let t = tempfile::tempdir().unwrap();
    std::fs::copy(root().join("pipeline.yaml"), t.path().join("pipeline.yaml")).unwrap();
    let copy = |from: &Path, to: &Path| {
        fn walk(a: &Path, b: &Path) {
            std::fs::create_dir_all(b).unwrap();
            for e in std::fs::read_dir(a).unwrap() {
                let e = e.unwrap();
                if e.path().is_dir() {
                    walk(&e.path(), &b.join(e.file_name()));
                } else {
                    std::fs::copy(e.path(), b.join(e.file_name())).unwrap();
                }
            }
        }
        walk(from, to)
    };
    copy(&root().join("stages"), &t.path().join("stages"));
    let f = t.path().join("stages/ledger.yaml");
    let text = std::fs::read_to_string(&f).unwrap();
    // A misspelt stage in the ledger: the shipped ledger is checked against the shipped
    // pipeline (a project may declare fewer stages: its missing rows are "not run").
    let typo = text.replacen("stage: fit-runout-dem,", "stage: fit-runout-dme,", 1);
    let l: claims::Ledger = serde_yaml::from_str(&typo).unwrap();
    let d = claims::validate(&l, &f, &typo, Some(&all_ids()));
    assert!(
        d.iter()
            .any(|x| x.message.contains("fit-runout-dme") && x.message.contains("not declared")),
        "{d:#?}"
    );
    std::fs::write(&f, &typo).unwrap();
    assert!(
        load(&t.path().join("pipeline.yaml"), "quick", &[]).is_ok(),
        "a row on an undeclared stage is not run, not refused"
    );
    std::fs::write(&f, text.replacen("kind: quantitative", "kind: quantitive", 1)).unwrap();
    let msg = load(&t.path().join("pipeline.yaml"), "quick", &[])
        .expect_err("refused")
        .to_string();
    assert!(msg.contains("ledger.yaml") && msg.contains("kind"), "{msg}");
}

/// `--stage headline` names exactly the stages the ledger's headline rows read (present in
/// the profile), so the headline subset follows the ledger, never a hand-kept list.
#[test]
fn the_headline_target_is_the_stages_the_headline_rows_read() {
    use granrepro::pipeline::dag::{HEADLINE, closure, members};
    let l = ledger();
    for profile in ["quick", "paper"] {
        let p = pipeline(profile);
        let got: BTreeSet<String> = members(&p, HEADLINE).into_iter().collect();
        let want: BTreeSet<String> = l
            .claims
            .iter()
            .filter(|r| r.headline.is_some())
            .flat_map(|r| r.measure.all_stages())
            .filter(|id| p.get(id).is_some())
            .map(String::from)
            .collect();
        assert!(!want.is_empty());
        assert_eq!(got, want, "{profile}");
        assert!(
            got.contains("fig4-03"),
            "col-phi-cs is a headline row read from fig4-03"
        );
        // the closure runs what they need, and not the whole pipeline
        let c = closure(&p, &[HEADLINE.to_string()]).unwrap();
        assert!(
            c.len() < p.stages.len() && c.iter().any(|id| id == "calib-dem"),
            "{profile}"
        );
    }
}

/// Issue 28.4: a verdict on a scene the quick profile runs too small (the 250-grain pile,
/// the half-size DEM columns) is marked as not comparable with the chapter, with its
/// reason; the same rows at the paper profile are not, nor are rows that read neither.
#[test]
fn rows_on_reduced_quick_scenes_are_marked_and_paper_rows_are_not() {
    let l = ledger();
    assert!(!l.reduced.is_empty());
    for (profile, reduced) in [("quick", true), ("paper", false)] {
        let p = pipeline(profile);
        let anc = claims::judge::ancestors(&claims::graph(&p));
        let mut j = claims::judge::judge(&l, &|_| None, &anc);
        claims::mark_reduced(&mut j, &l.reduced, profile, &anc);
        let marked = |id: &str| !j.iter().find(|x| x.id == id).unwrap().not_comparable.is_empty();
        assert_eq!(marked("pile-alpha"), reduced, "{profile}");
        assert_eq!(marked("col-runout-low-exponent"), reduced, "{profile}");
        assert_eq!(marked("col-phases-acc-a0.4"), reduced, "{profile}");
        // the MPM column alone, and the compression's modulus: not reduced scenes
        assert!(!marked("col-runout-mpm-linear"), "{profile}");
        assert!(!marked("col-modulus"), "{profile}");
    }
}

#[test]
fn the_calibration_and_the_settings_study_measure_the_runout_the_sweeps_report() {
    // calib-runout-short/-tall are checks of the run-out the column sweeps report: the grid
    // points (and wp-dem-column, which picks the sweeps' contact setting) must find the front
    // by the same D01 gap and stop by the same rule as col-dem. Fails on the tree where the
    // grid linked grains within 0.01 d̄ and stopped on energy alone (sweep: 0.5 d̄).
    for p in [pipeline("quick"), pipeline("paper")] {
        let sweep = &p.get("col-dem-a0.4").expect("col-dem-a0.4 in both profiles").params["run"];
        let same = ["link_gap", "stop", "front", "right_wall_at"];
        let mut seen = 0;
        for s in p
            .stages
            .iter()
            .filter(|s| s.kind == "dem-calibration-point" || s.id == "wp-dem-column")
        {
            for k in same {
                assert_eq!(s.params["run"][k], sweep[k], "{}: run.{k} differs from col-dem's", s.id);
            }
            seen += 1;
        }
        assert!(
            seen >= 3,
            "the grid points and wp-dem-column are in the profile ({seen})"
        );
    }
}

/// A chaotic row compares the grains' ensemble with an MPM run: the MPM side is one
/// deterministic computation, so the verdict rests on the DEM members' spread. Before, the
/// MPM side's single run made every such row "not resolved" whatever the members said
/// (col-mpm-critical-time-tall at paper size: 0.96 τ_c over the DEM's 0.93, 0.97, 0.82).
#[test]
fn an_mpm_side_of_a_chaotic_comparison_is_one_run_and_the_dem_members_decide() {
    let p = pipeline("paper");
    let l = ledger();
    let value = |id: &str| -> Option<(f64, &str)> {
        Some(match id {
            "col-mpm-a6" => (0.96, "mpm"),
            "col-dem-a6" => (0.93, "dem"),
            "col-dem-m1-a6" => (0.97, "dem"),
            "col-dem-m2-a6" => (0.82, "dem"),
            _ => return None,
        })
    };
    let fake = |id: &str| -> Option<serde_json::Value> {
        let (v, method) = value(id)?;
        Some(serde_json::json!({
            "scalars": { "t_kemax_over_tau_c": v },
            "measurements": [],
            "measured": { "methods": [{ "method": method }] },
        }))
    };
    let anc = ancestors(&claims::graph(&p));
    let j = judge(&l, &fake, &anc);
    let row = j.iter().find(|x| x.id == "col-mpm-critical-time-tall").unwrap();
    assert!(row.row.chaotic);
    let se = row.se.expect("the DEM members give the ratio its s.e.");
    // q = 0.96 / mean(0.93, 0.97, 0.82); s.e. from the members' s.d. / √3 alone
    let (m, sd) = (0.9066666666666666_f64, 0.07767453465154029_f64);
    assert!((row.mean - 0.96 / m).abs() < 1e-12, "{}", row.mean);
    assert!((se - row.mean * sd / 3f64.sqrt() / m).abs() < 1e-9, "{se}");
    // 1.06 against the chapter's 1.5 ± 0.225, 2 s.e. = 0.10: a miss, not "not resolved"
    assert_eq!(row.verdict, Verdict::Missed, "{}", row.note);
    // A DEM side with one member stays unknown: its chaos is not measured.
    let one = |id: &str| if id.contains("-m1-") || id.contains("-m2-") { None } else { fake(id) };
    let j1 = judge(&l, &one, &anc);
    let row1 = j1.iter().find(|x| x.id == "col-mpm-critical-time-tall").unwrap();
    assert_eq!(row1.verdict, Verdict::NotResolved, "{}", row1.note);
}
