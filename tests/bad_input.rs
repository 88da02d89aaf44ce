//! Bad input: every problem reported at once, exit code 2, naming file, line and key.

mod common;
use common::TempProject;

#[test]
fn misspelt_key_names_file_line_and_key() {
    let t = TempProject::new("version: 1\nstages:\n  - id: psd\n    kind: psd\n    params:\n      n: 100\n      d_mni_mm: 0.9\n");
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("pipeline.yaml:7"), "{err}");
    assert!(err.contains("d_mni_mm"), "{err}");
    assert!(err.contains("d_min_mm"), "should list the allowed keys: {err}");
}

#[test]
fn misspelt_key_in_a_stage_file_names_that_file() {
    let t = TempProject::new("version: 1\nstages:\n  - id: psd\n    kind: psd\n    params_file: stages/p.yaml\n");
    t.write("stages/p.yaml", "# grains\nn: 100\nseeed: 4\n");
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("p.yaml:3"), "{err}");
    assert!(err.contains("seeed"), "{err}");
}

#[test]
fn cycle_is_printed() {
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: a\n    kind: psd-figure\n    inputs: { psd: b }\n  - id: b\n    kind: psd-figure\n    inputs: { psd: a }\n",
    );
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("cycle: a -> b -> a") || err.contains("cycle: b -> a -> b"), "{err}");
}

#[test]
fn missing_input_unknown_kind_and_duplicate_id_all_reported() {
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: f\n    kind: psd-figure\n    inputs: { psd: nope }\n  - id: g\n    kind: psdd\n  - id: f\n    kind: psd\n",
    );
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("unknown stage kind `psdd`"), "{err}");
    assert!(err.contains("duplicate stage id"), "{err}");
    assert!(err.contains("missing input: no stage `nope`"), "{err}");
}

#[test]
fn unphysical_values_are_refused_with_the_allowed_range() {
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: psd\n    kind: psd\n    params: { d_min_mm: -1.0, d_max_mm: 1.38 }\n  - id: t\n    kind: material-table\n    params:\n      table: tab4-02\n      dem: { grain: { restitution: 1.5 } }\n",
    );
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("params.d_min_mm") && err.contains("> 0"), "{err}");
    assert!(err.contains("dem.grain.restitution") && err.contains("(0, 1]"), "{err}");
    // A rejected stage is reported once, not again as a "missing input" of its dependants.
    let t = TempProject::new("version: 1\nstages:\n  - id: psd\n    kind: psd\n    params: { n: 0 }\n  - id: f\n    kind: psd-figure\n    inputs: { psd: psd }\n");
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("params.n") && !err.contains("missing input"), "{err}");
}

#[test]
fn wrong_type_yaml_syntax_and_bad_set_are_exit_2() {
    let t = TempProject::new("version: 1\nstages:\n  - id: psd\n    kind: psd\n    params: { n: lots }\n");
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("params.n"), "{err}");
    let t = TempProject::new("version: 1\nstages:\n  - id: psd\n    kind: psd\n   params: {\n");
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("YAML syntax error"), "{err}");
    let t = TempProject::new("version: 1\nstages:\n  - id: psd\n    kind: psd\n");
    let (code, _, err) = t.cli(&["run", "--set", "nostage.n=3", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("no stage `nostage`"), "{err}");
    let (code, _, err) = t.cli(&["run", "--stage", "zzz", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("unknown stage"), "{err}");
}

#[test]
fn dag_prints_dot_and_mermaid() {
    let t = TempProject::new(common::SMALL);
    let (code, out, _) = t.cli(&["dag"]);
    assert_eq!(code, 0);
    assert!(out.contains("\"psd-a\" -> \"fig-a\""), "{out}");
    let (code, out, _) = t.cli(&["dag", "--format", "mermaid"]);
    assert_eq!(code, 0);
    assert!(out.contains("psd_a --> fig_a"), "{out}");
}

#[test]
fn matrix_expands_and_pairs() {
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: p\n    kind: psd\n    matrix: { seed: [1, 2] }\n    params: { n: 50 }\n  - id: f\n    kind: psd-figure\n    matrix: { seed: [1, 2] }\n    inputs: { psd: p }\n",
    );
    let (code, out, err) = t.cli(&["list"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("p-seed1") && out.contains("p-seed2") && out.contains("f-seed2"), "{out}");
    assert!(out.lines().any(|l| l.starts_with("f-seed2") && l.contains("[p-seed2]")), "{out}");
}

#[test]
fn explicit_rolling_damper_is_refused_by_the_preflight_with_numbers() {
    // The chapter's rolling dashpot (c_r = 0.1 N·m·s/rad) relaxes in ~1e-9 s: the naive
    // explicit update at the table-4.2 step must be refused before anything runs.
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: c\n    kind: dem-column-prep\n    params:\n      dem: { rolling: { damping: explicit } }\n    inputs: { psd: p }\n",
    );
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("params.dem.dt") && err.contains("explicit") && err.contains("e-9 s"), "{err}");
    // The implicit default passes validation (checked without running: --explain).
    let t = TempProject::new("version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: c\n    kind: dem-column-prep\n    inputs: { psd: p }\n");
    let (code, out, err) = t.cli(&["run", "--explain"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("rolling dashpot relaxation") && out.contains("implicit"), "{out}");
}
