//! Bad input: every problem reported at once, exit code 2, naming file, line and key.

mod common;
use common::TempProject;

#[test]
fn misspelt_key_names_file_line_and_key() {
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: psd\n    kind: psd\n    params:\n      n: 100\n      d_mni_mm: 0.9\n",
    );
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
    assert!(
        err.contains("cycle: a -> b -> a") || err.contains("cycle: b -> a -> b"),
        "{err}"
    );
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
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: psd\n    kind: psd\n    params: { n: 0 }\n  - id: f\n    kind: psd-figure\n    inputs: { psd: psd }\n",
    );
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
    assert!(
        out.contains("p-seed1") && out.contains("p-seed2") && out.contains("f-seed2"),
        "{out}"
    );
    assert!(
        out.lines().any(|l| l.starts_with("f-seed2") && l.contains("[p-seed2]")),
        "{out}"
    );
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
    assert!(
        err.contains("params.dem.dt") && err.contains("explicit") && err.contains("e-9 s"),
        "{err}"
    );
    // The implicit default passes validation (checked without running: --explain).
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: c\n    kind: dem-column-prep\n    inputs: { psd: p }\n",
    );
    let (code, out, err) = t.cli(&["run", "--explain"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("rolling dashpot relaxation") && out.contains("implicit"),
        "{out}"
    );
}

// ---- The bad-input corpus (issue 8) ---------------------------------------------------
// Each case: exit code 2, no panic, and the message names the file and the key. Cases
// marked "was:" failed before issue 8 (wrong exit code, or no file/key in the message).

/// One malformed input: the pipeline text, extra files, the command, and what the
/// message must contain (file and key).
struct Case {
    name: &'static str,
    pipeline: &'static str,
    files: &'static [(&'static str, &'static str)],
    args: &'static [&'static str],
    must: &'static [&'static str],
}

const PSD: &str = "version: 1\nstages:\n  - id: p\n    kind: psd\n";
const PSD_FIG: &str =
    "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: f\n    kind: psd-figure\n    inputs: { psd: p }\n";

macro_rules! case {
    ($name:expr, $pipeline:expr, $args:expr, $must:expr) => {
        Case {
            name: $name,
            pipeline: $pipeline,
            files: &[],
            args: $args,
            must: $must,
        }
    };
    ($name:expr, $pipeline:expr, $files:expr, $args:expr, $must:expr) => {
        Case {
            name: $name,
            pipeline: $pipeline,
            files: $files,
            args: $args,
            must: $must,
        }
    };
}

const RUN: &[&str] = &["run", "--quiet"];
const PY: &str = "pipeline.yaml";

fn corpus() -> Vec<Case> {
    vec![
        // -- the pipeline file itself
        case!(
            "unknown top-level key",
            "version: 1\nverison: 2\nstages: []\n",
            RUN,
            &[PY, "verison"]
        ),
        case!(
            "unsupported version",
            "version: 2\nstages: []\n",
            RUN,
            &["pipeline.yaml:1", "version"]
        ),
        case!("missing stages", "version: 1\n", RUN, &[PY, "stages"]),
        // -- the DEM calibration's rule (issue 24): calib_target is flows | friction-angle
        case!(
            "calibration target that is not a rule",
            "version: 1\nstages:\n  - id: c\n    kind: dem-calibration\n    params_file: stages/c.yaml\n",
            &[("stages/c.yaml", "# targets\ncalib_target: phi\n")],
            RUN,
            &[
                "c.yaml:2", "stages[c].params.calib_target", "phi", "flows", "friction-angle"
            ]
        ),
        // -- a study kind's method
        case!(
            "study without its method",
            "version: 1\nstages:\n  - id: c\n    kind: work-precision\n    params: { variants: [] }\n",
            RUN,
            &[PY, "stages[c].params.method", "dem | cd | mpm"]
        ),
        case!(
            "method the study does not have",
            "version: 1\nstages:\n  - id: c\n    kind: column-collapse\n    params: { method: cd }\n",
            RUN,
            &[
                PY, "stages[c].params.method", "`cd` is not a method of this study", "dem | mpm"
            ]
        ),
        case!(
            "a method's own key under another method",
            "version: 1\nstages:\n  - id: c\n    kind: column-collapse\n    params: { method: mpm, stiffness_factor: 0.01 }\n",
            RUN,
            &[PY, "stages[c].params.stiffness_factor"]
        ),
        case!(
            "pile run with another method's block",
            "version: 1\nstages:\n  - id: c\n    kind: pile-run\n    params: { method: cd, energies_mgd: [10], mpm_friction: 0.4 }\n",
            RUN,
            &[
                PY, "stages[c].params.mpm_friction", "a parameter of method mpm", "the keys of method cd: cd"
            ]
        ),
        case!("stages not a list", "version: 1\nstages: 3\n", RUN, &[PY, "stages"]),
        // -- a choice (one-key mapping) given two keys: the profile layer names another
        //    choice with a scalar, which merges into the base's instead of replacing it
        case!(
            "a step choice holding two choices after the profile layer",
            "version: 1\nstages:\n  - id: c\n    kind: column-collapse\n    params: { method: mpm, mpm: { step: { fixed: { dt: 1.0e-6 } } } }\n    profiles: { quick: { mpm: { step: { cfl: true } } } }\n",
            RUN,
            &[PY, "stages[c].params.mpm.step", "`cfl`", "`fixed`", "exactly one"]
        ),
        // -- the critical-state shear protocol (issue 24 item 1)
        case!(
            "a preparation's pressures outside the protocol's",
            "version: 1\nstages:\n  - id: s\n    kind: dem-shear\n    params_file: stages/s.yaml\n",
            &[(
                "stages/s.yaml",
                "shear:\n  pressures: [1.0e+3, 4.0e+3]\n  preparations:\n    - { name: loose, friction: 1.0, rolling: true, pressures: [2.0e+3] }\n"
            )],
            RUN,
            &[
                "s.yaml",
                "stages[s].params.shear.preparations[0].pressures",
                "a non-empty subset of shear.pressures"
            ]
        ),
        case!(
            "a steady window that starts after the end of the shear",
            "version: 1\nstages:\n  - id: s\n    kind: dem-shear\n    params: { shear: { strain: 2.0, steady_from: 2.5 } }\n",
            RUN,
            &[PY, "stages[s].params.shear.steady_from", "[0, shear.strain)"]
        ),
        // -- on-demand studies
        case!(
            "on_demand that is not a boolean",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    on_demand: sometimes\n",
            RUN,
            &[PY, "on_demand"]
        ),
        case!(
            "keep --stage of a stage that is not on demand",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n",
            &["keep", "--profile", "quick", "--stage", "p"],
            &["keep --stage", "`p` is not an on-demand study", "on_demand: true"]
        ),
        case!(
            "yaml syntax",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n   params: {\n",
            RUN,
            &[PY, "YAML syntax error"]
        ),
        case!("empty file", "", RUN, &[PY]),
        case!(
            "stage missing id",
            "version: 1\nstages:\n  - kind: psd\n",
            RUN,
            &[PY, "stages[#0]", "id"]
        ),
        case!(
            "stage missing kind",
            "version: 1\nstages:\n  - id: p\n",
            RUN,
            &[PY, "stages[p]", "kind"]
        ),
        case!(
            "unknown kind",
            "version: 1\nstages:\n  - id: p\n    kind: psdd\n",
            RUN,
            &["pipeline.yaml:4", "stages[p].kind", "psdd"]
        ),
        case!(
            "unknown stage field",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    param: {}\n",
            RUN,
            &["pipeline.yaml:5", "stages[p].param"]
        ),
        case!(
            "params not a mapping",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params: 3\n",
            RUN,
            &[PY, "stages[p]", "params"]
        ),
        case!(
            "duplicate id",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: p\n    kind: psd\n",
            RUN,
            &[PY, "stages[p].id", "duplicate"]
        ),
        // -- ids (finding 2; all were exit 0)
        case!(
            "empty id",
            "version: 1\nstages:\n  - id: \"\"\n    kind: reference-laws\n",
            RUN,
            &[PY, "stages[#0].id", "empty"]
        ),
        case!(
            "id escaping reports/",
            "version: 1\nstages:\n  - id: ../../../escaped-laws\n    kind: reference-laws\n",
            RUN,
            &["pipeline.yaml:3", "../../../escaped-laws"]
        ),
        case!(
            "id with a slash",
            "version: 1\nstages:\n  - id: sub/laws\n    kind: reference-laws\n",
            RUN,
            &["pipeline.yaml:3", "sub/laws"]
        ),
        case!(
            "hidden id",
            "version: 1\nstages:\n  - id: .laws\n    kind: reference-laws\n",
            RUN,
            &[PY, ".laws", "start with"]
        ),
        case!(
            "id with a space",
            "version: 1\nstages:\n  - id: my laws\n    kind: reference-laws\n",
            RUN,
            &[PY, "my laws"]
        ),
        case!(
            "id with a newline",
            "version: 1\nstages:\n  - id: \"a\\nb\"\n    kind: reference-laws\n",
            RUN,
            &[PY, "a\\nb"]
        ),
        case!(
            "id with ..",
            "version: 1\nstages:\n  - id: a..b\n    kind: reference-laws\n",
            RUN,
            &[PY, "a..b", ".."]
        ),
        case!(
            "id with @",
            "version: 1\nstages:\n  - id: a@b\n    kind: reference-laws\n",
            RUN,
            &[PY, "a@b"]
        ),
        case!(
            "matrix value a mapping",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    matrix: { seed: [{x: 1, y: 2}] }\n",
            RUN,
            &["pipeline.yaml:5", "stages[p].matrix.seed", "not a number"]
        ),
        case!(
            "matrix value with a slash",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    matrix: { tag: [a/b] }\n",
            RUN,
            &[PY, "stages[p].matrix.tag", "a/b"]
        ),
        case!(
            "matrix member id taken",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    matrix: { seed: [1] }\n  - id: p-seed1\n    kind: psd\n",
            RUN,
            &[PY, "p-seed1", "duplicate"]
        ),
        case!(
            "empty matrix",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    matrix: { seed: [] }\n",
            RUN,
            &[PY, "stages[p].matrix.seed", "empty"]
        ),
        case!(
            "two matrix keys",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    matrix: { seed: [1], n: [50] }\n",
            RUN,
            &[PY, "stages[p].matrix"]
        ),
        // -- values
        case!(
            "negative count",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params:\n      n: -1\n",
            RUN,
            &["pipeline.yaml:6", "stages[p].params.n"]
        ),
        case!(
            "wrong type",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params: { n: lots }\n",
            RUN,
            &[PY, "stages[p].params.n"]
        ),
        case!(
            "misspelt key",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params:\n      d_mni_mm: 0.9\n",
            RUN,
            &["pipeline.yaml:6", "d_mni_mm"]
        ),
        case!(
            "nan (was: invalid type: null)",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params:\n      d_min_mm: .nan\n",
            RUN,
            &["pipeline.yaml:6", "stages[p].params.d_min_mm", "finite"]
        ),
        case!(
            "inf",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params:\n      d_max_mm: .inf\n",
            RUN,
            &["pipeline.yaml:6", "stages[p].params.d_max_mm", "finite"]
        ),
        case!(
            "minus inf",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params:\n      beta_a: -.inf\n",
            RUN,
            &[PY, "params.beta_a", "finite"]
        ),
        case!(
            "overflowing literal",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params:\n      beta_b: 1e999\n",
            RUN,
            &["pipeline.yaml:6", "params.beta_b"]
        ),
        case!(
            "absurd magnitude",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params:\n      d_max_mm: 1e308\n",
            RUN,
            &[PY, "params.d_max_mm", "plausible"]
        ),
        case!(
            "d_max below d_min",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params: { d_min_mm: 2.0, d_max_mm: 1.0 }\n",
            RUN,
            &[PY, "params.d_max_mm"]
        ),
        case!(
            "negative seed",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params: { seed: -1 }\n",
            RUN,
            &[PY, "params.seed"]
        ),
        case!(
            "restitution above 1",
            "version: 1\nstages:\n  - id: t\n    kind: material-table\n    params:\n      table: tab4-02\n      dem: { grain: { restitution: 1.5 } }\n",
            RUN,
            &[PY, "params.dem.grain.restitution", "(0, 1]"]
        ),
        case!(
            "density 1e308 (was: accepted)",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: c\n    kind: dem-column-prep\n    params:\n      dem: { density: 1e308 }\n    inputs: { psd: p }\n",
            RUN,
            &["pipeline.yaml:8", "stages[c].params.dem.density", "plausible"]
        ),
        case!(
            "friction 1e308 (was: accepted)",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: c\n    kind: dem-column-prep\n    params:\n      dem: { grain: { friction: 1e308 } }\n    inputs: { psd: p }\n",
            RUN,
            &[PY, "params.dem.grain.friction"]
        ),
        case!(
            "kn 1e308 (was: blames dt)",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: c\n    kind: dem-column-prep\n    params:\n      dem: { grain: { kn: 1e308 } }\n    inputs: { psd: p }\n",
            RUN,
            &[PY, "params.dem.grain.kn", "plausible"]
        ),
        case!(
            "explicit rolling damper",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: c\n    kind: dem-column-prep\n    params:\n      dem: { rolling: { damping: explicit } }\n    inputs: { psd: p }\n",
            RUN,
            &[PY, "params.dem.dt"]
        ),
        case!(
            "bad regimes",
            "version: 1\nstages:\n  - id: l\n    kind: reference-laws\n  - id: f\n    kind: power-law-fit\n    params: { regimes: 3 }\n    inputs: { data: l }\n",
            RUN,
            &[PY, "stages[f].params.regimes"]
        ),
        // -- stage files
        case!(
            "params_file missing",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params_file: stages/none.yaml\n",
            RUN,
            &["pipeline.yaml:5", "stages[p].params_file", "none.yaml"]
        ),
        case!(
            "params_file syntax",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params_file: stages/p.yaml\n",
            &[("stages/p.yaml", "n: [\n")],
            RUN,
            &["p.yaml", "YAML syntax error"]
        ),
        case!(
            "params_file a list",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params_file: stages/p.yaml\n",
            &[("stages/p.yaml", "- 1\n- 2\n")],
            RUN,
            &["p.yaml:1", "mapping"]
        ),
        case!(
            "params_file bad value",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params_file: stages/p.yaml\n",
            &[("stages/p.yaml", "# grains\nn: 0\n")],
            RUN,
            &["p.yaml:2", "params.n"]
        ),
        case!(
            "params_file misspelt key",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params_file: stages/p.yaml\n",
            &[("stages/p.yaml", "seeed: 4\n")],
            RUN,
            &["p.yaml:1", "seeed"]
        ),
        case!(
            "params_file nan",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params_file: stages/p.yaml\n",
            &[("stages/p.yaml", "n: 100\nd_min_mm: .nan\n")],
            RUN,
            &["p.yaml:2", "d_min_mm", "finite"]
        ),
        case!(
            "params_file unknown profile",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params_file: stages/p.yaml\n",
            &[("stages/p.yaml", "n: 100\nprofiles:\n  fast: { n: 50 }\n")],
            RUN,
            &["p.yaml:3", "profiles.fast"]
        ),
        case!(
            "params_file profiles not a mapping",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params_file: stages/p.yaml\n",
            &[("stages/p.yaml", "profiles: 3\n")],
            RUN,
            &["p.yaml", "profiles"]
        ),
        // -- profiles (finding 5: the paper layer was checked only when paper ran)
        case!(
            "unknown entry profile",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    profiles: { fast: { n: 50 } }\n",
            RUN,
            &[PY, "stages[p].profiles.fast"]
        ),
        case!(
            "bad paper layer inline (was: exit 0)",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    profiles:\n      paper: { n: -1 }\n",
            RUN,
            &[PY, "stages[p].params.n", "profile `paper`"]
        ),
        case!(
            "bad paper layer in a file (was: exit 0)",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    params_file: stages/p.yaml\n",
            &[("stages/p.yaml", "n: 100\nprofiles:\n  paper:\n    n: 0\n")],
            RUN,
            &["p.yaml:4", "params.n", "profile `paper`"]
        ),
        case!(
            "bad quick layer seen from paper",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    profiles:\n      quick: { d_min_mm: .nan }\n",
            &[],
            &["run", "--quiet", "--profile", "paper"],
            &[PY, "params.d_min_mm", "profile `quick`"]
        ),
        // -- inputs and roles (finding 5: were exit 1 at run time, or accepted)
        case!(
            "input names no stage",
            "version: 1\nstages:\n  - id: f\n    kind: psd-figure\n    inputs: { psd: nope }\n",
            RUN,
            &["pipeline.yaml:5", "stages[f].inputs", "nope"]
        ),
        case!(
            "unpaired matrix member",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n    matrix: { seed: [1] }\n  - id: f\n    kind: psd-figure\n    matrix: { seed: [1, 2] }\n    inputs: { psd: p }\n",
            RUN,
            &[PY, "stages[f-seed2].inputs", "no member"]
        ),
        case!(
            "cycle",
            "version: 1\nstages:\n  - id: a\n    kind: psd-figure\n    inputs: { psd: b }\n  - id: b\n    kind: psd-figure\n    inputs: { psd: a }\n",
            RUN,
            &[PY, "stages", "cycle"]
        ),
        case!(
            "self cycle",
            "version: 1\nstages:\n  - id: a\n    kind: psd-figure\n    inputs: { psd: a }\n",
            RUN,
            &[PY, "cycle: a -> a"]
        ),
        case!(
            "required input missing (was: exit 1)",
            "version: 1\nstages:\n  - id: f\n    kind: psd-figure\n",
            RUN,
            &["pipeline.yaml:3", "stages[f].inputs", "missing required input `psd`"]
        ),
        case!(
            "snapshot without column (was: exit 1)",
            "version: 1\nstages:\n  - id: s\n    kind: dem-snapshot\n",
            RUN,
            &[PY, "stages[s].inputs", "`column`"]
        ),
        case!(
            "fit overlay without laws (was: exit 1)",
            "version: 1\nstages:\n  - id: l\n    kind: reference-laws\n  - id: f\n    kind: power-law-fit\n    params: { x: a, y: eq4_6_runout, overlay_laws: [eq4_6_runout] }\n    inputs: { data: l }\n",
            RUN,
            &[PY, "stages[f].inputs", "`laws`"]
        ),
        case!(
            "role the kind does not read (was: accepted)",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: q\n    kind: psd\n    inputs: { seed_from: p }\n",
            RUN,
            &["pipeline.yaml:7", "stages[q].inputs", "seed_from"]
        ),
        case!(
            "list form with a foreign role",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: f\n    kind: psd-figure\n    inputs: [p]\n",
            RUN,
            &[PY, "stages[f].inputs", "role `p`"]
        ),
        case!(
            "two stages for a single role",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: q\n    kind: psd\n  - id: f\n    kind: psd-figure\n    inputs: { psd: [p, q] }\n",
            RUN,
            &[PY, "stages[f].inputs", "exactly one"]
        ),
        // -- the command line
        case!(
            "--set unknown stage",
            PSD,
            &["run", "--quiet", "--set", "nostage.n=3"],
            &["<command line>", "nostage"]
        ),
        case!(
            "--set without a key",
            PSD,
            &["run", "--quiet", "--set", "p=3"],
            &["<command line>", "p=3"]
        ),
        case!(
            "--set without a value",
            PSD,
            &["run", "--quiet", "--set", "p.n"],
            &["<command line>", "p.n"]
        ),
        case!(
            "--set invalid yaml",
            PSD,
            &["run", "--quiet", "--set", "p.n=["],
            &["<command line>", "p.n"]
        ),
        case!(
            "--set bad value",
            PSD,
            &["run", "--quiet", "--set", "p.n=-5"],
            &["<command line>", "stages[p].params.n"]
        ),
        case!(
            "--set nan",
            PSD,
            &["run", "--quiet", "--set", "p.d_min_mm=.nan"],
            &["<command line>", "params.d_min_mm", "finite"]
        ),
        case!(
            "--set unknown key",
            PSD,
            &["run", "--quiet", "--set", "p.nn=5"],
            &["<command line>", "params.nn"]
        ),
        case!(
            "--jobs 0 (was: silently 1)",
            PSD,
            &["run", "--quiet", "--jobs", "0"],
            &["--jobs", "at least 1"]
        ),
        case!(
            "--jobs not a number",
            PSD,
            &["run", "--quiet", "--jobs", "two"],
            &["--jobs"]
        ),
        case!(
            "--profile unknown",
            PSD,
            &["run", "--quiet", "--profile", "fast"],
            &["--profile", "fast"]
        ),
        case!(
            "--stage unknown",
            PSD,
            &["run", "--quiet", "--stage", "zzz"],
            &["unknown stage", "zzz"]
        ),
        case!(
            "--only unknown",
            PSD,
            &["run", "--quiet", "--only", "zzz"],
            &["--only zzz"]
        ),
        case!(
            "--only with inputs not cached",
            PSD_FIG,
            &["run", "--quiet", "--only", "f"],
            &["--only", "p (needed by f"]
        ),
        case!("params of no stage", PSD, &["params", "zzz"], &["zzz"]),
        case!(
            "status with a bad --set",
            PSD,
            &["status", "--set", "p.n=-5"],
            &["<command line>", "params.n"]
        ),
        case!(
            "list of a bad pipeline",
            "version: 1\nstages:\n  - id: p\n    kind: psdd\n",
            &["list"],
            &[PY, "stages[p].kind"]
        ),
        case!(
            "dag of a bad pipeline",
            "version: 1\nstages:\n  - id: p\n    kind: psdd\n",
            &["dag"],
            &[PY, "stages[p].kind"]
        ),
        case!(
            "clean with no pipeline file",
            PSD,
            &["clean", "--pipeline", "no-such.yaml"],
            &["no-such.yaml"]
        ),
        case!(
            "run with no pipeline file",
            PSD,
            &["run", "--pipeline", "no-such.yaml"],
            &["no-such.yaml"]
        ),
        // -- simulate (finding 5: errors pointed at the generated file)
        case!(
            "scene unknown key",
            PSD,
            &[("scene.yaml", "psd: { n: 50 }\npsdd: {}\n")],
            &["simulate", "scene.yaml", "--out", "sim-out"],
            &["scene.yaml:2", "psdd"]
        ),
        case!(
            "scene bad value",
            PSD,
            &[("scene.yaml", "psd:\n  n: 0\n")],
            &["simulate", "scene.yaml", "--out", "sim-out"],
            &["scene.yaml:2", "psd.n"]
        ),
        case!(
            "scene bad dem value",
            PSD,
            &[("scene.yaml", "dem:\n  grain:\n    restitution: 1.5\n")],
            &["simulate", "scene.yaml", "--out", "sim-out"],
            &["scene.yaml:3", "dem.grain.restitution"]
        ),
        case!(
            "scene bad run value",
            PSD,
            &[("scene.yaml", "run:\n  nope: 1\n")],
            &["simulate", "scene.yaml", "--out", "sim-out"],
            &["scene.yaml:2", "run.nope"]
        ),
        case!(
            "scene nan",
            PSD,
            &[("scene.yaml", "stiffness_factor: .nan\n")],
            &["simulate", "scene.yaml", "--out", "sim-out"],
            &["scene.yaml:1", "stiffness_factor", "finite"]
        ),
        case!(
            "scene syntax",
            PSD,
            &[("scene.yaml", "psd: {\n")],
            &["simulate", "scene.yaml", "--out", "sim-out"],
            &["scene.yaml", "YAML syntax error"]
        ),
        case!(
            "scene missing",
            PSD,
            &["simulate", "no-scene.yaml", "--out", "sim-out"],
            &["no-scene.yaml"]
        ),
        case!(
            "simulate --out a file",
            PSD,
            &[("scene.yaml", "psd: { n: 50 }\n")],
            &["simulate", "scene.yaml", "--out", "pipeline.yaml"],
            &["pipeline.yaml", "--out"]
        ),
        // -- benchmarks (refused before the machine line is printed)
        case!(
            "bench cd-dense size malformed",
            PSD,
            &["bench", "cd-dense", "--dense-size", "40by25"],
            &["--dense-size", "40by25", "COLSxROWS"]
        ),
        case!(
            "bench cd-dense size too small",
            PSD,
            &["bench", "cd-dense", "--dense-size", "1x0"],
            &["--dense-size", "1x0", "COLS >= 2"]
        ),
    ]
}

/// Paths in a case's arguments (`--out X`, `--pipeline X`, a scene file) made absolute
/// inside the project.
fn project_args(t: &TempProject, args: &[&str]) -> Vec<String> {
    let simulate = args.first() == Some(&"simulate");
    args.iter()
        .enumerate()
        .map(|(i, a)| {
            let prev = if i > 0 { args[i - 1] } else { "" };
            let is_path = prev == "--out" || prev == "--pipeline" || (simulate && a.ends_with(".yaml"));
            if is_path {
                t.path().join(a).to_string_lossy().to_string()
            } else {
                a.to_string()
            }
        })
        .collect()
}

#[test]
fn bad_input_corpus() {
    let cases = corpus();
    assert!(cases.len() >= 60, "the corpus has {} cases", cases.len());
    let mut failures = Vec::new();
    for c in &cases {
        let t = TempProject::new(c.pipeline);
        for (f, text) in c.files {
            t.write(f, text);
        }
        let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_granrepro"));
        if !c.args.contains(&"--pipeline") {
            cmd.arg("--pipeline").arg(t.pipeline());
        }
        let out = cmd.args(project_args(&t, c.args)).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        let code = out.status.code();
        let missing: Vec<&str> = c.must.iter().copied().filter(|m| !err.contains(m)).collect();
        if code != Some(2) || err.contains("panicked") || !missing.is_empty() {
            failures.push(format!("[{}] exit {code:?}, missing {missing:?}:\n{err}", c.name));
        }
        // Nothing is printed to stdout either (a benchmark's machine line, a plan's first
        // rows): a consumer reading stdout sees no half output.
        if !out.stdout.is_empty() {
            failures.push(format!(
                "[{}] printed to stdout although the input was rejected:\n{}",
                c.name,
                String::from_utf8_lossy(&out.stdout)
            ));
        }
        // Nothing is written for bad input.
        if t.path().join(".granrepro").exists()
            || t.path().join("reports").exists()
            || t.path().join("sim-out").exists()
        {
            failures.push(format!("[{}] wrote files although the input was rejected", c.name));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n\n")
    );
}

/// Finding 5: one bad entry produced 6–8 follow-on "missing input" errors, and a bad
/// value in a shared stage file was printed once per stage using it.
#[test]
fn one_error_per_root_cause() {
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: p\n    kind: psd\n    param: { n: 3 }\n  - id: f\n    kind: psd-figure\n    inputs: { psd: p }\n  - id: g\n    kind: psd-figure\n    inputs: { psd: p }\n  - id: t\n    kind: material-table\n    params: { table: tab4-02 }\n    inputs: { psd: p }\n",
    );
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert_eq!(err.matches("error:").count(), 1, "{err}");
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: a\n    kind: psd\n    params_file: stages/shared.yaml\n  - id: b\n    kind: psd\n    params_file: stages/shared.yaml\n  - id: c\n    kind: psd\n    params_file: stages/shared.yaml\n",
    );
    t.write("stages/shared.yaml", "n: 100\nd_min_mm: -1.0\n");
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert_eq!(err.matches("error:").count(), 1, "{err}");
    assert!(
        err.contains("shared.yaml:2") && err.contains("stages[a, b, c].params.d_min_mm"),
        "{err}"
    );
}

/// The shipped pipeline declares every role its kinds read (the role table in
/// `src/pipeline/check.rs` agrees with `pipeline.yaml`), for every profile.
#[test]
fn shipped_pipeline_is_valid() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for profile in ["quick", "paper"] {
        if let Err(d) = granrepro::pipeline::load(&root.join("pipeline.yaml"), profile, &[]) {
            panic!("{d}");
        }
    }
}

// ---- Issue 29 -------------------------------------------------------------------------

/// The repository's pipeline.yaml (edited by `edit`) and stages/ in a temp project.
fn shipped_project(edit: impl Fn(&str) -> String) -> TempProject {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let t = TempProject::new(&edit(&std::fs::read_to_string(root.join("pipeline.yaml")).unwrap()));
    fn copy(from: &std::path::Path, to: &std::path::Path) {
        std::fs::create_dir_all(to).unwrap();
        for e in std::fs::read_dir(from).unwrap().flatten() {
            if e.path().is_dir() {
                copy(&e.path(), &to.join(e.file_name()));
            } else {
                std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
            }
        }
    }
    copy(&root.join("stages"), &t.path().join("stages"));
    t
}

/// Issue 29.1: a matrix key that is not a parameter of the kind (and pairs with no input)
/// was dropped: `calib-point` swept on `a` passed `run --dry-run` and made stages
/// `calib-point-abig` whose parameters held no `a`. Matrix keys are now read by the kind's
/// schema as `--set` keys are, and values checked against the parameter's type before
/// any member id is formed.
#[test]
fn matrix_key_that_is_not_a_parameter_is_refused_with_file_stage_and_key() {
    let t = shipped_project(|p| {
        let (old, new) = ("matrix: { mu_r: [0.1, 0.3] }", "matrix: { a: [0.4, big, 0.8, 1] }");
        assert!(p.contains(old), "pipeline.yaml no longer sweeps calib-point on mu_r");
        p.replacen(old, new, 1)
    });
    let (code, out, err) = t.cli(&["run", "--dry-run"]);
    assert_eq!(code, 2, "{out}{err}");
    for must in [
        "pipeline.yaml:",
        "stages[calib-point].matrix.a",
        "`a` is not a parameter of dem-calibration-point",
        "mu_r",
    ] {
        assert!(err.contains(must), "missing {must:?}: {err}");
    }
    assert!(
        !out.contains("would run") && !err.contains("calib-point-abig"),
        "{out}{err}"
    );
    // A value of the wrong type for a parameter: named with its key, no member id formed.
    let t = TempProject::new("version: 1\nstages:\n  - id: p\n    kind: psd\n    matrix: { seed: [1, big] }\n");
    let (code, _, err) = t.cli(&["run", "--dry-run"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("pipeline.yaml:5") && err.contains("stages[p].matrix.seed") && err.contains("`big`"),
        "{err}"
    );
    assert!(
        !err.contains("p-seedbig"),
        "a member id was formed from the bad value: {err}"
    );
    // A key of no parameter and no input sweep, on a kind without inputs.
    let t = TempProject::new("version: 1\nstages:\n  - id: p\n    kind: psd\n    matrix: { nn: [50] }\n");
    let (code, _, err) = t.cli(&["run", "--dry-run"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("`nn` is not a parameter of psd") && err.contains("d_min_mm"),
        "{err}"
    );
}

/// An empty profile matrix leaves the stage out of that profile and only that one (the
/// paper profile's extra ensemble members); a stage of that profile that reads it is
/// refused at the empty list, naming the reader. Before, the empty list was taken as the stage's matrix and the
/// stage refused with "empty value list".
#[test]
fn empty_profile_matrix_leaves_the_stage_out_of_that_profile() {
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: p\n    kind: psd\n    params: { n: 50 }\n  - id: q\n    kind: psd\n    matrix: { seed: [1, 2] }\n    params: { n: 50 }\n    profiles: { quick: { matrix: { seed: [] } } }\n",
    );
    let (code, out, err) = t.cli(&["list"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("p") && !out.contains("q-seed"), "{out}");
    let (code, out, err) = t.cli(&["list", "--profile", "paper"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("q-seed1") && out.contains("q-seed2"), "{out}");
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: q\n    kind: psd\n    matrix: { seed: [1, 2] }\n    params: { n: 50 }\n    profiles: { quick: { matrix: { seed: [] } } }\n  - id: f\n    kind: psd-figure\n    inputs: { psd: q }\n",
    );
    let (code, out, err) = t.cli(&["run", "--dry-run"]);
    assert_eq!(code, 2, "{out}{err}");
    // The root cause is named: the empty list, and who reads the stage it leaves out.
    assert!(
        err.contains("stages[q].profiles.quick.matrix.seed") && err.contains("`f` reads it"),
        "{err}"
    );
}

/// `--set` applies to the run's profile, so it may name a stage only that profile has.
/// Before, every other profile was validated with the same overrides, and `run --profile
/// paper --set col-dem-a8.dem.dt=…` (a = 8 is a paper-only column) was refused with "no
/// stage `col-dem-a8` (profile `quick`)". A stage the run's profile lacks is still refused.
#[test]
fn set_may_name_a_stage_only_the_run_profile_has() {
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: p\n    kind: psd\n    params: { n: 50 }\n  - id: q\n    kind: psd\n    matrix: { seed: [1, 2] }\n    params: { n: 50 }\n    profiles: { quick: { matrix: { seed: [] } } }\n",
    );
    let (code, out, err) = t.cli(&["run", "--profile", "paper", "--dry-run", "--set", "q-seed1.n=60"]);
    assert_eq!(code, 0, "{out}{err}");
    // In the quick profile the stage does not exist: refused, naming the override.
    let (code, out, err) = t.cli(&["run", "--dry-run", "--set", "q-seed1.n=60"]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(
        err.contains("--set q-seed1.n") && err.contains("no stage `q-seed1`"),
        "{err}"
    );
    let (code, _, err) = t.cli(&["run", "--profile", "paper", "--dry-run", "--set", "zz.n=60"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("no stage `zz`"), "{err}");
}

/// A profile's matrix with the stage's own key but a value that is not a list
/// (`profiles: { quick: { matrix: { seed: 3 } } }`) was refused with "a profile's matrix must
/// sweep the stage's own matrix key", which blamed the key the user got right. It now names
/// the key and asks for a list. Found by the loader property test once the shipped pipeline
/// had a profile matrix on a second stage.
#[test]
fn profile_matrix_value_that_is_not_a_list_is_named_by_its_key() {
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: p\n    kind: psd\n    matrix: { seed: [1, 2] }\n    profiles: { quick: { matrix: { seed: 3 } } }\n",
    );
    let (code, out, err) = t.cli(&["run", "--dry-run"]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(
        err.contains("stages[p].profiles.quick.matrix.seed") && err.contains("must be a list"),
        "{err}"
    );
    assert!(!err.contains("must sweep the stage's own matrix key"), "{err}");
    // The wrong key keeps its own message.
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: p\n    kind: psd\n    matrix: { seed: [1, 2] }\n    profiles: { quick: { matrix: { n: [50] } } }\n",
    );
    let (code, _, err) = t.cli(&["run", "--dry-run"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("must sweep the stage's own matrix key") && err.contains("seed"),
        "{err}"
    );
}

/// Issue 29.2: an empty scene ran the defaults, which failed after running (exit 1: "the
/// PSD input `psd` has 3000 grains; a 0.0039 m² column needs about 3824"). It is refused.
#[test]
fn empty_scene_is_refused_pointing_at_the_example() {
    for text in ["", "  \n\n", "# a scene, some day\n", "{}\n", "~\n"] {
        let t = TempProject::new(PSD);
        t.write("scene.yaml", text);
        let scene = t.path().join("scene.yaml");
        let out = t.path().join("sim-out");
        let (code, _, err) = t.cli(&["simulate", scene.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        assert_eq!(code, 2, "{text:?}: {err}");
        assert!(
            err.contains("scene.yaml is empty") && err.contains("stages/scenes/example-column.yaml"),
            "{text:?}: {err}"
        );
        assert!(!out.exists(), "{text:?}: wrote {}", out.display());
    }
}

/// Issue 29.2: the defaults of a scene that names only its column (or its grain sizes)
/// must be consistent: the PSD holds the grains the column's prep rains (the `psd` kind's
/// default 3000 was short of the default column's ~3800). Checked with the prep's own
/// count on the real sample, without running the DEM.
#[test]
fn scene_without_psd_n_samples_enough_grains_for_its_column() {
    for text in [
        "column: { packing: ballistic }\n",
        "vtk: true\n",
        "column: { area_m2: 0.01, a: 2.0 }\n",
        "psd: { d_min_mm: 0.5, d_max_mm: 1.0, beta_a: 4.0, beta_b: 4.0 }\n",
    ] {
        let scene = std::path::Path::new("scene.yaml");
        let sf = granrepro::scene::parse_scene(scene, text).unwrap();
        let doc = serde_yaml::to_string(&granrepro::scene::scene_pipeline(scene, &sf)).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let p = granrepro::pipeline::load_text(&dir.path().join("pipeline.yaml"), &doc, dir.path(), "quick", &[])
            .unwrap_or_else(|d| panic!("{text:?}: {d}"));
        let psd: granrepro::stages::generic::psd::PsdParams =
            serde_json::from_value(p.get("psd").unwrap().params.clone()).unwrap();
        let area = p.get("column").unwrap().params["area_m2"].as_f64().unwrap();
        let d = psd.grading().sample(psd.n, psd.seed);
        // The prep's count (src/stages/column/dem_prep.rs, `run_prep`): 1.15 × 0.85 A / mean area.
        let mean_area = d.iter().map(|d| std::f64::consts::PI * 0.25 * d * d).sum::<f64>() / d.len() as f64;
        let k = (1.15 * area * 0.85 / mean_area).ceil() as usize;
        assert!(
            d.len() >= k,
            "{text:?}: the PSD has {} grains, the column rains {k}",
            d.len()
        );
    }
}

/// Issue 29, found by `tests/loader_props.rs`: problems the loader placed in the wrong file
/// or without the key. Each case: pipeline, stage file, what stderr must contain.
#[test]
fn loader_property_findings_name_the_file_and_key() {
    const W: &str = "version: 1\nstages:\n  - id: w\n    kind: work-precision\n    params_file: stages/w.yaml\n";
    const P: &str = "version: 1\nstages:\n  - id: p\n    kind: psd\n    params_file: stages/p.yaml\n";
    let cases: &[(&str, &str, &str, &[&str])] = &[
        // a problem inside a list of a stage file was blamed on pipeline.yaml
        (
            "list item",
            W,
            "method: cd\nvariants:\n  - { dt: big }\n  - { dt: 1.0e-4, tolerance: 1.0e-4 }\n",
            &["stages/w.yaml:", "variants[0].dt"],
        ),
        // a stage file's `profiles.quick` that is not a mapping replaced all params: "params.:"
        (
            "profile section",
            P,
            "n: 100\nprofiles:\n  quick: 2\n",
            &["p.yaml:3", "profiles.quick"],
        ),
        // a second YAML document: no line
        (
            "two documents",
            P,
            "n: 100\n---\nn: 200\n",
            &["p.yaml:2", "more than one document"],
        ),
        // `inputs: { psd: {} }`: "data did not match any variant of untagged enum InputsSpec"
        (
            "input role not an id",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: f\n    kind: psd-figure\n    inputs: { psd: {} }\n",
            "",
            &[
                "pipeline.yaml:7", "stages[f].inputs.psd", "input `psd` must name a stage id",
            ],
        ),
        // a missing input did not say which role
        (
            "missing input role",
            "version: 1\nstages:\n  - id: f\n    kind: psd-figure\n    inputs: { psd: \"\" }\n",
            "",
            &["stages[f].inputs", "(input `psd`)"],
        ),
        // a matrix over `dem.dt` replaced a `dem:` that is not a mapping, silently
        (
            "matrix under a scalar",
            "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: c\n    kind: dem-column-prep\n    params: { dem: fast }\n    matrix: { dem.dt: [1.0e-7] }\n    inputs: { psd: p }\n",
            "",
            &["pipeline.yaml", "stages[c-dem.dt1e-7].params.dem", "fast"],
        ),
    ];
    let mut failures = Vec::new();
    for (name, pipeline, file, must) in cases {
        let t = TempProject::new(pipeline);
        for f in ["stages/w.yaml", "stages/p.yaml"] {
            t.write(f, file);
        }
        let (code, _, err) = t.cli(&["run", "--dry-run"]);
        let missing: Vec<&&str> = must.iter().filter(|m| !err.contains(**m)).collect();
        if code != 2 || !missing.is_empty() {
            failures.push(format!("[{name}] exit {code}, missing {missing:?}:\n{err}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// A stage file outside the project (an absolute path, or one through `..`) is refused,
/// naming pipeline.yaml's `params_file` key: the old loader read it (the property test found
/// `../x` resolving to a stray file outside its temp project and blamed that file instead).
#[test]
fn a_stage_file_outside_the_project_is_refused_naming_params_file() {
    let t = TempProject::new("version: 1\nstages:\n  - id: psd\n    kind: psd\n    params_file: stages/../p.yaml\n");
    t.write("p.yaml", "n: 100\n");
    let (code, _, err) = t.cli(&["run", "--quiet", "--dry-run"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("pipeline.yaml:5") && err.contains("stages[psd].params_file"),
        "{err}"
    );
    assert!(err.contains("outside the project"), "{err}");
    let abs = t.path().join("p.yaml");
    let t2 = TempProject::new(&format!(
        "version: 1\nstages:\n  - id: psd\n    kind: psd\n    params_file: {}\n",
        abs.display()
    ));
    let (code, _, err) = t2.cli(&["run", "--quiet", "--dry-run"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("stages[psd].params_file"), "{err}");
}
