//! Kind `dem-shear` (fig4-03): the bi-periodic DEM shear test at several pressures →
//! critical-state friction angle, which feeds the MPM through the DAG.
//!
//! Every DEM kind takes `dem` (the solver's own parameter schema, `stages/dem-column.yaml`)
//! and `stiffness_factor`: the quick profile softens k_n, k_t, k_r by this factor (the
//! step grows by 1/√factor); what that costs in accuracy is measured by
//! `wp-dem-column` and printed on the figures.

use serde::{Deserialize, Serialize};

use crate::dem::DemParams;
use crate::dem::critical_state::{CriticalStateParams, CsPoint, critical_state_test};
use crate::pipeline::context::{Claim, Output, StageCtx, col_f64, frame};
use crate::report::plot::{Chart, Series, Style, footer};
use crate::stages::column::dem_common::{check_dem, explain_dem};
use crate::stages::generic::psd::PsdParams;
use crate::stages::kind::{CostCtx, Work};
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
    /// The critical-state protocol.
    pub shear: CriticalStateParams,
    /// Allowed |φ − 22.2°| for the claim [°].
    pub tolerance_deg: f64,
    /// Smallest κ = k_n/P the `rigid` check accepts.
    pub kappa_min: f64,
}

impl Default for ShearStageParams {
    fn default() -> Self {
        ShearStageParams {
            dem: DemParams::default(),
            stiffness_factor: 1.0,
            shear: CriticalStateParams::default(),
            tolerance_deg: 1.0,
            kappa_min: 1e4,
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
        c.check(
            self.shear.steady_from >= 0.0 && self.shear.steady_from < self.shear.strain,
            "shear.steady_from",
            format!("{}", self.shear.steady_from),
            "a strain in [0, shear.strain): the steady window is [steady_from, strain]",
        );
        c.check(
            self.shear.kappa.is_none_or(|k| k > 0.0),
            "shear.kappa",
            format!("{:?}", self.shear.kappa),
            "κ = k_n/P > 0, or leave it out to run the given contacts",
        );
        c.check(
            !self.shear.preparations.is_empty(),
            "shear.preparations",
            "[]".to_string(),
            "at least one preparation ({name, friction, rolling})",
        );
        c.check(
            self.shear.layers >= 1 && self.shear.planes >= 1,
            "shear.layers",
            format!("layers {}, planes {}", self.shear.layers, self.shear.planes),
            "at least one wall row and one stress plane",
        );
        for (k, prep) in self.shear.preparations.iter().enumerate() {
            if let Some(ps) = &prep.pressures {
                c.check(
                    !ps.is_empty() && ps.iter().all(|x| self.shear.pressures.contains(x)),
                    &format!("shear.preparations[{k}].pressures"),
                    format!("{ps:?}"),
                    "a non-empty subset of shear.pressures (or leave it out: every pressure)",
                );
            }
        }
        if let Some(f) = &self.shear.fixed_stiffness_check {
            c.positive("shear.fixed_stiffness_check.stiffness_factor", f.stiffness_factor);
            c.check(
                !f.pressures.is_empty() && f.pressures.iter().all(|x| *x > 0.0),
                "shear.fixed_stiffness_check.pressures",
                format!("{:?}", f.pressures),
                "at least one pressure > 0 [Pa]",
            );
        }
        c.positive("shear.width", self.shear.width);
        c.positive("shear.sample_strain", self.shear.sample_strain);
        c.positive("tolerance_deg", self.tolerance_deg);
        c.issues
    }
}

fn run_shear(ctx: &StageCtx) -> anyhow::Result<Output> {
    let mut p: ShearStageParams = decode(ctx)?;
    super::dem_calibration::apply_calibration(ctx, &mut p.dem)?;
    let run = p.dem.softened(p.stiffness_factor);
    let psd = ctx.input("psd")?;
    let radii: Vec<f64> = col_f64(&psd.table("table")?, "d_m")?.iter().map(|d| 0.5 * d).collect();
    ctx.set_progress(0.0);
    let r = critical_state_test(&radii, &run, &p.shear)?;
    ctx.set_progress(1.0);
    let pts = &r.points;
    let col = |f: &dyn Fn(&CsPoint) -> f64| pts.iter().map(f).collect::<Vec<f64>>();
    let mut out = Output::default();
    out.table(
        "table",
        frame(vec![
            ("pressure_pa", col(&|q| q.pressure)),
            ("preparation", col(&|q| q.preparation as f64)),
            ("set", col(&|q| q.set as f64)),
            ("kn_n_m", col(&|q| q.kn)),
            ("kappa", col(&|q| q.kappa)),
            ("dt_s", col(&|q| q.dt)),
            ("steps", col(&|q| q.steps as f64)),
            ("sigma_n_pa", col(&|q| q.sigma_bulk)),
            ("tau_pa", col(&|q| q.tau_bulk)),
            ("mu", col(&|q| q.mu)),
            ("mu_se", col(&|q| q.mu_se)),
            ("mu_wall", col(&|q| q.mu_wall)),
            ("drift", col(&|q| q.drift)),
            ("mu_peak", col(&|q| q.mu_peak)),
            ("packing", col(&|q| q.packing)),
            ("packing_initial", col(&|q| q.packing_initial)),
            ("inertial_number", col(&|q| q.inertial_bulk)),
            ("inertial_imposed", col(&|q| q.inertial_imposed)),
            ("shear_rate_ratio", col(&|q| q.shear_rate_ratio)),
            ("inertial_local_max", col(&|q| q.inertial_local_max)),
            ("coordination", col(&|q| q.coordination)),
            ("sliding_fraction", col(&|q| q.sliding_fraction)),
            ("rolling_cap_fraction", col(&|q| q.rolling_cap_fraction)),
        ])?,
    );
    let (mut sp, mut sk, mut ss, mut sm, mut sw, mut sf) = (vec![], vec![], vec![], vec![], vec![], vec![]);
    for q in pts.iter().filter(|q| q.set == 0) {
        for s in &q.series {
            sp.push(q.pressure);
            sk.push(q.preparation as f64);
            ss.push(s.strain);
            sm.push(s.mu_bulk);
            sw.push(s.mu_wall);
            sf.push(s.packing);
        }
    }
    out.table(
        "series",
        frame(vec![
            ("pressure_pa", sp),
            ("preparation", sk),
            ("shear_strain", ss),
            ("tau_over_sigma_n", sm),
            ("tau_over_sigma_n_wall", sw),
            ("packing", sf),
        ])?,
    );
    let (mut pp, mut pk, mut py, mut pv) = (vec![], vec![], vec![], vec![]);
    for q in pts.iter().filter(|q| q.set == 0) {
        for &(y, v) in &q.profile {
            pp.push(q.pressure);
            pk.push(q.preparation as f64);
            py.push(y);
            pv.push(v);
        }
    }
    out.table(
        "profile",
        frame(vec![
            ("pressure_pa", pp),
            ("preparation", pk),
            ("y_over_h", py),
            ("vx_over_v", pv),
        ])?,
    );
    let set0: Vec<&CsPoint> = pts.iter().filter(|q| q.set == 0).collect();
    let spread = |v: &mut dyn Iterator<Item = f64>| {
        let v: Vec<f64> = v.collect();
        v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min)
    };
    // μ* spread over the pressures, the largest over the preparations
    let mu_spread = (0..p.shear.preparations.len())
        .map(|k| spread(&mut set0.iter().filter(|q| q.preparation == k).map(|q| q.mu)))
        .fold(0.0, f64::max);
    let packing_by_prep: Vec<f64> = (0..p.shear.preparations.len())
        .map(|k| {
            let v: Vec<f64> = set0.iter().filter(|q| q.preparation == k).map(|q| q.packing).collect();
            v.iter().sum::<f64>() / v.len().max(1) as f64
        })
        .collect();
    let phi_prep_spread = spread(&mut r.friction_angle_by_preparation.iter().cloned());
    let packing_spread = spread(&mut packing_by_prep.iter().cloned());
    let max_drift = set0.iter().map(|q| q.drift.abs()).fold(0.0, f64::max);
    let max_i = set0.iter().map(|q| q.inertial_bulk).fold(0.0, f64::max);
    let min_kappa = set0.iter().map(|q| q.kappa).fold(f64::INFINITY, f64::min);
    out.scalar("friction_angle_deg", r.friction_angle_deg)
        .scalar("friction_angle_free_fit_deg", r.friction_angle_free_deg)
        .scalar("cohesion_free_fit_pa", r.cohesion_free)
        .scalar(
            "friction_angle_first_preparation_deg", r.friction_angle_by_preparation[0],
        )
        .scalar("friction_angle_preparation_spread_deg", phi_prep_spread)
        .scalar("mu_star_pressure_spread", mu_spread)
        .scalar(
            "packing_fraction",
            packing_by_prep.iter().sum::<f64>() / packing_by_prep.len() as f64,
        )
        .scalar("packing_preparation_spread", packing_spread)
        .scalar("max_drift", max_drift)
        .scalar("min_kappa", min_kappa)
        .scalar(
            "min_shear_rate_ratio",
            set0.iter().map(|q| q.shear_rate_ratio).fold(f64::INFINITY, f64::min),
        )
        .scalar(
            "rolling_cap_fraction",
            set0.iter().map(|q| q.rolling_cap_fraction).sum::<f64>() / set0.len() as f64,
        )
        .scalar(
            "sliding_fraction",
            set0.iter().map(|q| q.sliding_fraction).sum::<f64>() / set0.len() as f64,
        )
        .scalar("grains", r.grains as f64)
        .scalar("pressures", p.shear.pressures.len() as f64)
        .scalar("max_inertial_number", max_i)
        .scalar(
            "max_local_inertial_number",
            set0.iter().map(|q| q.inertial_local_max).fold(0.0, f64::max),
        )
        .scalar("mu_r", p.dem.rolling.mu_r)
        .scalar("stiffness_factor", p.stiffness_factor);
    if let Some(phi) = r.friction_angle_fixed_stiffness {
        out.scalar("friction_angle_fixed_stiffness_deg", phi);
    }
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
    out.checks.push(Claim::at_most("quasi-static", "quasi-static shear: the bulk's inertial number (its measured shear rate and stress) I ≤ 1.5e-3 (SC-SHEAR-DEM) — largest", 1.5e-3, max_i));
    out.checks.push(Claim::at_most(
        "steady",
        "critical state reached: μ* of the steady window's second half minus its first, largest |difference| ≤ 0.02",
        0.02,
        max_drift,
    ));
    out.checks.push(Claim::at_most(
        "preparation-independent",
        "a critical state forgets its preparation: φ_cs of the preparations within 1° of each other",
        1.0,
        phi_prep_spread,
    ));
    out.checks.push(Claim::at_least(
        "rigid",
        "rigid-grain regime: κ = k_n/P ≥ the stated bound at every pressure (issue 24: 1e4 at paper size) — smallest",
        p.kappa_min,
        min_kappa,
    ));
    let smax = set0.iter().map(|q| q.sigma_bulk).fold(0.0, f64::max) * 1.1 / 1e3;
    let slope = r.friction_angle_deg.to_radians().tan();
    let mut series: Vec<Series> = p
        .shear
        .preparations
        .iter()
        .enumerate()
        .map(|(k, prep)| {
            Series::new(
                format!("DEM bulk, critical state, {} preparation", prep.name),
                Style::Points,
                set0.iter()
                    .filter(|q| q.preparation == k)
                    .map(|q| (q.sigma_bulk / 1e3, q.tau_bulk / 1e3))
                    .collect(),
                k,
            )
        })
        .collect();
    series.push(Series::new(
        format!("fit through origin: tan φ, φ = {:.2}°", r.friction_angle_deg),
        Style::Dashed,
        vec![(0.0, 0.0), (smax, smax * slope)],
        4,
    ));
    series.push(Series::new(
        "stated: φ = 22.2°",
        Style::Dashed,
        vec![(0.0, 0.0), (smax, smax * 22.2f64.to_radians().tan())],
        7,
    ));
    let chart = Chart {
        title: ctx.caption.clone().unwrap_or_else(|| "Periodic shear test".into()),
        footer: footer(
            &ctx.profile,
            &format!(
                "{} grains, γ = {}, steady from γ = {}, κ = k_n/P ≥ {:.0}, φ_cs = {:.2}°",
                r.grains, p.shear.strain, p.shear.steady_from, min_kappa, r.friction_angle_deg
            ),
        ),
        x_label: "normal stress σ'_n [kPa]".into(),
        y_label: "critical-state shear stress τ [kPa]".into(),
        x_range: Some((0.0, smax)),
        y_range: Some((0.0, smax * slope.max(0.3) * 1.2)),
        series,
        ..Default::default()
    };
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `dem-shear`.
pub const SHEAR_KIND: Kind = Kind {
    name: "dem-shear",
    source: file!(),
    method: Some(crate::engines::Method::Dem),
    version: 3,
    about: "fig4-03: critical-state DEM simple shear (two rough wall rows, bulk stress, k_n per pressure, dense and loose preparations) at several pressures -> critical-state friction angle",
    params: typed::<ShearStageParams>,
    run: run_shear,
    explain: Some(explain_dem),
    roles: crate::stages::kind::Roles::Fixed(&[
        ("psd", crate::pipeline::context::Arity::One),
        ("calibration", crate::pipeline::context::Arity::OptionalOne),
    ]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "cohesion_free_fit_pa", "friction_angle_deg", "friction_angle_first_preparation_deg",
            "friction_angle_fixed_stiffness_deg", "friction_angle_free_fit_deg",
            "friction_angle_preparation_spread_deg", "grains", "max_drift", "max_inertial_number",
            "max_local_inertial_number", "min_kappa", "min_shear_rate_ratio", "mu_r", "mu_star_pressure_spread",
            "packing_fraction", "packing_preparation_spread", "pressures", "rolling_cap_fraction", "sliding_fraction",
            "stiffness_factor",
        ],
        tables: &[
            crate::stages::kind::TableDecl {
                name: "profile",
                columns: &["preparation", "pressure_pa", "vx_over_v", "y_over_h"],
            },
            crate::stages::kind::TableDecl {
                name: "series",
                columns: &[
                    "packing", "preparation", "pressure_pa", "shear_strain", "tau_over_sigma_n",
                    "tau_over_sigma_n_wall",
                ],
            },
            crate::stages::kind::TableDecl {
                name: "table",
                columns: &[
                    "coordination", "drift", "dt_s", "inertial_imposed", "inertial_local_max", "inertial_number",
                    "kappa", "kn_n_m", "mu", "mu_peak", "mu_se", "mu_wall", "packing", "packing_initial",
                    "preparation", "pressure_pa", "rolling_cap_fraction", "set", "shear_rate_ratio", "sigma_n_pa",
                    "sliding_fraction", "steps", "tau_pa",
                ],
            },
        ],
        measurements: &["friction-angle"],
        texts: &[],
    },
    reads: None,
    cost: Some(cost),
    atlas: None,
};

/// Cost: grains of the PSD input; steps per simulated second times the simulated time of
/// the test (strain over the shear rate at each pressure, ∝ P^-1/2 at fixed I).
fn cost(c: &CostCtx) -> Option<Work> {
    let p: ShearStageParams = c.typed()?;
    let n = c.input::<PsdParams>("psd")?.n as f64;
    Some((
        vec![
            ("grains", n),
            (
                "steps",
                p.dem.steps_per_second(p.stiffness_factor)
                    * p.shear.relative_steps(p.dem.softened(p.stiffness_factor).grain.kn),
            ),
        ],
        false,
    ))
}
