//! Joint DEM calibration (issue 7): the chapter gives no rolling-friction coefficient μ_r
//! and no rolling-model details, yet μ_r decides both the shear test's friction angle and
//! the column's run-out. One `dem-calibration-point` stage per grid point (a matrix member,
//! so each point is a cached run) measures φ_cs from the periodic shear test and the
//! run-out of each prepared column as the mean over an ensemble of perturbed starts; the
//! `dem-calibration` stage ([`super::dem_choice`]) gathers the grid, chooses a point by a
//! stated rule (both targets met, else the calibration target the stage names) and hands
//! μ_r and the rolling model to every DEM scene through the DAG.
//!
//! The run-out of a collapse is chaotic: grains displaced by 1e-9 m give ΔL ± 0.05 at
//! a = 0.4 (LAMMPS and ours alike, `bench/lammps/column-rolling/`). A point is
//! therefore an ensemble: member k starts from the prepared column with every grain
//! moved by a uniform random offset of at most `perturbation_m` (seeded), member 0
//! unperturbed; we report the mean and the sample standard deviation.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::dem::column::{CollapseParams, CollapseResult, collapse, mean_std};
use crate::dem::prep::Column;
use crate::dem::shear::{ShearParams, shear_test};
use crate::dem::{DemParams, RollingModel};
use crate::pipeline::context::{Output, StageCtx, col_f64, frame};
use crate::stages::column::dem_prep::PrepParams as ColumnPrep;
use crate::stages::generic::psd::PsdParams;
use crate::stages::kind::{CostCtx, Work};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Eq 4.6: the chapter's DEM run-out law.
pub fn eq46(a: f64) -> f64 {
    if a <= 2.7 { 1.67 * a } else { 2.7 * a.powf(2.0 / 3.0) }
}

/// An ensemble of perturbed starts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Ensemble {
    /// Members (≥ 1; member 0 is the unperturbed column).
    pub members: usize,
    /// Largest displacement of a grain in a perturbed start [m]. 1e-9 m: far below any
    /// physical scale (overlaps are ~1e-6 m), enough to decorrelate chaotic runs.
    pub perturbation_m: f64,
    /// Seed of the perturbations.
    pub seed: u64,
}

impl Default for Ensemble {
    fn default() -> Self {
        Ensemble {
            members: 3,
            perturbation_m: 1e-9,
            seed: 7,
        }
    }
}

impl Ensemble {
    fn check(&self, c: &mut Checker) {
        c.check(
            self.members >= 1 && self.members <= 64,
            "ensemble.members",
            self.members,
            "an integer in [1, 64]",
        );
        c.check(
            self.perturbation_m.is_finite() && self.perturbation_m >= 0.0 && self.perturbation_m < 1e-4,
            "ensemble.perturbation_m",
            self.perturbation_m,
            "in [0, 1e-4) m",
        );
    }
}

/// Collapse of `col` once per ensemble member, members in parallel (each deterministic,
/// so the results do not depend on the thread count).
pub fn collapse_ensemble(
    col: &Column,
    run: &DemParams,
    cp: &CollapseParams,
    ens: &Ensemble,
) -> anyhow::Result<Vec<CollapseResult>> {
    (0..ens.members)
        .into_par_iter()
        .map(|k| Ok(collapse(&col.perturbed(k, ens.perturbation_m, ens.seed), run, cp)?))
        .collect()
}

/// Parameters of a `dem-calibration-point` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PointParams {
    /// Base solver parameters (table 4.2); `mu_r` and `model` replace the rolling ones.
    pub dem: DemParams,
    /// Softening of the contacts (must match the prepared columns').
    pub stiffness_factor: f64,
    /// Rolling-friction coefficient of this grid point (the matrix key).
    pub mu_r: f64,
    /// Rolling model of this grid point.
    pub model: RollingModel,
    /// Periodic shear test settings.
    pub shear: ShearParams,
    /// Collapse run control.
    pub run: CollapseParams,
    /// Ensemble of each column's collapse.
    pub ensemble: Ensemble,
}

impl Default for PointParams {
    fn default() -> Self {
        PointParams {
            dem: DemParams::default(),
            stiffness_factor: 1.0,
            mu_r: 0.3,
            model: RollingModel::Epsd,
            shear: ShearParams::default(),
            run: CollapseParams::default(),
            ensemble: Ensemble::default(),
        }
    }
}

impl Validate for PointParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        crate::stages::column::dem_common::check_dem(&self.dem, self.stiffness_factor, &mut c);
        c.check(
            self.mu_r.is_finite() && (0.0..=2.0).contains(&self.mu_r),
            "mu_r",
            self.mu_r,
            "in [0, 2]",
        );
        c.check(
            self.shear.pressures.len() >= 2 && self.shear.pressures.iter().all(|p| *p > 0.0 && p.is_finite()),
            "shear.pressures",
            format!("{:?}", self.shear.pressures),
            "at least two finite pressures > 0 [Pa]",
        );
        c.check(
            self.run.t_max > self.run.t_min,
            "run.t_max",
            format!("{} (with run.t_min = {})", self.run.t_max, self.run.t_min),
            "> run.t_min",
        );
        self.ensemble.check(&mut c);
        c.issues
    }
}

impl PointParams {
    /// The solver parameters of this grid point (softened).
    fn solver(&self) -> DemParams {
        let mut d = self.dem.clone();
        d.rolling.mu_r = self.mu_r;
        d.rolling.model = self.model;
        d.softened(self.stiffness_factor)
    }
}

fn model_code(m: RollingModel) -> f64 {
    match m {
        RollingModel::Epsd => 0.0,
        RollingModel::Capped => 1.0,
    }
}
/// The rolling model of a `model_capped` code.
pub(crate) fn model_name(code: f64) -> &'static str {
    if code > 0.5 { "capped" } else { "epsd" }
}

fn run_point(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: PointParams = decode(ctx)?;
    let run = p.solver();
    let radii: Vec<f64> = col_f64(&ctx.input("psd")?.table("table")?, "d_m")?
        .iter()
        .map(|d| 0.5 * d)
        .collect();
    let columns = ctx.inputs_of("columns");
    anyhow::ensure!(
        !columns.is_empty(),
        "stage `{}` needs `columns` inputs (prepared DEM columns)",
        ctx.id
    );
    ctx.set_progress(0.0);
    let cols = columns
        .iter()
        .map(|i| crate::stages::column::dem_common::column_from(i, run.density))
        .collect::<anyhow::Result<Vec<Column>>>()?;
    // The shear test and every collapse of every column are independent scenes: run them
    // side by side (each scene is small and steps on one thread, PAR_MIN_ITEMS).
    let (shear, ensembles) = rayon::join(
        || shear_test(&radii, &run, &p.shear),
        || {
            cols.par_iter()
                .map(|c| collapse_ensemble(c, &run, &p.run, &p.ensemble))
                .collect::<Vec<_>>()
        },
    );
    let shear = shear?;
    let mut out = Output::default();
    out.scalar("mu_r", p.mu_r)
        .scalar("model_capped", model_code(p.model))
        .scalar("friction_angle_deg", shear.friction_angle_deg)
        .scalar("stiffness_factor", p.stiffness_factor);
    let (mut ta, mut tm, mut tr, mut tt) = (vec![], vec![], vec![], vec![]);
    for (ci, (col, rs)) in cols.iter().zip(ensembles).enumerate() {
        let rs = rs?;
        let a = col.h0 / col.l0;
        let dl: Vec<f64> = rs.iter().map(|r| r.delta_l()).collect();
        for (k, r) in rs.iter().enumerate() {
            ta.push(a);
            tm.push(k as f64);
            tr.push(r.delta_l());
            tt.push(r.samples.last().map(|s| s.t / r.tau_c).unwrap_or(f64::NAN));
        }
        let (m, s) = mean_std(&dl);
        let key = format!("{}", (a * 10.0).round() / 10.0);
        out.scalar(&format!("runout_mean_a{key}"), m)
            .scalar(&format!("runout_std_a{key}"), s)
            .scalar(&format!("runout_eq46_a{key}"), eq46(a));
        ctx.set_progress((ci + 1) as f64 / columns.len() as f64);
    }
    out.table(
        "table",
        frame(vec![
            ("a", ta),
            ("member", tm),
            ("runout_norm", tr),
            ("t_end_over_tau_c", tt),
        ])?,
    );
    out.table(
        "shear",
        frame(vec![
            ("sigma_n_pa", shear.points.iter().map(|q| q.sigma_n).collect()),
            ("tau_pa", shear.points.iter().map(|q| q.tau).collect()),
            (
                "inertial_number",
                shear.points.iter().map(|q| q.inertial_number).collect(),
            ),
        ])?,
    );
    out.note(format!(
        "Grid point μ_r = {}, rolling model {:?}: φ_cs = {:.2}°; {} ensemble members per column.",
        p.mu_r, p.model, shear.friction_angle_deg, p.ensemble.members
    ));
    Ok(out)
}

/// Kind `dem-calibration-point`.
pub const POINT_KIND: Kind = Kind {
    name: "dem-calibration-point",
    source: file!(),
    method: Some(crate::engines::Method::Dem),
    version: 1,
    about: "one point of the joint DEM calibration: shear-test φ_cs and ensemble column run-outs at given μ_r and rolling model",
    params: typed::<PointParams>,
    run: run_point,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[
        ("psd", crate::pipeline::context::Arity::One),
        ("columns", crate::pipeline::context::Arity::Many),
    ]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "friction_angle_deg", "model_capped", "mu_r", "runout_eq46_a*", "runout_mean_a*", "runout_std_a*",
            "stiffness_factor",
        ],
        tables: &[
            crate::stages::kind::TableDecl {
                name: "shear",
                columns: &["inertial_number", "sigma_n_pa", "tau_pa"],
            },
            crate::stages::kind::TableDecl {
                name: "table",
                columns: &["a", "member", "runout_norm", "t_end_over_tau_c"],
            },
        ],
        measurements: &[],
        texts: &[],
    },
    reads: None,
    cost: Some(cost),
    atlas: None,
};

/// Apply a `calibration` input (a `dem-calibration` stage) to a stage's DEM parameters:
/// μ_r and the rolling model come from the chosen grid point. Returns whether one was
/// applied (then every claim resting on them is calibrated).
pub fn apply_calibration(ctx: &StageCtx, dem: &mut DemParams) -> anyhow::Result<bool> {
    let Some(input) = ctx.input_opt("calibration") else {
        return Ok(false);
    };
    dem.rolling.mu_r = input.scalar("mu_r")?;
    dem.rolling.model = if input.scalar("rolling_model_capped")? > 0.5 {
        RollingModel::Capped
    } else {
        RollingModel::Epsd
    };
    Ok(true)
}

/// Cost: the shear test and the column ensembles, bounded by the larger ratio (see the
/// module doc).
fn cost(c: &CostCtx) -> Option<Work> {
    let p: PointParams = c.typed()?;
    let rate = p.dem.steps_per_second(p.stiffness_factor);
    let shear = c.input::<PsdParams>("psd")?.n as f64 * rate * p.shear.relative_duration();
    let cols: f64 = c.all::<ColumnPrep>("columns").iter().map(|x| x.area_m2).sum::<f64>() * rate;
    Some((vec![("shear test", shear), ("columns", cols)], true))
}
