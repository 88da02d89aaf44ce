//! What the MPM stage kinds share: the DEM-calibrated friction angle and modulus injected
//! through the DAG, the parameter check with its CFL pre-flight, and the `--explain` table.
//!
//! Multi-scale link: when a stage declares the inputs `shear` (DEM periodic shear test,
//! scalar `friction_angle_deg`) and/or `compression` (DEM confined compression, scalar
//! `youngs_modulus_pa`), those measured values replace table 4.3's φ and E — so a change
//! to a DEM parameter re-runs these stages through the DAG. `use_dem_calibration: false`
//! keeps the table values for comparison.

use crate::mpm::{Model, MpmParams};
use crate::pipeline::context::StageCtx;
use crate::validate::Checker;

/// Inject the DEM-calibrated friction angle and modulus; returns a note for the report.
pub(crate) fn calibrate(ctx: &StageCtx, p: &mut MpmParams, enabled: bool) -> anyhow::Result<String> {
    if !enabled {
        return Ok(format!(
            "table 4.3 values: φ = {}°, E = {:.3e} Pa (DEM calibration disabled)",
            p.material.friction_deg, p.material.young_pa
        ));
    }
    let mut parts = Vec::new();
    if let Some(s) = ctx.input_opt("shear") {
        p.material.friction_deg = s.scalar("friction_angle_deg")?;
        parts.push(format!("φ = {:.2}° from `{}`", p.material.friction_deg, s.id));
        // μ(I)'s quasi-static friction is the same measured φ (docs/definitions.md I6: the
        // chapter's μ_min is tan of its critical-state angle), so μ(I) and Mohr–Coulomb
        // differ only by the rate term — the comparison of figs 4.14–4.15.
        let mu = p.material.friction_deg.to_radians().tan();
        match &mut p.material.model {
            Model::MuILinear { mu_min, .. } => {
                *mu_min = mu;
                parts.push(format!("μ_min = tan φ = {mu:.4}"));
            }
            Model::MuIJop { mu_s, mu_2, .. } => {
                let spread = *mu_2 - *mu_s;
                *mu_s = mu;
                *mu_2 = mu + spread;
                parts.push(format!("μ_s = tan φ = {mu:.4}"));
            }
            _ => {}
        }
    } else {
        parts.push(format!("φ = {}° (table 4.3)", p.material.friction_deg));
    }
    if let Some(c) = ctx.input_opt("compression") {
        p.material.young_pa = c.scalar("youngs_modulus_pa")?;
        parts.push(format!("E = {:.3e} Pa from `{}`", p.material.young_pa, c.id));
    } else {
        parts.push(format!("E = {:.3e} Pa (table 4.3)", p.material.young_pa));
    }
    Ok(parts.join(", "))
}

/// Largest speed the validation-time pre-flight expects: √(2 g H_0) of the tallest
/// column (a = 10, H_0 ≈ 0.197 m), docs/definitions.md c.3.
pub(crate) const PREFLIGHT_V_MAX: f64 = 1.97;

pub(crate) fn check_mpm(p: &MpmParams, c: &mut Checker) {
    for i in p.validate() {
        c.fail(&format!("mpm.{}", i.key), i.value, &i.allowed);
    }
    if !c.issues.is_empty() {
        return;
    }
    let dt = crate::mpm::preflight::planned_dt(p, PREFLIGHT_V_MAX);
    if let Err(e) = crate::mpm::preflight::preflight(p, dt, PREFLIGHT_V_MAX) {
        c.fail(
            "mpm.step",
            format!("{dt:.3e} s"),
            &format!("a stable step — {e}. `granrepro run --explain` prints the CFL table"),
        );
    }
}

/// `--explain`: the CFL pre-flight table of an MPM stage.
pub(crate) fn explain_mpm(v: &serde_json::Value) -> String {
    let p: MpmParams = v
        .get("mpm")
        .cloned()
        .and_then(|d| serde_json::from_value(d).ok())
        .unwrap_or_default();
    preflight_mpm(&p)
}

/// The MPM pre-flight: the CFL table of `p`'s planned step.
pub(crate) fn preflight_mpm(p: &MpmParams) -> String {
    let dt = crate::mpm::preflight::planned_dt(p, PREFLIGHT_V_MAX);
    match crate::mpm::preflight::preflight(p, dt, PREFLIGHT_V_MAX) {
        Ok(r) => format!("{r}"),
        Err(e) => format!("refused: {e}"),
    }
}

/// Material points of a column of `area` at `ppc` per cell of size `h`.
pub(crate) fn points(area: f64, ppc: f64, h: f64) -> f64 {
    area * ppc / (h * h)
}

/// CFL steps per simulated second at Courant number `k` and cell size `h`.
pub(crate) fn cfl(m: &MpmParams, k: f64, h: f64) -> f64 {
    m.material.p_wave_speed() / (k * h)
}
