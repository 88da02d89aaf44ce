//! CD stage kinds: the periodic shear test (C3: μ*(I) and its μ(I) fit, whose μ_min the
//! pile's MPM can read through the DAG), the figure 4.25 stage with the chapter's claim,
//! and the pile work-precision sweep.
//!
//! Every kind takes `cd` (the solver's parameter schema, `stages/cd-solver.yaml`).

use serde::{Deserialize, Serialize};

use super::{Kind, Validate, decode, typed};
use crate::cd::CdParams;
use crate::cd::shear::{ShearCdParams, shear_test};
use crate::pipeline::context::{Claim, Output, StageCtx, col_f64, frame};
use crate::report::plot::{Chart, Legend, Series, Style, footer};
use crate::validate::{Checker, Issue};

fn check_cd(p: &CdParams, c: &mut Checker) {
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
    version: 1,
    about: "C3: periodic CD shear at several inertial numbers -> mu*(I), fit mu_min + b I",
    params: typed::<ShearStageParams>,
    run: run_shear,
    explain: None,
};

/// Parameters of a `cd-shear-figure` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShearFigureParams {
    /// The chapter's macroscopic friction coefficient.
    pub paper_mu: f64,
    /// Allowed |μ_min − 0.22|. 0.03: about twice the standard error of μ_min in the quick
    /// cell, and the spread of quasi-static μ* reported for 2D disks at μ_p = 0.4.
    pub tolerance: f64,
}

impl Default for ShearFigureParams {
    fn default() -> Self {
        ShearFigureParams {
            paper_mu: 0.22,
            tolerance: 0.03,
        }
    }
}

impl Validate for ShearFigureParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.positive("paper_mu", self.paper_mu);
        c.positive("tolerance", self.tolerance);
        c.issues
    }
}

fn run_shear_figure(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: ShearFigureParams = decode(ctx)?;
    let input = ctx.input("shear")?;
    let df = input.table("table")?;
    let (i, mu, se) = (
        col_f64(&df, "inertial_number")?,
        col_f64(&df, "mu")?,
        col_f64(&df, "mu_se")?,
    );
    let (mu_min, b) = (input.scalar("mu_min")?, input.scalar("b")?);
    let mu_min_se = input.scalar("mu_min_se").unwrap_or(f64::NAN);
    let i_fit = input
        .params
        .pointer("/shear/fit_max_inertial_number")
        .and_then(|v| v.as_f64())
        .unwrap_or(f64::NAN);
    let mut out = Output::default();
    out.table(
        "table",
        frame(vec![
            ("inertial_number", i.clone()),
            ("mu", mu.clone()),
            ("mu_se", se.clone()),
        ])?,
    );
    out.scalar("mu_min", mu_min)
        .scalar("b", b)
        .scalar("mu_min_se", mu_min_se);
    out.claims.push(Claim::abs("macro-friction", "\"Periodic shear tests using CD (figure 4.25a), reveals a macroscopic friction coefficient of 0.22\" — μ*(I → 0) = μ_min of the fit μ = μ_min + b I", p.paper_mu, mu_min, p.tolerance));
    out.note(format!(
        "μ* points from `{}`; fit μ_min = {:.3} ± {:.3}, b = {:.3}.",
        input.id, mu_min, mu_min_se, b
    ));
    let (lo, hi) = i
        .iter()
        .filter(|v| *v > &0.0)
        .fold((f64::INFINITY, 0.0f64), |(a, z), &v| (a.min(v), z.max(v)));
    let grid: Vec<f64> = (0..=40)
        .map(|k| (lo / 1.5) * ((hi * 1.5) / (lo / 1.5)).powf(k as f64 / 40.0))
        .collect();
    let mut err_lo = Vec::new();
    let mut err_hi = Vec::new();
    for k in 0..i.len() {
        err_lo.push((i[k], mu[k] - se[k]));
        err_hi.push((i[k], mu[k] + se[k]));
    }
    let chart = Chart {
        title: ctx.caption.clone().unwrap_or_else(|| "Figure 4.25b".into()),
        footer: footer(
            &ctx.profile,
            &format!("μ_min = {mu_min:.3} ± {mu_min_se:.3}, b = {b:.3}"),
        ),
        x_label: "inertial number I [-]".into(),
        y_label: "macroscopic friction μ* = τ/σ_n [-]".into(),
        x_log: true,
        y_range: Some((0.0, (mu.iter().cloned().fold(0.0, f64::max) * 1.25).max(0.5))),
        legend: Legend::UpperLeft,
        series: vec![
            Series::new(
                "CD, time-averaged steady shear",
                Style::Points,
                i.iter().cloned().zip(mu.iter().cloned()).collect(),
                0,
            ),
            Series::new(
                "± standard error (8 blocks)",
                Style::Points,
                err_lo.into_iter().chain(err_hi).collect(),
                5,
            ),
            Series::new(
                format!("fit (I ≤ {i_fit}): μ = {mu_min:.3} + {b:.2} I"),
                Style::Dashed,
                grid.iter().map(|&x| (x, mu_min + b * x)).collect(),
                1,
            ),
            Series::new(
                format!("stated: μ* = {}", p.paper_mu),
                Style::Dashed,
                vec![(grid[0], p.paper_mu), (grid[40], p.paper_mu)],
                7,
            ),
        ],
        ..Default::default()
    };
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `cd-shear-figure`.
pub const SHEAR_FIGURE_KIND: Kind = Kind {
    name: "cd-shear-figure",
    version: 1,
    about: "fig4-25b: macroscopic friction mu* against inertial number (log x) with the fit and the 0.22 claim",
    params: typed::<ShearFigureParams>,
    run: run_shear_figure,
    explain: None,
};

/// One work-precision variant.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct WpVariant {
    /// Time step [s].
    pub dt: f64,
    /// NLGS tolerance (‖ΔP‖/‖P‖); the residual tolerance is 10× it.
    pub tolerance: f64,
    /// NLGS iteration cap of this variant (default: the solver's `max_iterations`): a step
    /// that reaches it ends unconverged, counted in `unconverged_steps`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_iterations: Option<u32>,
}

/// Perturbed starts per variant (the pile is chaotic: every variant runs the same starts,
/// the errors are differences of ensemble means with their standard error).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct WpEnsemble {
    /// Starts per variant; member 0 is the settled deposit itself (1 = no ensemble).
    pub members: usize,
    /// Jitter of every grain's position in the settled deposit, uniform in ±this [m].
    pub perturbation_m: f64,
    /// ChaCha8 seed of the jitter.
    pub seed: u64,
}

impl Default for WpEnsemble {
    fn default() -> Self {
        WpEnsemble {
            members: 1,
            perturbation_m: 1e-8,
            seed: 7,
        }
    }
}

fn single(e: &WpEnsemble) -> bool {
    *e == WpEnsemble::default()
}

/// Parameters of a `cd-work-precision` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WpParams {
    /// Solver parameters (dt and tolerances replaced per variant).
    pub cd: CdParams,
    /// The deposit (lattice drop, PSD-PILE sizes at scale 2.455 mm).
    pub deposit: crate::cd::pile::DropSpec,
    /// Settling time of the deposit [s].
    pub settle_time: f64,
    /// Gradient excitation: v_x at the base [m/s].
    pub v0: f64,
    /// Simulated time after the excitation [s].
    pub run_time: f64,
    /// Variants; the first is the reference (finest step, tightest tolerance).
    pub variants: Vec<WpVariant>,
    /// Perturbed starts per variant.
    #[serde(skip_serializing_if = "single")]
    pub ensemble: WpEnsemble,
}

impl Default for WpParams {
    fn default() -> Self {
        WpParams {
            cd: CdParams::default(),
            deposit: crate::cd::pile::DropSpec {
                ncol: 20,
                nrow: 10,
                scale: 2.455e-3,
                seed: 1,
            },
            settle_time: 0.3,
            v0: 0.5,
            run_time: 0.4,
            variants: vec![],
            ensemble: WpEnsemble::default(),
        }
    }
}

impl Validate for WpParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_cd(&self.cd, &mut c);
        c.check(
            self.variants.len() >= 2,
            "variants",
            self.variants.len(),
            "at least two (the first is the reference)",
        );
        for (k, v) in self.variants.iter().enumerate() {
            c.positive(&format!("variants[{k}].dt"), v.dt);
            c.in_open(&format!("variants[{k}].tolerance"), v.tolerance, 0.0, 0.1);
            if let Some(m) = v.max_iterations {
                c.check(m >= 1, &format!("variants[{k}].max_iterations"), m, "≥ 1");
            }
            if let (true, Err(m)) = (
                v.dt > 0.0 && self.v0 > 0.0 && self.deposit.scale > 0.0,
                self.cd.step_preflight(v.dt, 0.8 * self.deposit.scale, self.v0),
            ) {
                c.fail(
                    &format!("variants[{k}].dt"),
                    v.dt,
                    &format!("a step that cannot miss a contact — {m}"),
                );
            }
        }
        c.check(
            self.deposit.ncol >= 3 && self.deposit.nrow >= 2,
            "deposit",
            format!("{}x{}", self.deposit.ncol, self.deposit.nrow),
            "at least 3 columns and 2 rows",
        );
        c.positive("deposit.scale", self.deposit.scale);
        c.positive("settle_time", self.settle_time);
        c.positive("v0", self.v0);
        c.positive("run_time", self.run_time);
        c.check(
            (1..=16).contains(&self.ensemble.members),
            "ensemble.members",
            self.ensemble.members,
            "an integer in [1, 16]",
        );
        c.in_closed("ensemble.perturbation_m", self.ensemble.perturbation_m, 0.0, 1e-4);
        c.issues
    }
}

/// Mean and sample standard deviation (NaN for one value).
fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let sd = if v.len() > 1 {
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    } else {
        f64::NAN
    };
    (m, sd)
}

fn run_wp(ctx: &StageCtx) -> anyhow::Result<Output> {
    use crate::cd::pile::{ImpactResult, impact, settled_deposit};
    use rand::{RngExt, SeedableRng};
    use rayon::prelude::*;
    let p: WpParams = decode(ctx)?;
    let (state, walls) = settled_deposit(&p.deposit, &p.cd, p.settle_time)?;
    let width = p.deposit.width();
    let members = p.ensemble.members.max(1);
    let starts: Vec<_> = (0..members)
        .map(|k| {
            let mut s = state.clone();
            if k > 0 {
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(
                    p.ensemble.seed.wrapping_mul(0x9E37_79B9).wrapping_add(k as u64),
                );
                for i in 0..s.len() {
                    s.x[i] += p.ensemble.perturbation_m * (2.0 * rng.random::<f64>() - 1.0);
                    s.y[i] += p.ensemble.perturbation_m * (2.0 * rng.random::<f64>() - 1.0);
                }
            }
            s
        })
        .collect();
    // rows[variant][member]
    let mut rows: Vec<Vec<ImpactResult>> = Vec::new();
    for (k, v) in p.variants.iter().enumerate() {
        ctx.set_progress(k as f64 / p.variants.len() as f64);
        let cd = CdParams {
            dt: v.dt,
            tolerance: v.tolerance,
            residual_tolerance: (10.0 * v.tolerance).min(0.5),
            max_iterations: v.max_iterations.unwrap_or(p.cd.max_iterations),
            ..p.cd.clone()
        };
        let runs = starts
            .par_iter()
            .map(|s| impact(s, &walls, width, &cd, p.v0, p.run_time))
            .collect::<Vec<_>>()
            .into_iter()
            .collect::<Result<Vec<_>, _>>()?;
        rows.push(runs);
    }
    ctx.set_progress(1.0);
    let nf = members as f64;
    // per variant: (mean, sd) of a quantity; error of the means vs the reference ± s.e.
    let stat = |f: &dyn Fn(&ImpactResult) -> f64| -> Vec<(f64, f64)> {
        rows.iter()
            .map(|rs| mean_sd(&rs.iter().map(f).collect::<Vec<_>>()))
            .collect()
    };
    let rel = |st: &[(f64, f64)]| -> (Vec<f64>, Vec<f64>) {
        let (m0, s0) = st[0];
        (
            st.iter().map(|(m, _)| ((m - m0) / m0).abs()).collect(),
            st.iter()
                .map(|(_, s)| (s.powi(2) / nf + s0.powi(2) / nf).sqrt() / m0.abs())
                .collect(),
        )
    };
    let (st_l, st_c, st_d) = (stat(&|r| r.runout), stat(&|r| r.com_shift), stat(&|r| r.dissipated));
    let ((err_l, se_l), (err_c, se_c), (err_d, se_d)) = (rel(&st_l), rel(&st_c), rel(&st_d));
    let mean_of = |f: &dyn Fn(&ImpactResult) -> f64| -> Vec<f64> {
        rows.iter().map(|rs| rs.iter().map(f).sum::<f64>() / nf).collect()
    };
    let wall: Vec<f64> = mean_of(&|r| r.wall_s);
    let mut out = Output::default();
    out.table(
        "table",
        frame(vec![
            ("dt_s", p.variants.iter().map(|v| v.dt).collect()),
            ("tolerance", p.variants.iter().map(|v| v.tolerance).collect()),
            (
                "max_iterations",
                p.variants
                    .iter()
                    .map(|v| v.max_iterations.unwrap_or(p.cd.max_iterations) as f64)
                    .collect(),
            ),
            ("members", vec![nf; rows.len()]),
            ("runout_norm", st_l.iter().map(|x| x.0).collect()),
            ("runout_norm_std", st_l.iter().map(|x| x.1).collect()),
            ("runout_rel_error", err_l.clone()),
            ("runout_rel_error_se", se_l.clone()),
            ("com_shift_norm", st_c.iter().map(|x| x.0).collect()),
            ("com_shift_norm_std", st_c.iter().map(|x| x.1).collect()),
            ("com_shift_rel_error", err_c.clone()),
            ("com_shift_rel_error_se", se_c.clone()),
            ("dissipated_j_m", st_d.iter().map(|x| x.0).collect()),
            ("dissipated_j_m_std", st_d.iter().map(|x| x.1).collect()),
            ("dissipated_rel_error", err_d.clone()),
            ("dissipated_rel_error_se", se_d.clone()),
            ("ek_final_over_ek0", mean_of(&|r| r.ek_final / r.ek0)),
            (
                "mean_iterations",
                mean_of(&|r| r.stats.iterations as f64 / r.stats.steps.max(1) as f64),
            ),
            ("unconverged_steps", mean_of(&|r| r.stats.unconverged as f64)),
            (
                "max_penetration_d",
                rows.iter()
                    .map(|rs| rs.iter().map(|r| r.stats.max_penetration).fold(0.0, f64::max))
                    .collect(),
            ),
        ])?,
    );
    out.table("timing", frame(vec![("wall_s", wall.clone())])?);
    out.scalar("reference_runout_norm", st_l[0].0)
        .scalar("reference_com_shift_norm", st_c[0].0)
        .scalar("reference_dissipated_j_m", st_d[0].0)
        .scalar("grains", state.len() as f64)
        .scalar("members", nf);
    let v0 = &p.variants[0];
    out.note(format!(
        "Run-out (95th-percentile front) is reported but not plotted: frictional disks roll freely on the flat floor, so the front is a few rolling grains and moves by tens of % between variants with no trend (chaotic); the centre-of-mass travel and the dissipated energy are the converging measures. Reference: h = {:.2e} s, tolerance {:.0e}{} → (L_f − L_0)/L_0 = {:.4}, D = {:.4e} J/m. {} grains, gradient excitation v0 = {} m/s at the base, {} s simulated.{}",
        v0.dt, v0.tolerance, v0.max_iterations.map(|m| format!(", ≤ {m} iterations")).unwrap_or_default(), st_l[0].0, st_d[0].0, state.len(), p.v0, p.run_time,
        if members > 1 { format!(" Every variant runs the same {members} starts (member 0 the settled deposit, the others with every grain jittered by ≤ {:.0e} m, ChaCha8 seed {}): errors are differences of ensemble means ± their standard error.", p.ensemble.perturbation_m, p.ensemble.seed) } else { String::new() }
    ));
    let err_bars = |idx: &[usize], se: &[f64]| -> Vec<f64> {
        idx.iter()
            .map(|&i| if se[i].is_finite() { se[i] } else { 0.0 })
            .collect()
    };
    let mut series = Vec::new();
    let default_cap = p.cd.max_iterations;
    let mut tols: Vec<f64> = p
        .variants
        .iter()
        .skip(1)
        .filter(|v| v.max_iterations.is_none())
        .map(|v| v.tolerance)
        .collect();
    tols.sort_by(|a, b| b.total_cmp(a));
    tols.dedup();
    for (k, t) in tols.iter().enumerate() {
        let idx: Vec<usize> = (1..rows.len())
            .filter(|&i| p.variants[i].tolerance == *t && p.variants[i].max_iterations.is_none())
            .collect();
        let s = Series::new(
            format!("centre-of-mass travel, tolerance {t:.0e} (points: h)"),
            Style::LinePoints,
            idx.iter().map(|&i| (wall[i], err_c[i].max(1e-6))).collect(),
            k,
        );
        series.push(if members > 1 {
            s.with_errors(err_bars(&idx, &se_c))
        } else {
            s
        });
    }
    let capped: Vec<usize> = (1..rows.len())
        .filter(|&i| p.variants[i].max_iterations.is_some_and(|m| m != default_cap))
        .collect();
    if !capped.is_empty() {
        let s = Series::new(
            "centre-of-mass travel, NLGS iteration cap (points: cap)".to_string(),
            Style::LinePoints,
            capped.iter().map(|&i| (wall[i], err_c[i].max(1e-6))).collect(),
            5,
        );
        series.push(if members > 1 {
            s.with_errors(err_bars(&capped, &se_c))
        } else {
            s
        });
    }
    let all: Vec<usize> = (1..rows.len()).collect();
    let s = Series::new(
        "dissipated energy, all variants",
        Style::Points,
        all.iter().map(|&i| (wall[i], err_d[i].max(1e-6))).collect(),
        7,
    );
    series.push(if members > 1 {
        s.with_errors(err_bars(&all, &se_d))
    } else {
        s
    });
    let chart = Chart {
        y_label: "relative error vs the reference".into(),
        ..Chart::work_precision(
            ctx.caption.clone().unwrap_or_else(|| "Work-precision of CD".into()),
            footer(
                &ctx.profile,
                &format!(
                    "reference h = {:.1e} s, tol {:.0e}{}",
                    v0.dt,
                    v0.tolerance,
                    if members > 1 {
                        format!(", {members} starts per variant, ± s.e.")
                    } else {
                        String::new()
                    }
                ),
            ),
            series,
        )
    };
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `cd-work-precision`.
pub const WP_KIND: Kind = Kind {
    name: "cd-work-precision",
    version: 3,
    about: "work-precision of CD: pile impact run-out and dissipated energy against time step and NLGS tolerance, vs wall time",
    params: typed::<WpParams>,
    run: run_wp,
    explain: None,
};
