//! `granrepro simulate SCENE.yaml --out DIR` for an MPM column (`engine: mpm`): one
//! `column-collapse` stage (`method: mpm`) with the scene's solver, material and geometry (table 4.3 values
//! unless given; no DEM calibration inputs), validated — CFL pre-flight and grid
//! containment included — before anything is written, then run under DIR like the DEM and
//! CD scenes (same tables, figures, claims and exit codes).

use std::path::Path;

use serde::{Deserialize, Serialize};

/// The MPM scene file.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MpmSceneFile {
    /// Must be `mpm`.
    pub engine: String,
    /// Solver and material (schema of `stages/mpm-column.yaml`).
    #[serde(default)]
    pub mpm: serde_yaml::Value,
    /// Aspect ratio H_0/L_0.
    #[serde(default)]
    pub a: Option<f64>,
    /// Column area [m²].
    #[serde(default)]
    pub area_m2: Option<f64>,
    /// Run control (schema of the `column-collapse` kind's `run`, method mpm).
    #[serde(default)]
    pub run: serde_yaml::Value,
}

/// Is this an MPM scene file (`engine: mpm`)?
pub fn is_mpm_scene(path: &Path) -> bool {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|t| serde_yaml::from_str::<serde_yaml::Value>(&t).ok())
        .and_then(|v| v.get("engine").and_then(|e| e.as_str()).map(|e| e == "mpm"))
        .unwrap_or(false)
}

/// Run an MPM scene; exit code 0 ok, 1 failed, 2 bad input (nothing written).
pub fn simulate_mpm(scene: &Path, out: &Path, quiet: bool) -> i32 {
    let text = match std::fs::read_to_string(scene) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("error: {}: cannot read the scene file: {e}", scene.display());
            return 2;
        }
    };
    let v: serde_yaml::Value = match serde_yaml::from_str(&text) {
        Ok(v) => v,
        Err(e) => {
            let line = e.location().map(|l| format!(":{}", l.line())).unwrap_or_default();
            eprintln!("error: {}{line}: YAML syntax error: {e}", scene.display());
            return 2;
        }
    };
    if let Some((key, value, allowed)) = crate::pipeline::check::bad_numbers(&v).into_iter().next() {
        let line = crate::pipeline::diag::locate(&text, &key.split('.').collect::<Vec<_>>(), 1)
            .map(|l| format!(":{l}"))
            .unwrap_or_default();
        eprintln!(
            "error: {}{line}: {key}: value {value} is not allowed\n  help: {allowed}",
            scene.display()
        );
        return 2;
    }
    let sf: MpmSceneFile = match serde_yaml::from_value(v) {
        Ok(s) => s,
        Err(e) => {
            eprintln!(
                "error: {}: {e}\n  help: MPM scene keys: engine, mpm, a, area_m2, run",
                scene.display()
            );
            return 2;
        }
    };
    let mut m = serde_yaml::Mapping::new();
    if !sf.mpm.is_null() {
        m.insert("mpm".into(), sf.mpm.clone());
    }
    if let Some(a) = sf.a {
        m.insert("a".into(), a.into());
    }
    if let Some(x) = sf.area_m2 {
        m.insert("area_m2".into(), x.into());
    }
    if !sf.run.is_null() {
        m.insert("run".into(), sf.run.clone());
    }
    m.insert("use_dem_calibration".into(), false.into());
    m.insert("method".into(), "mpm".into());
    let stages = vec![crate::scene::stage_entry(
        "collapse",
        "column-collapse",
        serde_yaml::Value::Mapping(m),
        None,
    )];
    let mut doc = serde_yaml::Mapping::new();
    doc.insert("version".into(), 1.into());
    doc.insert(
        "description".into(),
        format!("generated from {} by granrepro simulate (MPM)", scene.display()).into(),
    );
    doc.insert("stages".into(), serde_yaml::Value::Sequence(stages));
    crate::scene::run_generated(scene, &text, &serde_yaml::Value::Mapping(doc), out, quiet)
}
