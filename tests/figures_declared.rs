//! Figures as declarations (`plot`), comparative claims (`sweep-compare`) and matrices
//! whose values depend on the profile: they run on real upstream stages, and every
//! mistake in a declaration is refused before anything runs (exit 2, naming the key).

mod common;
use common::TempProject;

/// Two PSD families swept over n (quick: fewer members), a plot of one's table and a
/// sweep of both's scalars, and a comparison of their mean diameters.
const PIPE: &str = r#"version: 1
stages:
  - id: fine
    kind: psd
    params: { d_min_mm: 0.9, d_max_mm: 1.1, beta_a: 1.0, beta_b: 1.0, seed: 3 }
    matrix: { n: [200, 400, 800] }
    profiles: { quick: { matrix: { n: [200, 400] } } }
  - id: coarse
    kind: psd
    params: { d_min_mm: 1.8, d_max_mm: 2.2, beta_a: 1.0, beta_b: 1.0, seed: 3 }
    matrix: { n: [200, 400, 800] }
    profiles: { quick: { matrix: { n: [200, 400] } } }
  - id: fig
    kind: plot
    caption: "Diameters"
    params:
      panels:
        - x: { label: "grain" }
          y: { label: "d [mm]" }
          series:
            - { from: one, x: grain, y: d_m, y_scale: 1000.0, label: "fine, n = 200" }
        - x: { label: "n", log: true }
          y: { label: "d50 [mm]" }
          series:
            - { from: f, source: scalars, x: n, y: d50_m, y_scale: 1000.0, label: "fine" }
            - { from: c, source: scalars, x: n, y: d50_m, y_scale: 1000.0, label: "coarse", filter: { n: 400 } }
    inputs: { one: fine-n200, f: fine, c: coarse }
  - id: cmp
    kind: sweep-compare
    params:
      claims:
        - { id: coarse-twice, statement: "coarse grains are twice the fine ones", a: c, b: f, y: d50_m, pair_on: n, relation: ratio, paper: 2.0, tolerance: 0.05 }
        - { id: fine-smaller, statement: "fine grains are smaller", a: f, b: c, y: d50_m, pair_on: n, relation: less }
    inputs: { f: fine, c: coarse }
"#;

fn json(t: &TempProject, id: &str) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(t.path().join("reports/quick").join(format!("{id}.json"))).unwrap()).unwrap()
}

#[test]
fn plot_and_compare_run_on_the_quick_matrix() {
    let t = TempProject::new(PIPE);
    let (code, out, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 0, "{out}\n{err}");
    // The quick profile sweeps n ∈ {200, 400}: no n = 800 member ran.
    assert!(t.path().join("reports/quick/fine-n400.json").exists());
    assert!(!t.path().join("reports/quick/fine-n800.json").exists());
    let fig = json(&t, "fig");
    assert_eq!(fig["scalars"]["panel0_points"].as_f64(), Some(200.0), "{fig}");
    // panel 1: two fine members + the one coarse member the filter keeps
    assert_eq!(fig["scalars"]["panel1_points"].as_f64(), Some(3.0), "{fig}");
    let svg = std::fs::read_to_string(t.path().join("reports/quick/fig.svg")).unwrap();
    assert!(
        svg.contains("d50 [mm]") && svg.contains("profile: quick"),
        "two panels and the footer"
    );
    let cmp = json(&t, "cmp");
    // A stage publishes measurements; the ledger (stages/ledger.yaml) judges them.
    let claims = cmp["measurements"].as_array().unwrap();
    assert_eq!(claims.len(), 2);
    let ratio = cmp["scalars"]["coarse-twice_ratio"].as_f64().unwrap();
    assert!(
        (ratio - 2.0).abs() < 0.05,
        "d50 ratio of [1.8, 2.2] to [0.9, 1.1] mm grains: {ratio}"
    );
    assert!(
        claims
            .iter()
            .all(|c| c["ours"].as_f64().is_some_and(f64::is_finite) && c.get("pass").is_none()),
        "{claims:?}"
    );
    assert_eq!(cmp["scalars"]["coarse-twice_pairs"].as_f64(), Some(2.0));
}

#[test]
fn paper_profile_sweeps_the_paper_matrix() {
    let t = TempProject::new(PIPE);
    let (code, out, err) = t.cli(&["run", "--profile", "paper", "--stage", "fine", "--quiet"]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(t.path().join("reports/paper/fine-n800.json").exists());
}

#[test]
fn a_profile_matrix_must_sweep_the_stage_key() {
    let t = TempProject::new(&PIPE.replace(
        "profiles: { quick: { matrix: { n: [200, 400] } } }\n  - id: coarse",
        "profiles: { quick: { matrix: { seed: [1, 2] } } }\n  - id: coarse",
    ));
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("stages[fine].profiles.quick.matrix") && err.contains("matrix: { n: [..] }"),
        "{err}"
    );
}

#[test]
fn plot_roles_must_match_its_inputs() {
    // a series reads a role nobody declared, and a declared role is never read
    let t = TempProject::new(&PIPE.replace(
        "inputs: { one: fine-n200, f: fine, c: coarse }",
        "inputs: { one: fine-n200, f: fine, extra: coarse }",
    ));
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("reads role `c`, which is not under `inputs:`"), "{err}");
    assert!(err.contains("input role `extra` is not read"), "{err}");
}

#[test]
fn bad_plot_and_compare_params_are_refused() {
    let bad = PIPE
        .replace(
            "- x: { label: \"n\", log: true }",
            "- x: { label: \"n\", log: true, range: [0.0, 10.0] }",
        )
        .replace("relation: less }", "relation: less, tolerance: 0.1 }");
    let t = TempProject::new(&bad);
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("panels[1].x.range"), "log axis from 0: {err}");
    assert!(err.contains("claims[1].relation"), "less with a tolerance: {err}");
    assert_eq!(
        err.matches("error:").count(),
        2,
        "one error per mistake, none about the stages' inputs: {err}"
    );
    // a misspelt key names itself and the allowed ones
    let t = TempProject::new(&PIPE.replace(
        "y_scale: 1000.0, label: \"fine, n = 200\"",
        "y_scale: 1000.0, label: \"fine, n = 200\", colour: 3",
    ));
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("series[0].colour") && err.contains("`color`"), "{err}");
    assert_eq!(
        err.matches("error:").count(),
        1,
        "a rejected stage's inputs are not handed to another stage: {err}"
    );
}

/// A panel's straight lines: a level read from an input's scalar and a stated number,
/// drawn with the values in the legend; a line naming a scalar the input's kind does not
/// publish is refused at load, naming the key.
#[test]
fn plot_lines_read_declared_scalars() {
    let with_lines = |intercept: &str| {
        PIPE.replace(
            "label: \"coarse\", filter: { n: 400 } }",
            &format!(
                "label: \"coarse\", filter: {{ n: 400 }} }}\n          lines:\n            - {{ from: c, intercept: {intercept}, slope: 1.0e-6, label: \"coarse line\" }}\n            - {{ intercept: 1.5, label: \"stated d50\" }}"
            ),
        )
    };
    let t = TempProject::new(&with_lines("d50_m"));
    let (code, out, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 0, "{out}\n{err}");
    let svg = std::fs::read_to_string(t.path().join("reports/quick/fig.svg")).unwrap();
    assert!(svg.contains("stated d50 = 1.500"), "the level and its value in the legend");
    assert!(svg.contains("coarse line: 0.002"), "the fitted line's coefficients in the legend");
    // lines are overlays, not data: the panel still counts its three points
    assert_eq!(json(&t, "fig")["scalars"]["panel1_points"].as_f64(), Some(3.0));

    let t = TempProject::new(&with_lines("d50_mm"));
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("panels[1].lines[0].intercept") && err.contains("d50_mm"), "{err}");
    assert!(!t.path().join("reports/quick/fine-n200.json").exists(), "refused before anything ran");
}

/// A series may read x from another table of its input, row for row (a work-precision
/// figure draws `table`'s errors against `timing`'s wall times): the x table and its column
/// are checked at load like every other name, and refused before anything runs.
#[test]
fn plot_x_table_is_read_row_for_row_and_checked_at_load() {
    let with_x_table = |t: &str| {
        PIPE.replace(
            "{ from: one, x: grain, y: d_m, y_scale: 1000.0, label: \"fine, n = 200\" }",
            &format!("{{ from: one, x_table: {t}, x: grain, y: d_m, y_scale: 1000.0, label: \"fine, n = 200\" }}"),
        )
    };
    let t = TempProject::new(&with_x_table("table"));
    let (code, out, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert_eq!(json(&t, "fig")["scalars"]["panel0_points"].as_f64(), Some(200.0));

    let t = TempProject::new(&with_x_table("timing"));
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("panels[0].series[0].x_table") && err.contains("timing"), "{err}");
    assert!(!t.path().join("reports/quick/fine-n200.json").exists(), "refused before anything ran");
}
