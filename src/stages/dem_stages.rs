//! DEM stage kinds: column preparation, collapse, snapshots, the two calibration tests
//! that feed the MPM through the DAG (periodic shear → friction angle, confined
//! compression → modulus) and the DEM work-precision sweep.
//!
//! Every kind takes `dem` (the solver's own parameter schema, `stages/dem-column.yaml`)
//! and `stiffness_factor`: the quick profile softens k_n, k_t, k_r by this factor (the
//! step grows by 1/√factor); what that costs in accuracy is measured by
//! `wp-dem-column` and printed on the figures.

use serde::{Deserialize, Serialize};

use super::column::dem_common::{check_dem, column_from, explain_dem};
use super::wp_summary::ensemble_error;
use crate::dem::DemParams;
use crate::dem::column::{CollapseParams, Variant, work_precision};
use crate::dem::compress::{CompressionParams, compression_test};
use crate::dem::shear::{ShearParams, shear_test};
use crate::pipeline::context::{Claim, Output, StageCtx, col_f64, frame};
use crate::report::plot::{Chart, Series, Style, footer};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Parameters of a `dem-shear` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShearStageParams {
    /// Solver parameters.
    pub dem: DemParams,
    /// Softening.
    pub stiffness_factor: f64,
    /// Test settings.
    pub shear: ShearParams,
    /// Allowed |φ − 22.2°| for the claim [°].
    pub tolerance_deg: f64,
}

impl Default for ShearStageParams {
    fn default() -> Self {
        ShearStageParams {
            dem: DemParams::default(),
            stiffness_factor: 1.0,
            shear: ShearParams::default(),
            tolerance_deg: 1.0,
        }
    }
}

impl Validate for ShearStageParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_dem(&self.dem, self.stiffness_factor, &mut c);
        c.check(
            self.shear.pressures.len() >= 2 && self.shear.pressures.iter().all(|p| *p > 0.0),
            "shear.pressures",
            format!("{:?}", self.shear.pressures),
            "at least two pressures > 0 [Pa]",
        );
        c.in_open("shear.inertial_number", self.shear.inertial_number, 0.0, 1.0);
        c.positive("shear.strain", self.shear.strain);
        c.positive("tolerance_deg", self.tolerance_deg);
        c.issues
    }
}

fn run_shear(ctx: &StageCtx) -> anyhow::Result<Output> {
    let mut p: ShearStageParams = decode(ctx)?;
    super::calib::apply_calibration(ctx, &mut p.dem)?;
    let run = p.dem.softened(p.stiffness_factor);
    let psd = ctx.input("psd")?;
    let radii: Vec<f64> = col_f64(&psd.table("table")?, "d_m")?.iter().map(|d| 0.5 * d).collect();
    let total = p.shear.pressures.len();
    ctx.set_progress(0.0);
    let r = shear_test(&radii, &run, &p.shear)?;
    ctx.set_progress(1.0);
    let pts = &r.points;
    let mut out = Output::default();
    out.table(
        "table",
        frame(vec![
            ("pressure_pa", pts.iter().map(|q| q.pressure).collect()),
            ("sigma_n_pa", pts.iter().map(|q| q.sigma_n).collect()),
            ("tau_pa", pts.iter().map(|q| q.tau).collect()),
            ("mu", pts.iter().map(|q| q.mu).collect()),
            ("inertial_number", pts.iter().map(|q| q.inertial_number).collect()),
            ("velocity_m_s", pts.iter().map(|q| q.velocity).collect()),
        ])?,
    );
    let mut sp = Vec::new();
    let mut ss = Vec::new();
    let mut sm = Vec::new();
    for q in pts {
        for s in &q.series {
            sp.push(q.pressure);
            ss.push(s.strain);
            sm.push(if s.sigma_n > 0.0 { s.tau / s.sigma_n } else { f64::NAN });
        }
    }
    out.table(
        "series",
        frame(vec![
            ("pressure_pa", sp),
            ("shear_strain", ss),
            ("tau_over_sigma_n", sm),
        ])?,
    );
    out.scalar("friction_angle_deg", r.friction_angle_deg)
        .scalar("friction_angle_free_fit_deg", r.friction_angle_free_deg)
        .scalar("cohesion_free_fit_pa", r.cohesion_free)
        .scalar("grains", r.grains as f64)
        .scalar("pressures", total as f64)
        .scalar(
            "max_inertial_number",
            pts.iter().map(|q| q.inertial_number).fold(0.0, f64::max),
        )
        .scalar("mu_r", p.dem.rolling.mu_r)
        .scalar("stiffness_factor", p.stiffness_factor);
    out.claims.push(
        Claim::abs(
            "friction-angle",
            "\"A critical state friction angle of 22.2° was obtained\" (table 4.3: 22.2 ± 0.2°)",
            22.2,
            r.friction_angle_deg,
            p.tolerance_deg,
        )
        .calibrated(),
    );
    out.checks.push(Claim::at_most("quasi-static", "quasi-static shear: inertial number I < 1e-3 (SC-SHEAR-DEM; imposed through the shear rate) — largest measured I", 1.5e-3, pts.iter().map(|q| q.inertial_number).fold(0.0, f64::max)));
    let smax = pts.iter().map(|q| q.sigma_n).fold(0.0, f64::max) * 1.1 / 1e3;
    let slope = r.friction_angle_deg.to_radians().tan();
    let chart = Chart {
        title: ctx.caption.clone().unwrap_or_else(|| "Periodic shear test".into()),
        footer: footer(
            &ctx.profile,
            &format!(
                "{} grains, φ_cs = {:.2}°, stiffness factor {}",
                r.grains, r.friction_angle_deg, p.stiffness_factor
            ),
        ),
        x_label: "normal stress σ'_n [kPa]".into(),
        y_label: "critical-state shear stress τ [kPa]".into(),
        x_range: Some((0.0, smax)),
        y_range: Some((0.0, smax * slope.max(0.3) * 1.2)),
        series: vec![
            Series::new(
                "DEM, time-averaged critical state",
                Style::Points,
                pts.iter().map(|q| (q.sigma_n / 1e3, q.tau / 1e3)).collect(),
                0,
            ),
            Series::new(
                format!("fit through origin: tan φ, φ = {:.2}°", r.friction_angle_deg),
                Style::Dashed,
                vec![(0.0, 0.0), (smax, smax * slope)],
                1,
            ),
            Series::new(
                "stated: φ = 22.2°",
                Style::Dashed,
                vec![(0.0, 0.0), (smax, smax * 22.2f64.to_radians().tan())],
                7,
            ),
        ],
        ..Default::default()
    };
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `dem-shear`.
pub const SHEAR_KIND: Kind = Kind {
    name: "dem-shear",
    version: 2,
    about: "fig4-03: bi-periodic DEM shear test at several pressures -> critical-state friction angle",
    params: typed::<ShearStageParams>,
    run: run_shear,
    explain: Some(explain_dem),
};

/// Parameters of a `dem-compress` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CompressStageParams {
    /// Solver parameters.
    pub dem: DemParams,
    /// Softening.
    pub stiffness_factor: f64,
    /// Test settings.
    pub compression: CompressionParams,
}

impl Default for CompressStageParams {
    fn default() -> Self {
        CompressStageParams {
            dem: DemParams::default(),
            stiffness_factor: 1.0,
            compression: CompressionParams::default(),
        }
    }
}

impl Validate for CompressStageParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_dem(&self.dem, self.stiffness_factor, &mut c);
        c.positive("compression.strain_rate", self.compression.strain_rate);
        c.positive("compression.max_strain", self.compression.max_strain);
        c.check(
            self.compression.fit_strain > 0.0 && self.compression.fit_strain <= self.compression.max_strain,
            "compression.fit_strain",
            self.compression.fit_strain,
            "in (0, max_strain]",
        );
        c.in_open("compression.poisson", self.compression.poisson, -1.0, 0.5);
        c.issues
    }
}

fn run_compress(ctx: &StageCtx) -> anyhow::Result<Output> {
    let mut p: CompressStageParams = decode(ctx)?;
    super::calib::apply_calibration(ctx, &mut p.dem)?;
    let run = p.dem.softened(p.stiffness_factor);
    let col = column_from(ctx.input("column")?, run.density)?;
    let r = compression_test(&col, &run, &p.compression)?;
    let mut out = Output::default();
    out.table(
        "table",
        frame(vec![
            ("axial_strain", r.curve.iter().map(|c| c.strain).collect()),
            ("axial_stress_pa", r.curve.iter().map(|c| c.stress).collect()),
            ("lateral_stress_pa", r.curve.iter().map(|c| c.lateral).collect()),
        ])?,
    );
    // Measured at the stiffness it ran with (the sample is re-settled at that stiffness
    // first): no rescaling. A low-stress packing's modulus does not scale with k_n (its
    // seating response is dominated by contact creation, tests/dem_compression.rs).
    out.scalar("constrained_modulus_pa", r.modulus)
        .scalar("youngs_modulus_pa", r.young)
        .scalar("k0", r.k0)
        .scalar("height_m", r.height)
        .scalar("stiffness_factor", p.stiffness_factor);
    out.claims.push(Claim::rel("youngs-modulus", "E = 1.98e6 N/m², \"initial slope of the stress-strain plot of a uni-axial compression of a laterally confined granular column\" (I12: that slope is M; E = M(1+ν)(1−2ν)/(1−ν))", 1.98e6, r.young, 0.25));
    out.note(format!("Constrained modulus M = {:.3e} Pa (slope over the first {:.2} % strain), E = {:.3e} Pa with ν = {}; K_0 = {:.3}. Contact stiffness factor {} (the affine estimate of docs/definitions.md I12 scales with k_n).", r.modulus, 100.0 * p.compression.fit_strain, r.young, p.compression.poisson, r.k0, p.stiffness_factor));
    let chart = Chart {
        title: ctx
            .caption
            .clone()
            .unwrap_or_else(|| "Laterally confined compression".into()),
        footer: footer(
            &ctx.profile,
            &format!("M = {:.3e} Pa, E = {:.3e} Pa", r.modulus, r.young),
        ),
        x_label: "axial strain [-]".into(),
        y_label: "stress [Pa]".into(),
        series: vec![
            Series::new(
                "axial σ_yy",
                Style::Line,
                r.curve.iter().map(|c| (c.strain, c.stress)).collect(),
                0,
            ),
            Series::new(
                "lateral σ_xx",
                Style::Line,
                r.curve.iter().map(|c| (c.strain, c.lateral)).collect(),
                1,
            ),
            Series::new(
                format!("fit: slope M = {:.3e} Pa", r.modulus),
                Style::Dashed,
                vec![
                    (0.0, r.curve.first().map(|c| c.stress).unwrap_or(0.0)),
                    (
                        p.compression.fit_strain,
                        r.curve.first().map(|c| c.stress).unwrap_or(0.0) + r.modulus * p.compression.fit_strain,
                    ),
                ],
                2,
            ),
        ],
        ..Default::default()
    };
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `dem-compress`.
pub const COMPRESS_KIND: Kind = Kind {
    name: "dem-compress",
    version: 2,
    about: "laterally confined uniaxial compression of a DEM column -> constrained and Young's modulus",
    params: typed::<CompressStageParams>,
    run: run_compress,
    explain: Some(explain_dem),
};

/// Parameters of a `dem-work-precision` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WpParams {
    /// Base solver parameters (table 4.2).
    pub dem: DemParams,
    /// Variants: the first is the reference (stiffest, finest).
    pub variants: Vec<Variant>,
    /// Run control.
    pub run: CollapseParams,
    /// Perturbed starts per variant (the run-out is chaotic: errors are differences of
    /// ensemble means, with their standard error).
    pub ensemble: super::calib::Ensemble,
    /// Grain-count knob: the variant (label) run on the coarser column of the optional
    /// input `coarser` (the same a, fewer grains); empty = the second variant.
    #[serde(skip_serializing_if = "String::is_empty")]
    pub grains_at: String,
}

impl Default for WpParams {
    fn default() -> Self {
        WpParams {
            dem: DemParams::default(),
            variants: vec![],
            run: CollapseParams::default(),
            ensemble: super::calib::Ensemble::default(),
            grains_at: String::new(),
        }
    }
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

fn run_wp(ctx: &StageCtx) -> anyhow::Result<Output> {
    let mut p: WpParams = decode(ctx)?;
    super::calib::apply_calibration(ctx, &mut p.dem)?;
    let col = column_from(ctx.input("column")?, p.dem.density)?;
    let mut rows = work_precision(
        &col,
        &p.dem,
        &p.run,
        &p.variants,
        p.ensemble.members,
        p.ensemble.perturbation_m,
        p.ensemble.seed,
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
    let mut factors: Vec<f64> = rows
        .iter()
        .zip(&grains)
        .skip(1)
        .filter(|(_, g)| **g == n_full)
        .map(|(r, _)| r.variant.stiffness_factor)
        .collect();
    factors.sort_by(|a, b| b.total_cmp(a));
    factors.dedup();
    let series = factors
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let sel: Vec<&crate::dem::column::WorkPrecisionRow> = rows
                .iter()
                .zip(&grains)
                .skip(1)
                .filter(|(r, g)| r.variant.stiffness_factor == *f && **g == n_full)
                .map(|(r, _)| r)
                .collect();
            Series::new(
                format!("k_n × {f} (mean error ± s.e.)"),
                Style::LinePoints,
                sel.iter().map(|r| (r.wall_s, r.error.max(1e-4))).collect(),
                k,
            )
            .with_errors(sel.iter().map(|r| r.error_spread).collect())
        })
        .collect::<Vec<_>>();
    let mut series = series;
    for (r, g) in rows.iter().zip(&grains).filter(|(_, g)| **g != n_full) {
        series.push(
            Series::new(
                format!("{g} grains (of {n_full}), {}", r.variant.label),
                Style::Points,
                vec![(r.wall_s, r.error.max(1e-4))],
                6,
            )
            .with_errors(vec![r.error_spread]),
        );
    }
    let chart = Chart::work_precision(
        ctx.caption.clone().unwrap_or_else(|| "DEM work-precision".into()),
        footer(
            &ctx.profile,
            &format!(
                "reference: {} (ΔL = {:.3} ± {:.3}), {} grains, {} starts per setting",
                rows[0].variant.label,
                rows[0].mean,
                rows[0].spread,
                col.state.len(),
                p.ensemble.members
            ),
        ),
        series,
    );
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `dem-work-precision`.
pub const WP_KIND: Kind = Kind {
    name: "dem-work-precision",
    version: 4,
    about: "DEM column run-out error vs wall time over stiffness and time-step fraction (ensembles, re-settled per setting)",
    params: typed::<WpParams>,
    run: run_wp,
    explain: None,
};
