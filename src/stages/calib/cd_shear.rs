//! Kind `cd-shear` (C3): the periodic CD shear test at several inertial numbers → μ*(I)
//! and its μ(I) fit, whose μ_min the pile's MPM can read through the DAG.
//!
//! Every CD kind takes `cd` (the solver's parameter schema, `stages/cd-solver.yaml`).

use serde::{Deserialize, Serialize};

use crate::cd::CdParams;
use crate::cd::shear::{ShearCdParams, shear_test};
use crate::pipeline::context::{Output, StageCtx, col_f64, frame};
use crate::report::plot::{Chart, Legend, Series, Style, footer};
use crate::stages::kind::{CostCtx, Work};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Check `cd` (the CD solver's parameters) into `c`.
pub(crate) fn check_cd(p: &CdParams, c: &mut Checker) {
    for i in p.validate() {
        c.fail(&format!("cd.{}", i.key), i.value, &i.allowed);
    }
}

/// Parameters of a `cd-shear` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShearStageParams {
    /// Solver parameters (`dt` is replaced per point by the c.5 rule).
    pub cd: CdParams,
    /// Test settings.
    pub shear: ShearCdParams,
    /// How many grains of the PSD input form the sample (its order is shuffled, so the
    /// first k follow the distribution).
    pub grains: usize,
}

impl Default for ShearStageParams {
    fn default() -> Self {
        ShearStageParams {
            cd: CdParams::default(),
            shear: ShearCdParams::default(),
            grains: 1000,
        }
    }
}

impl Validate for ShearStageParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_cd(&self.cd, &mut c);
        let s = &self.shear;
        c.check(
            !s.inertial_numbers.is_empty() && s.inertial_numbers.iter().all(|i| *i > 0.0 && *i < 1.0),
            "shear.inertial_numbers",
            format!("{:?}", s.inertial_numbers),
            "at least one, each in (0, 1)",
        );
        c.positive("shear.pressure", s.pressure);
        c.positive("shear.strain", s.strain);
        c.in_open("shear.average_from", s.average_from, 0.0, 1.0);
        c.check(
            s.width >= 6.0,
            "shear.width",
            s.width,
            "≥ 6 mean diameters (the periodic cell list needs 3 cells)",
        );
        c.in_closed("shear.layer_pitch", s.layer_pitch, 1.0, 1.8);
        c.in_open_closed("shear.courant", s.courant, 0.0, 0.1);
        c.positive("shear.v_floor", s.v_floor);
        c.positive("shear.compaction_tp", s.compaction_tp);
        c.positive("shear.plate_drift", s.plate_drift);
        c.positive("shear.fit_max_inertial_number", s.fit_max_inertial_number);
        c.check(self.grains >= 20, "grains", self.grains, "≥ 20");
        c.issues
    }
}

fn run_shear(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: ShearStageParams = decode(ctx)?;
    let psd = ctx.input("psd")?;
    let d = col_f64(&psd.table("table")?, "d_m")?;
    anyhow::ensure!(
        d.len() >= p.grains,
        "the PSD input `{}` has {} grains; the CD shear cell asks for {}: lower `grains` or raise the PSD's `n`",
        psd.id,
        d.len(),
        p.grains
    );
    let radii: Vec<f64> = d[..p.grains].iter().map(|d| 0.5 * d).collect();
    ctx.set_progress(0.0);
    let r = shear_test(&radii, &p.cd, &p.shear)?;
    ctx.set_progress(1.0);
    let pts = &r.points;
    let mut out = Output::default();
    let col = |f: &dyn Fn(&crate::cd::shear::ShearCdPoint) -> f64| pts.iter().map(f).collect::<Vec<f64>>();
    out.table(
        "table",
        frame(vec![
            ("target_inertial_number", col(&|q| q.target)),
            ("inertial_number", col(&|q| q.inertial_number)),
            ("mu", col(&|q| q.mu)),
            ("mu_se", col(&|q| q.mu_se)),
            ("tau_pa", col(&|q| q.tau)),
            ("sigma_n_pa", col(&|q| q.sigma_n)),
            ("packing_fraction", col(&|q| q.packing_fraction)),
            ("velocity_m_s", col(&|q| q.velocity)),
            ("mean_dt_s", col(&|q| q.dt)),
            ("steps", col(&|q| q.steps as f64)),
            ("mean_iterations", col(&|q| q.mean_iterations)),
            ("unconverged_steps", col(&|q| q.unconverged as f64)),
            ("max_penetration_d", col(&|q| q.max_penetration)),
            ("wall_s", col(&|q| q.wall_s)),
        ])?,
    );
    let (mut si, mut ss, mut sm) = (Vec::new(), Vec::new(), Vec::new());
    for q in pts {
        for &(g, m) in &q.series {
            si.push(q.target);
            ss.push(g);
            sm.push(m);
        }
    }
    out.table(
        "series",
        frame(vec![
            ("target_inertial_number", si),
            ("shear_strain", ss),
            ("tau_over_sigma_n", sm),
        ])?,
    );
    let steps: u64 = pts.iter().map(|q| q.steps).sum();
    let unconv: u64 = pts.iter().map(|q| q.unconverged).sum();
    out.scalar("mu_min", r.mu_min)
        .scalar("b", r.b)
        .scalar("mu_min_se", r.mu_min_se)
        .scalar("b_se", r.b_se)
        .scalar("friction_angle_deg", r.mu_min.atan().to_degrees())
        .scalar("grains", r.grains as f64)
        .scalar("d_mean_m", r.d_mean)
        .scalar("compaction_packing_fraction", r.compaction_packing)
        .scalar("steps", steps as f64)
        .scalar("unconverged_steps", unconv as f64)
        .scalar(
            "max_penetration_d",
            pts.iter().map(|q| q.max_penetration).fold(0.0, f64::max),
        );
    out.note(format!(
        "{} grains (first of `{}`), d̄ = {:.3} mm, p = {} Pa, μ_grain = {}, ε_n = {}, ε_t = {}; fit μ = μ_min + b I: μ_min = {:.3} ± {:.3}, b = {:.3} ± {:.3}. NLGS: tolerance {:.0e} (‖ΔP‖/‖P‖) and {:.0e} (natural-map residual), cap {} sweeps: {} of {} steps unconverged ({:.1} %).",
        r.grains, psd.id, r.d_mean * 1e3, p.shear.pressure, p.cd.friction, p.cd.restitution_n, p.cd.restitution_t, r.mu_min, r.mu_min_se, r.b, r.b_se,
        p.cd.tolerance, p.cd.residual_tolerance, p.cd.max_iterations, unconv, steps, 100.0 * unconv as f64 / steps.max(1) as f64
    ));
    let chart = Chart {
        title: ctx.caption.clone().unwrap_or_else(|| "CD periodic shear".into()),
        footer: footer(
            &ctx.profile,
            &format!("{} grains, {} of {} steps unconverged", r.grains, unconv, steps),
        ),
        x_label: "shear strain γ [-]".into(),
        y_label: "μ* = τ/σ_n [-]".into(),
        y_range: Some((0.0, 0.8)),
        legend: Legend::UpperRight,
        series: pts
            .iter()
            .enumerate()
            .map(|(k, q)| Series::new(format!("I = {:.0e}", q.target), Style::Line, q.series.clone(), k))
            .collect(),
        ..Default::default()
    };
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `cd-shear`.
pub const SHEAR_KIND: Kind = Kind {
    name: "cd-shear",
    source: file!(),
    method: Some(crate::engines::Method::Cd),
    version: 1,
    about: "C3: periodic CD shear at several inertial numbers -> mu*(I), fit mu_min + b I",
    params: typed::<ShearStageParams>,
    run: run_shear,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[("psd", crate::pipeline::context::Arity::One)]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "b", "b_se", "compaction_packing_fraction", "d_mean_m", "friction_angle_deg", "grains",
            "max_penetration_d", "mu_min", "mu_min_se", "steps", "unconverged_steps",
        ],
        tables: &[
            crate::stages::kind::TableDecl {
                name: "series",
                columns: &["shear_strain", "target_inertial_number", "tau_over_sigma_n"],
            },
            crate::stages::kind::TableDecl {
                name: "table",
                columns: &[
                    "inertial_number", "max_penetration_d", "mean_dt_s", "mean_iterations", "mu", "mu_se",
                    "packing_fraction", "sigma_n_pa", "steps", "target_inertial_number", "tau_pa", "unconverged_steps",
                    "velocity_m_s", "wall_s",
                ],
            },
        ],
        measurements: &[],
        texts: &[],
    },
    reads: None,
    cost: Some(shear_cost),
    atlas: None,
};

/// Cost (shear): grains; steps = strain × Σ 1/I over the inertial numbers / Δt.
fn shear_cost(c: &CostCtx) -> Option<Work> {
    let p: ShearStageParams = c.typed()?;
    let steps = p.shear.strain * p.shear.inertial_numbers.iter().map(|i| 1.0 / i).sum::<f64>() / p.cd.dt;
    Some((vec![("grains", p.grains as f64), ("steps", steps)], false))
}
