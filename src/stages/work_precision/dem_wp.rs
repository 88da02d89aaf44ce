//! `work-precision`, `method: dem` ([`super::study`]): DEM column run-out error against wall time over stiffness
//! and time-step fraction (ensembles of perturbed starts, re-settled per setting).

use serde::{Deserialize, Serialize};

use super::wp_summary::ensemble_error;
use crate::dem::DemParams;
use crate::dem::column::{CollapseParams, Variant, work_precision};
use crate::pipeline::context::{Output, StageCtx, frame};
use crate::stages::Validate;
use crate::stages::column::dem_common::{check_dem, column_from};
use crate::stages::column::dem_prep::PrepParams;
use crate::stages::kind::{CostCtx, Work};
use crate::validate::{Checker, Issue};

/// Parameters of a `work-precision` stage with `method: dem`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
#[derive(Default)]
pub struct WpParams {
    /// Base solver parameters (table 4.2).
    pub dem: DemParams,
    /// Variants: the first is the reference (stiffest, finest).
    pub variants: Vec<Variant>,
    /// Run control.
    pub run: CollapseParams,
    /// Perturbed starts per variant (the run-out is chaotic: errors are differences of
    /// ensemble means, with their standard error).
    pub ensemble: crate::stages::calib::dem_calibration::Ensemble,
    /// Grain-count knob: the variant (label) run on the coarser column of the optional
    /// input `coarser` (the same a, fewer grains); empty = the second variant.
    #[serde(skip_serializing_if = "String::is_empty")]
    pub grains_at: String,
}

impl Validate for WpParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_dem(&self.dem, 1.0, &mut c);
        c.check(
            self.variants.len() >= 2,
            "variants",
            self.variants.len(),
            "at least two (the first is the reference)",
        );
        for (i, v) in self.variants.iter().enumerate() {
            c.in_open_closed(&format!("variants[{i}].stiffness_factor"), v.stiffness_factor, 0.0, 1.0);
            c.in_open_closed(&format!("variants[{i}].dt_fraction"), v.dt_fraction, 0.0, 0.5);
        }
        c.check(
            self.ensemble.members >= 3 && self.ensemble.members <= 64,
            "ensemble.members",
            self.ensemble.members,
            "an integer in [3, 64] (an error needs a spread)",
        );
        if !self.grains_at.is_empty() {
            c.check(
                self.variants.iter().any(|v| v.label == self.grains_at),
                "grains_at",
                &self.grains_at,
                "the label of one of `variants`",
            );
        }
        c.issues
    }
}

pub(super) fn run(ctx: &StageCtx, mut p: WpParams) -> anyhow::Result<Output> {
    crate::stages::calib::dem_calibration::apply_calibration(ctx, &mut p.dem)?;
    let col = column_from(ctx.input("column")?, p.dem.density)?;
    let mut rows = work_precision(
        &col, &p.dem, &p.run, &p.variants, p.ensemble.members, p.ensemble.perturbation_m, p.ensemble.seed,
    )?;
    let mut grains: Vec<f64> = vec![col.state.len() as f64; rows.len()];
    // Grain-count knob: one variant on the coarser column, its error against the reference
    // (the stiffest, finest setting on the full column) as every other row's.
    if let Some(inp) = ctx.input_opt("coarser") {
        let coarse = column_from(inp, p.dem.density)?;
        let v = if p.grains_at.is_empty() {
            p.variants[1].clone()
        } else {
            p.variants
                .iter()
                .find(|v| v.label == p.grains_at)
                .cloned()
                .unwrap_or_else(|| p.variants[1].clone())
        };
        let mut r = work_precision(
            &coarse,
            &p.dem,
            &p.run,
            std::slice::from_ref(&v),
            p.ensemble.members,
            p.ensemble.perturbation_m,
            p.ensemble.seed,
        )?
        .remove(0);
        let (m0, s0, n0) = (rows[0].mean, rows[0].spread, rows[0].delta_l.len() as f64);
        let n = r.delta_l.len() as f64;
        r.error = (r.mean - m0).abs() / m0.abs().max(1e-12);
        r.error_spread = (r.spread * r.spread / n + s0 * s0 / n0).sqrt() / m0.abs().max(1e-12);
        r.variant.label = format!("{}-n{}", v.label, coarse.state.len());
        rows.push(r);
        grains.push(coarse.state.len() as f64);
    }
    let n_full = col.state.len() as f64;
    let mut out = Output::default();
    let idx: Vec<f64> = (0..rows.len()).map(|i| i as f64).collect();
    out.table(
        "table",
        frame(vec![
            ("variant", idx.clone()),
            (
                "stiffness_factor",
                rows.iter().map(|r| r.variant.stiffness_factor).collect(),
            ),
            ("dt_fraction", rows.iter().map(|r| r.variant.dt_fraction).collect()),
            ("grains", grains.clone()),
            // the first row is the reference; the others at the column's own size form the
            // stiffness × step sweep, the rest are the smaller (coarser) column's
            ("reference", (0..rows.len()).map(|i| (i == 0) as u8 as f64).collect()),
            ("full_size", grains.iter().map(|g| (*g == n_full) as u8 as f64).collect()),
            ("dt_s", rows.iter().map(|r| r.dt).collect()),
            ("steps", rows.iter().map(|r| r.steps as f64).collect()),
            ("members", rows.iter().map(|r| r.delta_l.len() as f64).collect()),
            ("runout_norm_mean", rows.iter().map(|r| r.mean).collect()),
            ("runout_norm_std", rows.iter().map(|r| r.spread).collect()),
            ("hf_over_l0", rows.iter().map(|r| r.h_final_over_l0).collect()),
            ("runout_rel_error", rows.iter().map(|r| r.error).collect()),
            ("runout_rel_error_se", rows.iter().map(|r| r.error_spread).collect()),
            // the other quantities the column figures report: duration (fig 4.11's stop) and
            // final energy (fig 4.13's E_p(end)/E_p(0)), same ensemble-mean measure
            (
                "duration_tau_mean",
                rows.iter()
                    .map(|r| ensemble_error(&r.duration, &rows[0].duration).0)
                    .collect(),
            ),
            (
                "duration_rel_error",
                rows.iter()
                    .map(|r| ensemble_error(&r.duration, &rows[0].duration).1)
                    .collect(),
            ),
            (
                "duration_rel_error_se",
                rows.iter()
                    .map(|r| ensemble_error(&r.duration, &rows[0].duration).2)
                    .collect(),
            ),
            (
                "ep_final_mean",
                rows.iter()
                    .map(|r| ensemble_error(&r.ep_final, &rows[0].ep_final).0)
                    .collect(),
            ),
            (
                "ep_final_rel_error",
                rows.iter()
                    .map(|r| ensemble_error(&r.ep_final, &rows[0].ep_final).1)
                    .collect(),
            ),
            (
                "ep_final_rel_error_se",
                rows.iter()
                    .map(|r| ensemble_error(&r.ep_final, &rows[0].ep_final).2)
                    .collect(),
            ),
        ])?,
    );
    out.table(
        "timing",
        frame(vec![
            ("variant", idx),
            ("wall_s", rows.iter().map(|r| r.wall_s).collect()),
            ("settle_wall_s", rows.iter().map(|r| r.settle_wall_s).collect()),
        ])?,
    );
    out.scalar("reference_runout_mean", rows[0].mean)
        .scalar("reference_runout_std", rows[0].spread)
        .scalar("grains", col.state.len() as f64)
        .scalar("members", p.ensemble.members as f64);
    for r in &rows {
        let key = r.variant.label.replace(|c: char| !c.is_ascii_alphanumeric(), "_");
        out.scalar(&format!("error_{key}"), r.error)
            .scalar(&format!("error_se_{key}"), r.error_spread)
            .scalar(&format!("runout_mean_{key}"), r.mean)
            .scalar(&format!("runout_std_{key}"), r.spread);
        let (_, de, dse) = ensemble_error(&r.duration, &rows[0].duration);
        let (_, ee, ese) = ensemble_error(&r.ep_final, &rows[0].ep_final);
        out.scalar(&format!("duration_error_{key}"), de)
            .scalar(&format!("duration_error_se_{key}"), dse)
            .scalar(&format!("ep_final_error_{key}"), ee)
            .scalar(&format!("ep_final_error_se_{key}"), ese);
    }
    out.note(format!(
        "Each setting re-settled at its own stiffness and step, then {} perturbed starts (≤ {:.0e} m). Reference: {} (k factor {}, Δt = {:.2} t_c) → ΔL = {:.4} ± {:.4} (s.d.). Per setting, mean ± s.d. and one-collapse wall time: {}.",
        p.ensemble.members, p.ensemble.perturbation_m, rows[0].variant.label, rows[0].variant.stiffness_factor, rows[0].variant.dt_fraction, rows[0].mean, rows[0].spread,
        rows.iter().map(|r| format!("{} {:.3} ± {:.3}, {:.1} s", r.variant.label, r.mean, r.spread, r.wall_s)).collect::<Vec<_>>().join("; ")
    ));
    Ok(out)
}

/// Cost: grains ∝ the input column's area; steps summed over the variants, times the
/// ensemble's members.
pub(super) fn cost(p: &WpParams, c: &CostCtx) -> Option<Work> {
    let area = c.input::<PrepParams>("column")?.area_m2;
    let steps: f64 = p
        .variants
        .iter()
        .map(|x| x.stiffness_factor.sqrt() / x.dt_fraction)
        .sum();
    Some((
        vec![("grains", area), ("steps", p.ensemble.members as f64 * steps)],
        false,
    ))
}
