//! `granrepro simulate SCENE.yaml --out DIR` for a CD scene (`engine: cd`): a shear test
//! (psd → cd-shear → the fig4-25 `plot`) or a pile work-precision set (one work-precision
//! stage), written as a small pipeline under DIR and run there like the DEM and MPM scenes
//! (same tables, figures, claims and exit codes).

use serde::{Deserialize, Serialize};

/// A CD scene for `granrepro simulate` (a file with `engine: cd`).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CdSceneFile {
    /// Must be `cd`.
    pub engine: String,
    /// `shear` (periodic shear → μ*(I)) or `pile` (deposit + impact, one or more variants).
    pub scene: String,
    /// CD solver parameters (schema of `stages/cd-solver.yaml`).
    #[serde(default)]
    pub cd: serde_yaml::Value,
    /// Shear scenes: grain sizes (schema of the `psd` kind).
    #[serde(default)]
    pub psd: serde_yaml::Value,
    /// Shear scenes: test settings (schema of `stages/cd-shear.yaml`'s `shear`).
    #[serde(default)]
    pub shear: serde_yaml::Value,
    /// Shear scenes: grains taken from the PSD.
    #[serde(default)]
    pub grains: Option<usize>,
    /// Pile scenes: schema of `stages/wp-cd-pile.yaml` (deposit, settle_time, v0, run_time,
    /// variants).
    #[serde(default)]
    pub pile: serde_yaml::Value,
}

/// Whether a scene file asks for the CD engine (`engine: cd`).
pub fn is_cd_scene(path: &std::path::Path) -> bool {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|t| serde_yaml::from_str::<serde_yaml::Value>(&t).ok())
        .and_then(|v| v.get("engine").and_then(|e| e.as_str()).map(|e| e == "cd"))
        .unwrap_or(false)
}

/// The figure of a shear scene: the project's declaration of figure 4.25(b), built in (a
/// scene runs outside the repository).
fn shear_figure() -> serde_yaml::Value {
    serde_yaml::from_str(include_str!("../stages/pile/fig4-25.yaml")).expect("stages/pile/fig4-25.yaml is valid YAML")
}

/// `granrepro simulate` for a CD scene: written as a small pipeline under `out` (psd →
/// cd-shear → the fig4-25 `plot`, or one work-precision stage, method cd) and run there, so the
/// outputs are the stages' tables, figures and claims. Exit code 0 ok, 1 failed, 2 bad input.
pub fn simulate_cd(scene: &std::path::Path, out: &std::path::Path, quiet: bool) -> i32 {
    let nonnull = |v: &serde_yaml::Value| {
        if v.is_null() {
            serde_yaml::Value::Mapping(Default::default())
        } else {
            v.clone()
        }
    };
    let text = match std::fs::read_to_string(scene) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("error: {}: cannot read the scene file: {e}", scene.display());
            return 2;
        }
    };
    let sf: CdSceneFile = match serde_yaml::from_str(&text) {
        Ok(s) => s,
        Err(e) => {
            let line = e.location().map(|l| format!(":{}", l.line())).unwrap_or_default();
            eprintln!(
                "error: {}{line}: {e}\n  help: CD scene keys: engine, scene (shear | pile), cd, psd, shear, grains, pile",
                scene.display()
            );
            return 2;
        }
    };
    let mk = crate::scene::stage_entry;
    let stages = match sf.scene.as_str() {
        "shear" => {
            let mut sh = serde_yaml::Mapping::new();
            sh.insert("cd".into(), nonnull(&sf.cd));
            sh.insert("shear".into(), nonnull(&sf.shear));
            if let Some(g) = sf.grains {
                sh.insert("grains".into(), (g as u64).into());
            }
            vec![
                mk("psd", "psd", nonnull(&sf.psd), None),
                mk(
                    "shear",
                    "cd-shear",
                    serde_yaml::Value::Mapping(sh),
                    Some(("psd", "psd")),
                ),
                mk("figure", "plot", shear_figure(), Some(("shear", "shear"))),
            ]
        }
        "pile" => {
            let mut pl = match nonnull(&sf.pile) {
                serde_yaml::Value::Mapping(m) => m,
                _ => {
                    eprintln!("error: {}: `pile` must be a mapping", scene.display());
                    return 2;
                }
            };
            pl.insert("method".into(), "cd".into());
            pl.insert("cd".into(), nonnull(&sf.cd));
            vec![mk("pile", "work-precision", serde_yaml::Value::Mapping(pl), None)]
        }
        other => {
            eprintln!(
                "error: {}: scene `{other}` is not a CD scene; expected `shear` or `pile`",
                scene.display()
            );
            return 2;
        }
    };
    if sf.engine != "cd" {
        eprintln!("error: {}: engine `{}` is not `cd`", scene.display(), sf.engine);
        return 2;
    }
    let mut doc = serde_yaml::Mapping::new();
    doc.insert("version".into(), 1.into());
    doc.insert(
        "description".into(),
        format!("generated from {} by granrepro simulate (CD)", scene.display()).into(),
    );
    doc.insert("stages".into(), serde_yaml::Value::Sequence(stages));
    // validated before anything is written; `out` must be new, empty or our own output
    crate::scene::run_generated(scene, &text, &serde_yaml::Value::Mapping(doc), out, quiet)
}

#[cfg(test)]
mod tests {
    use crate::stages::Validate;

    /// The built-in figure of a shear scene is the project's fig4-25 declaration, valid as a
    /// `plot` and reading only the role the scene gives it.
    #[test]
    fn the_shear_figure_is_a_valid_plot_of_the_shear_role() {
        let v = serde_json::to_value(super::shear_figure()).unwrap();
        let p: crate::stages::generic::plot::PlotParams = serde_json::from_value(v).unwrap();
        assert!(p.validate().is_empty(), "{:?}", p.validate());
        assert_eq!(p.roles(), vec!["shear"]);
    }
}
