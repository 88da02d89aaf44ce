//! `granrepro simulate SCENE.yaml --out DIR`: one ad-hoc DEM column scene outside the
//! pipeline. The scene file uses the same parameter schemas as `stages/` (PSD, DEM solver,
//! column preparation, collapse run control); it is validated with file, line and key,
//! then run as a three-stage pipeline (psd → dem-column-prep → dem-collapse) whose cache
//! and reports live under DIR — so the outputs are the same tables, figures and VTK files.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::pipeline::{Project, RunOptions, load};

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
    if v.is_null() { serde_yaml::Value::Mapping(Default::default()) } else { v.clone() }
}

/// Run a scene; returns the process exit code (0 ok, 1 failed, 2 bad input).
pub fn simulate(scene: &Path, out: &Path, quiet: bool) -> i32 {
    let text = match std::fs::read_to_string(scene) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("error: {}: cannot read the scene file: {e}", scene.display());
            return 2;
        }
    };
    let sf: SceneFile = match serde_yaml::from_str(&text) {
        Ok(s) => s,
        Err(e) => {
            let line = e.location().map(|l| format!(":{}", l.line())).unwrap_or_default();
            eprintln!("error: {}{line}: {e}\n  help: scene keys: psd, dem, stiffness_factor, column, run, vtk", scene.display());
            return 2;
        }
    };
    if let Err(e) = std::fs::create_dir_all(out) {
        eprintln!("error: cannot create {}: {e}", out.display());
        return 2;
    }
    let mut prep = nonnull(&sf.column);
    let mut coll = serde_yaml::Mapping::new();
    if let serde_yaml::Value::Mapping(m) = &mut prep {
        m.insert("dem".into(), nonnull(&sf.dem));
        m.insert("stiffness_factor".into(), sf.stiffness_factor.into());
    }
    coll.insert("dem".into(), nonnull(&sf.dem));
    coll.insert("stiffness_factor".into(), sf.stiffness_factor.into());
    coll.insert("run".into(), nonnull(&sf.run));
    coll.insert("vtk".into(), sf.vtk.into());
    let mk = |id: &str, kind: &str, params: serde_yaml::Value, inputs: Option<(&str, &str)>| {
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
    };
    let stages = vec![
        mk("psd", "psd", nonnull(&sf.psd), None),
        mk("column", "dem-column-prep", prep, Some(("psd", "psd"))),
        mk("collapse", "dem-collapse", serde_yaml::Value::Mapping(coll), Some(("column", "column"))),
    ];
    let mut doc = serde_yaml::Mapping::new();
    doc.insert("version".into(), 1.into());
    doc.insert("description".into(), format!("generated from {} by granrepro simulate", scene.display()).into());
    doc.insert("stages".into(), serde_yaml::Value::Sequence(stages));
    let pfile = out.join("pipeline.yaml");
    if let Err(e) = std::fs::write(&pfile, serde_yaml::to_string(&serde_yaml::Value::Mapping(doc)).unwrap_or_default()) {
        eprintln!("error: cannot write {}: {e}", pfile.display());
        return 2;
    }
    let p = match load(&pfile, "quick", &[]) {
        Ok(p) => p,
        Err(d) => {
            eprintln!("{d}\n  note: stage `psd` ← scene key `psd`, `column` ← `column` + `dem`, `collapse` ← `run` + `dem` (in {})", scene.display());
            return 2;
        }
    };
    match crate::pipeline::run::run(&p, &Project::new(out), &RunOptions { jobs: 1, quiet, ..Default::default() }) {
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
