//! Kind `dem-shear` (fig4-03): the bi-periodic DEM shear test at several pressures →
//! critical-state friction angle, which feeds the MPM through the DAG.
//!
//! Every DEM kind takes `dem` (the solver's own parameter schema, `stages/dem-column.yaml`)
//! and `stiffness_factor`: the quick profile softens k_n, k_t, k_r by this factor (the
//! step grows by 1/√factor); what that costs in accuracy is measured by
//! `wp-dem-column` and printed on the figures.

use serde::{Deserialize, Serialize};

use crate::dem::DemParams;
use crate::dem::shear::{ShearParams, shear_test};
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
    super::dem_calibration::apply_calibration(ctx, &mut p.dem)?;
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
    source: file!(),
    method: Some(crate::engines::Method::Dem),
    version: 2,
    about: "fig4-03: bi-periodic DEM shear test at several pressures -> critical-state friction angle",
    params: typed::<ShearStageParams>,
    run: run_shear,
    explain: Some(explain_dem),
    roles: crate::stages::kind::Roles::Fixed(&[
        ("psd", crate::pipeline::context::Arity::One),
        ("calibration", crate::pipeline::context::Arity::OptionalOne),
    ]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "cohesion_free_fit_pa", "friction_angle_deg", "friction_angle_free_fit_deg", "grains",
            "max_inertial_number", "mu_r", "pressures", "stiffness_factor",
        ],
        tables: &[
            crate::stages::kind::TableDecl {
                name: "series",
                columns: &["pressure_pa", "shear_strain", "tau_over_sigma_n"],
            },
            crate::stages::kind::TableDecl {
                name: "table",
                columns: &[
                    "inertial_number", "mu", "pressure_pa", "sigma_n_pa", "tau_pa", "velocity_m_s",
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
                p.dem.steps_per_second(p.stiffness_factor) * p.shear.relative_duration(),
            ),
        ],
        false,
    ))
}
