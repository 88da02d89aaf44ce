//! `granrepro simulate SCENE.yaml --out DIR`: one ad-hoc DEM column scene outside the
//! pipeline. The scene file uses the same parameter schemas as `stages/` (PSD, DEM solver,
//! column preparation, collapse run control); it is validated with file, line and key,
//! then run as a three-stage pipeline (psd → dem-column-prep → column-collapse) whose cache
//! and reports live under DIR — so the outputs are the same tables, figures and VTK files.
//! Problems are reported against the scene file's keys and lines; nothing is written
//! until the scene is valid, and DIR must be new, empty, or an earlier simulate output
//! (marked by a `.granrepro-simulate` file). An empty scene file is refused (exit 2, pointing
//! at the example); a scene without `psd.n` gets enough grains for its column
//! ([`default_psd_n`]), so a scene naming only its column (or only its grain sizes) runs.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::pipeline::profiles::load_text;
use crate::pipeline::{Project, RunOptions};

/// The scene file.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Grain sizes (schema of the `psd` kind).
    #[serde(default)]
    pub psd: serde_yaml::Value,
    /// DEM solver parameters (schema of `stages/dem-column.yaml`).
    #[serde(default)]
    pub dem: serde_yaml::Value,
    /// Contact softening factor (1 = as given).
    #[serde(default = "one")]
    pub stiffness_factor: f64,
    /// Column preparation (schema of the `dem-column-prep` kind, without `dem`).
    #[serde(default)]
    pub column: serde_yaml::Value,
    /// Run control (schema of `stages/col-dem.yaml`'s `run`).
    #[serde(default)]
    pub run: serde_yaml::Value,
    /// Write `.vtp` snapshots.
    #[serde(default)]
    pub vtk: bool,
}

fn one() -> f64 {
    1.0
}

fn nonnull(v: &serde_yaml::Value) -> serde_yaml::Value {
    if v.is_null() {
        serde_yaml::Value::Mapping(Default::default())
    } else {
        v.clone()
    }
}

/// Marker file in a directory `simulate` made: `--out` may reuse it.
pub const OUT_MARK: &str = ".granrepro-simulate";

/// Is `out` usable: missing, empty, or one of simulate's own output directories?
fn check_out(out: &Path) -> Result<(), String> {
    if !out.exists() {
        return Ok(());
    }
    if !out.is_dir() {
        return Err(format!("{}: --out must be a directory; it is a file", out.display()));
    }
    let mut entries = std::fs::read_dir(out).map_err(|e| format!("cannot read {}: {e}", out.display()))?;
    if entries.next().is_none() || out.join(OUT_MARK).is_file() {
        return Ok(());
    }
    Err(format!(
        "{}: --out is a non-empty directory that `granrepro simulate` did not make; nothing written\n  help: pass a new or empty directory (simulate writes pipeline.yaml, .granrepro/ and reports/ there)",
        out.display()
    ))
}

/// The scene key of a generated stage's parameter (`stages[column].params.dem.kn` →
/// `dem.kn`), so problems point at the scene file.
fn scene_key(diag_key: &str) -> String {
    let Some(rest) = diag_key.strip_prefix("stages[") else {
        return diag_key.to_string();
    };
    let Some((stage, rest)) = rest.split_once(']') else {
        return diag_key.to_string();
    };
    let param = rest.strip_prefix(".params.").unwrap_or(rest.trim_start_matches('.'));
    let top = param.split('.').next().unwrap_or("");
    match (stage, top) {
        (_, "dem" | "stiffness_factor" | "vtk") => param.to_string(),
        ("psd", _) => format!("psd.{param}"),
        ("column", _) => format!("column.{param}"),
        ("collapse", "run" | "mpm" | "a" | "area_m2") => param.to_string(),
        _ => format!("{stage}.{param}"),
    }
}

/// Print the pipeline's problems as problems of the scene file (its keys and lines).
fn report_scene_problems(scene: &Path, text: &str, d: &crate::pipeline::Diagnostics) {
    let mut seen = std::collections::HashSet::new();
    for x in &d.0 {
        let key = scene_key(&x.key);
        if !seen.insert((key.clone(), x.message.clone())) {
            continue;
        }
        let parts: Vec<&str> = key.split('.').collect();
        let line = crate::pipeline::diag::locate(text, &parts, 1)
            .map(|l| format!(":{l}"))
            .unwrap_or_default();
        eprintln!("error: {}{line}: {key}: {}", scene.display(), x.message);
        if !x.help.is_empty() {
            eprintln!("  help: {}", x.help);
        }
    }
    eprintln!("{} error(s); nothing was run or written", seen.len());
}

/// Parse the scene file, naming the file, line and key of a problem; an empty scene is
/// refused.
pub fn parse_scene(scene: &Path, text: &str) -> Result<SceneFile, String> {
    const KEYS: &str = "scene keys: psd, dem, stiffness_factor, column, run, vtk";
    refuse_empty(scene, text)?;
    let v: serde_yaml::Value = serde_yaml::from_str(text).map_err(|e| {
        let line = e.location().map(|l| format!(":{}", l.line())).unwrap_or_default();
        format!("{}{line}: YAML syntax error: {e}\n  help: {KEYS}", scene.display())
    })?;
    if let Some((key, value, allowed)) = crate::pipeline::check::bad_numbers(&v).into_iter().next() {
        let line = crate::pipeline::diag::locate(text, &key.split('.').collect::<Vec<_>>(), 1)
            .map(|l| format!(":{l}"))
            .unwrap_or_default();
        return Err(format!(
            "{}{line}: {key}: value {value} is not allowed\n  help: {allowed}",
            scene.display()
        ));
    }
    serde_path_to_error::deserialize::<_, SceneFile>(v).map_err(|e| {
        let inner = e.inner().to_string();
        let key = match inner.split('`').nth(1) {
            Some(f) if inner.starts_with("unknown field") => f.to_string(),
            _ => e.path().to_string(),
        };
        let line = crate::pipeline::diag::locate(text, &key.split('.').collect::<Vec<_>>(), 1)
            .map(|l| format!(":{l}"))
            .unwrap_or_default();
        format!("{}{line}: {key}: {inner}\n  help: {KEYS}", scene.display())
    })
}

/// The example scene a refusal points to.
pub const EXAMPLE_SCENE: &str = "stages/scenes/example-column.yaml";

/// An empty scene (nothing, whitespace, comments, `~` or `{}`) would run the defaults of
/// every key, which is never what was meant: refuse it, pointing at the example.
fn refuse_empty(scene: &Path, text: &str) -> Result<(), String> {
    let empty = match serde_yaml::from_str::<serde_yaml::Value>(text) {
        Ok(serde_yaml::Value::Null) => true,
        Ok(serde_yaml::Value::Mapping(m)) => m.is_empty(),
        _ => false, // anything else is reported by the parser with its line
    };
    if !empty {
        return Ok(());
    }
    let name = scene
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    Err(format!(
        "{}: {name} is empty: a scene states at least its grains or its column\n  help: start from {EXAMPLE_SCENE} (keys psd, dem, stiffness_factor, column, run, vtk)",
        scene.display()
    ))
}

/// The PSD size of a scene that does not give `psd.n`: enough grains for its ballistic
/// column whatever the grading. The prep rains ⌈1.15 · 0.85 A / mean grain area⌉ grains
/// and refuses a shorter PSD; the smallest grain bounds that mean, so
/// n = ⌈1.15 · 0.85 A / (π r_min²)⌉ always suffices. (The `psd` kind's own default, 3000,
/// is PSD-COL's count: the default 3.9e-3 m² column needs about 3800 of its grains, so a
/// scene naming neither would fail at the prep.) Sampling is cheap and the prep rains only
/// what it needs. None when the sizes are not valid (the stages report them) or the count
/// is beyond the `psd` kind's limit.
pub fn default_psd_n(sf: &SceneFile) -> Option<u64> {
    let given = |v: &serde_yaml::Value, k: &str| v.get(k).map(|x| x.as_f64());
    if sf.psd.get("n").is_some() {
        return None;
    }
    let d_min_mm =
        given(&sf.psd, "d_min_mm").unwrap_or(Some(crate::stages::generic::psd::PsdParams::default().d_min_mm))?;
    let area =
        given(&sf.column, "area_m2").unwrap_or(Some(crate::stages::column::dem_prep::PrepParams::default().area_m2))?;
    let r_min = 0.5e-3 * d_min_mm;
    let n = (1.15 * 0.85 * area / (std::f64::consts::PI * r_min * r_min)).ceil();
    (n.is_finite() && r_min > 0.0 && area > 0.0 && n <= 1e7).then_some((n as u64).max(10))
}

/// The generated three-stage pipeline of a scene (`psd` → `column` → `collapse`).
pub fn scene_pipeline(scene: &Path, sf: &SceneFile) -> serde_yaml::Value {
    let mut psd = nonnull(&sf.psd);
    if let (Some(n), serde_yaml::Value::Mapping(m)) = (default_psd_n(sf), &mut psd) {
        m.insert("n".into(), n.into());
    }
    let mut prep = nonnull(&sf.column);
    let mut coll = serde_yaml::Mapping::new();
    if let serde_yaml::Value::Mapping(m) = &mut prep {
        m.insert("dem".into(), nonnull(&sf.dem));
        m.insert("stiffness_factor".into(), sf.stiffness_factor.into());
    }
    coll.insert("method".into(), "dem".into());
    coll.insert("dem".into(), nonnull(&sf.dem));
    coll.insert("stiffness_factor".into(), sf.stiffness_factor.into());
    coll.insert("run".into(), nonnull(&sf.run));
    coll.insert("vtk".into(), sf.vtk.into());
    let mk = stage_entry;
    let stages = vec![
        mk("psd", "psd", psd, None),
        mk("column", "dem-column-prep", prep, Some(("psd", "psd"))),
        mk(
            "collapse",
            "column-collapse",
            serde_yaml::Value::Mapping(coll),
            Some(("column", "column")),
        ),
    ];
    let mut doc = serde_yaml::Mapping::new();
    doc.insert("version".into(), 1.into());
    doc.insert(
        "description".into(),
        format!("generated from {} by granrepro simulate", scene.display()).into(),
    );
    doc.insert("stages".into(), serde_yaml::Value::Sequence(stages));
    serde_yaml::Value::Mapping(doc)
}

/// Run a scene; returns the process exit code (0 ok, 1 failed, 2 bad input). Nothing is
/// written before the scene is valid and `out` is usable.
pub fn simulate(scene: &Path, out: &Path, quiet: bool) -> i32 {
    let text = match std::fs::read_to_string(scene) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("error: {}: cannot read the scene file: {e}", scene.display());
            return 2;
        }
    };
    let sf = match parse_scene(scene, &text) {
        Ok(s) => s,
        Err(m) => {
            eprintln!("error: {m}");
            return 2;
        }
    };
    if let Err(m) = preflight_scene_sizes(scene, &text, &sf) {
        eprintln!("error: {m}");
        return 2;
    }
    run_generated(scene, &text, &scene_pipeline(scene, &sf), out, quiet)
}

/// The stage validation audits the step on PSD-COL's sizes (it cannot see the grains);
/// a scene states its own d_min and d_max, so audit those too (a wider PSD has smaller,
/// faster grains: r = 6 needs a smaller step than PSD-COL).
fn preflight_scene_sizes(scene: &Path, text: &str, sf: &SceneFile) -> Result<(), String> {
    let num = |k: &str| sf.psd.get(k).and_then(|v| v.as_f64());
    let (Some(dmin), Some(dmax)) = (num("d_min_mm"), num("d_max_mm")) else {
        return Ok(());
    };
    let Ok(dem) = serde_yaml::from_value::<crate::dem::DemParams>(nonnull(&sf.dem)) else {
        return Ok(());
    };
    if !(dmin > 0.0 && dmax >= dmin) || !dem.validate().is_empty() || !(sf.stiffness_factor > 0.0) {
        return Ok(()); // reported by the stage validation
    }
    let run = dem.softened(sf.stiffness_factor);
    let sizes = crate::dem::SizeClasses {
        r_min: 0.5e-3 * dmin,
        r_mean: 0.25e-3 * (dmin + dmax),
        r_max: 0.5e-3 * dmax,
    };
    match crate::dem::preflight(&run, sizes, true, run.dt) {
        Ok(_) => Ok(()),
        Err(e) => {
            let line = crate::pipeline::diag::locate(text, &["dem", "dt"], 1)
                .map(|l| format!(":{l}"))
                .unwrap_or_default();
            Err(format!(
                "{}{line}: dem.dt: {:.3e} s (stiffness_factor {}) is unstable for this scene's grains (d_min = {dmin} mm): {e}\n  help: `granrepro run --explain` prints every time scale",
                scene.display(),
                run.dt,
                sf.stiffness_factor
            ))
        }
    }
}

/// One stage entry of a generated pipeline: `id`, `kind`, `params` and at most one input
/// (role, stage id). Used by every engine's `simulate`.
pub fn stage_entry(id: &str, kind: &str, params: serde_yaml::Value, inputs: Option<(&str, &str)>) -> serde_yaml::Value {
    let mut m = serde_yaml::Mapping::new();
    m.insert("id".into(), id.into());
    m.insert("kind".into(), kind.into());
    m.insert("params".into(), params);
    if let Some((role, id)) = inputs {
        let mut i = serde_yaml::Mapping::new();
        i.insert(role.into(), id.into());
        m.insert("inputs".into(), serde_yaml::Value::Mapping(i));
    }
    serde_yaml::Value::Mapping(m)
}

/// Validate the pipeline generated from a scene file (problems reported against the scene
/// file's lines), check that `out` is usable, and only then write it and run. Shared by
/// every engine's `simulate` (DEM columns here, CD and MPM scenes in `scene_cd.rs`, `scene_mpm.rs`).
pub fn run_generated(scene: &Path, text: &str, generated: &serde_yaml::Value, out: &Path, quiet: bool) -> i32 {
    let doc = serde_yaml::to_string(generated).unwrap_or_default();
    let pfile = out.join("pipeline.yaml");
    let p = match load_text(&pfile, &doc, out, "quick", &[]) {
        Ok(p) => p,
        Err(d) => {
            report_scene_problems(scene, text, &d);
            return 2;
        }
    };
    if let Err(m) = check_out(out) {
        eprintln!("error: {m}");
        return 2;
    }
    let written = crate::pipeline::fsio::create_dir_all(out)
        .and_then(|()| crate::pipeline::fsio::write_atomic(&out.join(OUT_MARK), b"made by granrepro simulate\n"))
        .and_then(|()| crate::pipeline::fsio::write_atomic(&pfile, doc.as_bytes()));
    if let Err(e) = written {
        eprintln!("error: {e}");
        return 1;
    }
    match crate::pipeline::run::run(
        &p,
        &Project::new(out),
        &RunOptions {
            jobs: 1,
            quiet,
            ..Default::default()
        },
    ) {
        Ok(s) if !s.failed() => {
            println!("outputs in {}", out.join("reports").join("quick").display());
            0
        }
        Ok(s) => {
            for r in &s.stages {
                if let crate::pipeline::Outcome::Failed(m) = &r.outcome {
                    eprintln!("error: {}: {m}", r.id);
                }
            }
            1
        }
        Err(e) => {
            eprintln!("error: {e}");
            2
        }
    }
}
