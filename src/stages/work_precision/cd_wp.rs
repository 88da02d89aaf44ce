//! `work-precision`, `method: cd` ([`super::study`]): the CD pile impact's run-out and dissipated energy against
//! time step and NLGS tolerance, vs wall time (ensembles of perturbed starts).
//!
//! Every CD kind takes `cd` (the solver's parameter schema, `stages/cd-solver.yaml`).

use serde::{Deserialize, Serialize};

use crate::cd::CdParams;
use crate::pipeline::context::{Output, StageCtx, frame};
use crate::stages::Validate;
use crate::stages::calib::cd_shear::check_cd;
use crate::stages::kind::{CostCtx, Work};
use crate::validate::{Checker, Issue};

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

/// Parameters of a `work-precision` stage with `method: cd`.
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
                    format!("{} (with deposit.scale = {})", v.dt, self.deposit.scale),
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

pub(super) fn run(ctx: &StageCtx, p: WpParams) -> anyhow::Result<Output> {
    use crate::cd::pile::{ImpactResult, impact, settled_deposit};
    use rand::{RngExt, SeedableRng};
    use rayon::prelude::*;
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
            // the first variant is the reference; a capped variant sets its own NLGS
            // iteration cap (its figure draws the capped ones as one series)
            ("reference", (0..p.variants.len()).map(|i| (i == 0) as u8 as f64).collect()),
            (
                "capped",
                p.variants
                    .iter()
                    .map(|v| v.max_iterations.is_some_and(|m| m != p.cd.max_iterations) as u8 as f64)
                    .collect(),
            ),
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
    Ok(out)
}

/// Cost (work-precision): the deposit's grains; steps summed over the variants.
pub(super) fn cost(p: &WpParams, _: &CostCtx) -> Option<Work> {
    let t = p.settle_time + p.run_time;
    let steps: f64 = p.variants.iter().map(|x| t / x.dt).sum();
    Some((
        vec![("grains", (p.deposit.ncol * p.deposit.nrow) as f64), ("steps", steps)],
        false,
    ))
}
