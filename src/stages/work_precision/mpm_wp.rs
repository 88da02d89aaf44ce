//! `work-precision`, `method: mpm` ([`super::study`]): MPM column run-out error against wall time over PPC × cell
//! size × Courant number (and the alternative shape functions and update scheme).

use serde::{Deserialize, Serialize};

use super::wp_summary::ensemble_error;
use crate::mpm::column::{CollapseOptions, CollapseResult, ColumnSpec, collapse};
use crate::mpm::{MpmParams, StepRule};
use crate::pipeline::context::{Output, StageCtx, frame};
use crate::stages::Validate;
use crate::stages::column::mpm_common::{calibrate, check_mpm};
use crate::stages::column::mpm_common::{cfl, points};
use crate::stages::kind::{CostCtx, Work};
use crate::validate::{Checker, Issue};

/// One extra work-precision setting: a point of the PPC × cell × Courant grid run with
/// other shape functions or another update scheme (the knobs with two values).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct WpAlternative {
    /// Points per cell.
    pub ppc: u32,
    /// Cell size [m].
    pub cell_size: f64,
    /// Courant number.
    pub courant: f64,
    /// Shape functions (`gimp` | `linear`).
    #[serde(default)]
    pub shape: crate::mpm::params::Shape,
    /// Update scheme (`usl` | `musl`).
    #[serde(default = "usl")]
    pub scheme: crate::mpm::Scheme,
}

fn usl() -> crate::mpm::Scheme {
    crate::mpm::Scheme::Usl
}

/// Perturbed starts per setting (MPM runs are deterministic: the spread of a setting's
/// run-out under a tiny change of the initial point positions is its error bar).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct WpEnsemble {
    /// Runs per setting; member 0 is unperturbed (1 = the deterministic run alone).
    pub members: usize,
    /// Velocity given to every point at release, uniform in ±`perturbation` × √(g H_0) per axis.
    pub perturbation: f64,
    /// ChaCha8 seed of the jitter.
    pub seed: u64,
}

impl Default for WpEnsemble {
    fn default() -> Self {
        WpEnsemble {
            members: 1,
            perturbation: 1e-3,
            seed: 7,
        }
    }
}

/// Parameters of a `work-precision` stage with `method: mpm`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WorkPrecisionParams {
    /// Base solver and material.
    pub mpm: MpmParams,
    /// Aspect ratio.
    pub a: f64,
    /// Column area L_0·H_0 [m²] (as the DEM columns of the profile).
    pub area_m2: f64,
    /// Points per cell to sweep.
    pub ppc: Vec<u32>,
    /// Cell sizes to sweep [m].
    pub cell_sizes: Vec<f64>,
    /// Courant numbers to sweep.
    pub courants: Vec<f64>,
    /// Reference run: (ppc, cell size, Courant number) — the finest.
    pub reference: (u32, f64, f64),
    /// Extra settings with other shape functions or update scheme.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub alternatives: Vec<WpAlternative>,
    /// Perturbed starts per setting.
    #[serde(skip_serializing_if = "is_single")]
    pub ensemble: WpEnsemble,
    /// The tall-column (a = 6) resolution check ([`super::mpm_tall`], issue 25): table
    /// `tall_resolution`. None: not run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tall: Option<Box<super::mpm_tall::TallCheck>>,
    /// Run control.
    pub run: CollapseOptions,
    /// Take φ and E from the DEM calibration inputs when declared.
    pub use_dem_calibration: bool,
}

fn is_single(e: &WpEnsemble) -> bool {
    *e == WpEnsemble::default()
}

impl Default for WorkPrecisionParams {
    fn default() -> Self {
        WorkPrecisionParams {
            mpm: MpmParams::default(),
            a: 0.4,
            area_m2: crate::mpm::column::DEM_COLUMN_AREA,
            ppc: vec![4, 9, 16, 25],
            cell_sizes: vec![2e-3, 4e-3],
            courants: vec![0.5, 0.25],
            reference: (25, 2e-3, 0.1),
            alternatives: vec![],
            ensemble: WpEnsemble::default(),
            tall: None,
            run: CollapseOptions::default(),
            use_dem_calibration: true,
        }
    }
}

impl Validate for WorkPrecisionParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_mpm(&self.mpm, &mut c);
        c.in_closed("a", self.a, 0.05, 20.0);
        for &p in self
            .ppc
            .iter()
            .chain(std::iter::once(&self.reference.0))
            .chain(self.alternatives.iter().map(|a| &a.ppc))
        {
            let r = (p as f64).sqrt().round() as u32;
            c.check(p >= 1 && r * r == p, "ppc", p, "perfect squares (1, 4, 9, 16, 25, …)");
        }
        for &h in self
            .cell_sizes
            .iter()
            .chain(std::iter::once(&self.reference.1))
            .chain(self.alternatives.iter().map(|a| &a.cell_size))
        {
            c.positive("cell_sizes", h);
        }
        for &k in self
            .courants
            .iter()
            .chain(std::iter::once(&self.reference.2))
            .chain(self.alternatives.iter().map(|a| &a.courant))
        {
            c.in_open_closed("courants", k, 0.0, 1.0);
        }
        c.check(
            !self.ppc.is_empty() && !self.cell_sizes.is_empty() && !self.courants.is_empty(),
            "ppc",
            "[]",
            "non-empty sweeps",
        );
        c.check(
            (1..=16).contains(&self.ensemble.members),
            "ensemble.members",
            self.ensemble.members,
            "an integer in [1, 16]",
        );
        c.in_closed("ensemble.perturbation", self.ensemble.perturbation, 0.0, 0.1);
        if let Some(t) = &self.tall {
            t.check(&mut c);
        }
        c.issues
    }
}

/// One work-precision setting: (ppc, cell size, Courant, shape, scheme).
type WpSetting = (u32, f64, f64, crate::mpm::params::Shape, crate::mpm::Scheme);

/// The runs of one setting (an ensemble) and their run-out statistics.
struct WpRuns {
    runs: Vec<CollapseResult>,
    mean: f64,
    sd: f64,
    q99_mean: f64,
    wall_s: f64,
}

/// Geostatic stage, release, collapse — as [`collapse`], with every point's velocity at
/// release perturbed (member k > 0) by a uniform random ±`perturbation` × √(g H_0) per axis
/// (after the geostatic stage: jittered positions before it keep the damped stage from
/// reaching its rest criterion, and moving points after it would stale their stencils).
fn perturbed_collapse(
    mp: &MpmParams,
    spec: ColumnSpec,
    opts: &CollapseOptions,
    k: usize,
    e: &WpEnsemble,
) -> anyhow::Result<CollapseResult> {
    use crate::mpm::column::{build, expected_v_max, release, run_collapse};
    use rand::{RngExt, SeedableRng};
    if k == 0 || e.perturbation == 0.0 {
        return Ok(collapse(mp, spec, opts)?);
    }
    let vmax = expected_v_max(&spec, mp.gravity);
    crate::mpm::preflight::preflight(mp, crate::mpm::preflight::planned_dt(mp, vmax), vmax)?;
    let mut col = build(mp, spec)?;
    let geo = if opts.skip_geostatic {
        None
    } else {
        Some(crate::mpm::geostatic::run(
            &mut col.solver, &mut col.state, col.spec.h0,
        )?)
    };
    let amp = e.perturbation * (mp.gravity * col.spec.h0).sqrt();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(e.seed.wrapping_mul(0x9E37_79B9).wrapping_add(k as u64));
    for p in col.state.points.iter_mut() {
        p.v.x += amp * (2.0 * rng.random::<f64>() - 1.0);
        p.v.y += amp * (2.0 * rng.random::<f64>() - 1.0);
    }
    release(&mut col);
    Ok(run_collapse(col, geo, mp, opts)?)
}

/// Duration of each run: its stop time / τ_c [-].
fn duration(r: &WpRuns, g: f64) -> Vec<f64> {
    r.runs
        .iter()
        .map(|c| c.series.last().map_or(0.0, |s| s.t) / c.spec.tau_c(g))
        .collect()
}

/// Final potential energy of each run, E_p(end)/E_p(0) [-].
fn ep_final(r: &WpRuns) -> Vec<f64> {
    r.runs
        .iter()
        .map(|c| match (c.series.first(), c.series.last()) {
            (Some(a), Some(b)) if a.e.potential > 0.0 => b.e.potential / a.e.potential,
            _ => f64::NAN,
        })
        .collect()
}

pub(super) fn run(ctx: &StageCtx, mut p: WorkPrecisionParams) -> anyhow::Result<Output> {
    use crate::mpm::Scheme;
    use crate::mpm::params::Shape;
    use rayon::prelude::*;
    let note = calibrate(ctx, &mut p.mpm, p.use_dem_calibration)?;
    let spec = ColumnSpec::from_area(p.a, p.area_m2);
    let (shape0, scheme0) = (p.mpm.shape, p.mpm.scheme);
    let mut configs: Vec<WpSetting> = Vec::new();
    for &h in &p.cell_sizes {
        for &n in &p.ppc {
            for &k in &p.courants {
                configs.push((n, h, k, shape0, scheme0));
            }
        }
    }
    configs.extend(
        p.alternatives
            .iter()
            .map(|a| (a.ppc, a.cell_size, a.courant, a.shape, a.scheme)),
    );
    let members = p.ensemble.members.max(1);
    let runit = |s: &WpSetting| -> anyhow::Result<WpRuns> {
        let mp = MpmParams {
            ppc: s.0,
            cell_size: s.1,
            step: StepRule::Cfl {
                courant: s.2,
                dt_max: 1e-3,
            },
            shape: s.3,
            scheme: s.4,
            ..p.mpm.clone()
        };
        let runs = (0..members)
            .into_par_iter()
            .map(|k| perturbed_collapse(&mp, spec, &p.run, k, &p.ensemble))
            .collect::<Vec<_>>()
            .into_iter()
            .collect::<anyhow::Result<Vec<_>>>()?;
        let n = runs.len() as f64;
        let mean = runs.iter().map(|r| r.runout).sum::<f64>() / n;
        let sd = if runs.len() > 1 {
            (runs.iter().map(|r| (r.runout - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            f64::NAN
        };
        let q99_mean = runs.iter().map(|r| r.runout_q99).sum::<f64>() / n;
        let wall_s = runs.iter().map(|r| r.wall_s).sum::<f64>() / n;
        Ok(WpRuns {
            runs,
            mean,
            sd,
            q99_mean,
            wall_s,
        })
    };
    let total = configs.len() + 1;
    let reference = runit(&(p.reference.0, p.reference.1, p.reference.2, shape0, scheme0))?;
    let reference = &reference;
    ctx.set_progress(1.0 / total as f64);
    let mut rows: Vec<(WpSetting, WpRuns)> = Vec::new();
    let ref_setting: WpSetting = (p.reference.0, p.reference.1, p.reference.2, shape0, scheme0);
    for (i, s) in configs.iter().enumerate() {
        // a grid point at the reference setting is the reference itself (error 0): not re-run
        let runs = if *s == ref_setting {
            WpRuns {
                runs: reference.runs.clone(),
                ..*reference
            }
        } else {
            runit(s)?
        };
        rows.push((*s, runs));
        ctx.set_progress((i + 2) as f64 / total as f64);
    }
    let ref_dl = reference.mean;
    let nf = members as f64;
    // error of the ensemble means and its standard error (NaN for single runs)
    let err = |r: &WpRuns| ((r.mean - ref_dl) / ref_dl).abs();
    let err_se = |r: &WpRuns| (r.sd.powi(2) / nf + reference.sd.powi(2) / nf).sqrt() / ref_dl.abs();
    let mut out = Output::default();
    out.table(
        "table",
        frame(vec![
            ("ppc", rows.iter().map(|r| r.0.0 as f64).collect()),
            ("cell_size_m", rows.iter().map(|r| r.0.1).collect()),
            ("courant", rows.iter().map(|r| r.0.2).collect()),
            (
                "shape_linear",
                rows.iter().map(|r| (r.0.3 == Shape::Linear) as u8 as f64).collect(),
            ),
            (
                "scheme_musl",
                rows.iter().map(|r| (r.0.4 == Scheme::Musl) as u8 as f64).collect(),
            ),
            ("members", rows.iter().map(|r| r.1.runs.len() as f64).collect()),
            ("points", rows.iter().map(|r| r.1.runs[0].points as f64).collect()),
            ("steps", rows.iter().map(|r| r.1.runs[0].steps as f64).collect()),
            ("runout_norm", rows.iter().map(|r| r.1.mean).collect()),
            ("runout_norm_std", rows.iter().map(|r| r.1.sd).collect()),
            ("runout_rel_error", rows.iter().map(|r| err(&r.1)).collect()),
            ("runout_rel_error_se", rows.iter().map(|r| err_se(&r.1)).collect()),
            ("runout_q99_norm", rows.iter().map(|r| r.1.q99_mean).collect()),
            (
                "runout_q99_rel_error",
                rows.iter()
                    .map(|r| ((r.1.q99_mean - reference.q99_mean) / reference.q99_mean).abs())
                    .collect(),
            ),
            (
                "point_steps",
                rows.iter()
                    .map(|r| r.1.runs[0].points as f64 * r.1.runs[0].steps as f64)
                    .collect(),
            ),
            // the other quantities the column figures report: duration (the stop rule's instant,
            // fig 4.11) and final energy (E_p(end)/E_p(0), fig 4.13), same ensemble-mean measure
            (
                "duration_tau_mean",
                rows.iter()
                    .map(|r| ensemble_error(&duration(&r.1, p.mpm.gravity), &duration(reference, p.mpm.gravity)).0)
                    .collect(),
            ),
            (
                "duration_rel_error",
                rows.iter()
                    .map(|r| ensemble_error(&duration(&r.1, p.mpm.gravity), &duration(reference, p.mpm.gravity)).1)
                    .collect(),
            ),
            (
                "duration_rel_error_se",
                rows.iter()
                    .map(|r| ensemble_error(&duration(&r.1, p.mpm.gravity), &duration(reference, p.mpm.gravity)).2)
                    .collect(),
            ),
            (
                "ep_final_mean",
                rows.iter()
                    .map(|r| ensemble_error(&ep_final(&r.1), &ep_final(reference)).0)
                    .collect(),
            ),
            (
                "ep_final_rel_error",
                rows.iter()
                    .map(|r| ensemble_error(&ep_final(&r.1), &ep_final(reference)).1)
                    .collect(),
            ),
            (
                "ep_final_rel_error_se",
                rows.iter()
                    .map(|r| ensemble_error(&ep_final(&r.1), &ep_final(reference)).2)
                    .collect(),
            ),
        ])?,
    );
    // Wall times are measurements, not results: a separate table so the main one stays
    // bit-identical across runs and thread counts.
    out.table(
        "timing",
        frame(vec![
            ("ppc", rows.iter().map(|r| r.0.0 as f64).collect()),
            ("cell_size_m", rows.iter().map(|r| r.0.1).collect()),
            ("courant", rows.iter().map(|r| r.0.2).collect()),
            ("wall_s", rows.iter().map(|r| r.1.wall_s).collect()),
        ])?,
    );
    if let Some(t) = &p.tall {
        tall_outputs(&mut out, &super::mpm_tall::run(&p.mpm, &p.run, p.area_m2, t)?, t)?;
    }
    out.scalar("reference_runout_norm", ref_dl)
        .scalar("reference_runout_q99_norm", reference.q99_mean)
        .scalar("reference_points", reference.runs[0].points as f64)
        .scalar("reference_steps", reference.runs[0].steps as f64)
        .scalar("members", nf);
    if reference.sd.is_finite() {
        out.scalar("reference_runout_std", reference.sd);
    }
    // Profile error: the configuration of the base params (its shape and scheme included).
    let base = rows
        .iter()
        .find(|r| r.0.0 == p.mpm.ppc && (r.0.1 - p.mpm.cell_size).abs() < 1e-12 && r.0.3 == shape0 && r.0.4 == scheme0);
    if let Some(b) = base {
        out.scalar("base_config_runout_rel_error", err(&b.1));
        if b.1.sd.is_finite() {
            out.scalar("base_config_runout_rel_error_se", err_se(&b.1));
        }
        out.scalar(
            "base_config_runout_q99_rel_error",
            ((b.1.q99_mean - reference.q99_mean) / reference.q99_mean).abs(),
        );
        let (_, de, dse) = ensemble_error(&duration(&b.1, p.mpm.gravity), &duration(reference, p.mpm.gravity));
        let (_, ee, ese) = ensemble_error(&ep_final(&b.1), &ep_final(reference));
        out.scalar("base_config_duration_rel_error", de)
            .scalar("base_config_duration_rel_error_se", dse);
        out.scalar("base_config_ep_final_rel_error", ee)
            .scalar("base_config_ep_final_rel_error_se", ese);
    }
    for (s, r) in rows.iter().filter(|r| r.0.3 != shape0 || r.0.4 != scheme0) {
        // the two-valued knobs: the alternative against the base shape/scheme at its setting
        let twin = rows
            .iter()
            .find(|o| o.0.0 == s.0 && o.0.1 == s.1 && o.0.2 == s.2 && o.0.3 == shape0 && o.0.4 == scheme0);
        let key = format!(
            "ppc{}_h{}mm_c{}_{}_{}",
            s.0,
            s.1 * 1e3,
            s.2,
            if s.3 == Shape::Linear { "linear" } else { "gimp" },
            s.4.name().to_lowercase()
        )
        .replace('.', "_");
        out.scalar(&format!("error_{key}"), err(r));
        if let Some(t) = twin {
            out.scalar(&format!("shift_vs_base_{key}"), r.mean - t.1.mean);
        }
    }
    out.note(format!(
        "Reference: {} PPC, h = {} m, Courant {} → ΔL = {:.4}{} ({} points, {} steps, {:.1} s). {}{note}",
        p.reference.0, p.reference.1, p.reference.2, ref_dl,
        if reference.sd.is_finite() { format!(" ± {:.4} (s.d.)", reference.sd) } else { String::new() },
        reference.runs[0].points, reference.runs[0].steps, reference.wall_s,
        if members > 1 { format!("Every setting runs {members} starts (member 0 as built, the others with every point given a random velocity ≤ {} √(g H_0) per axis at release, ChaCha8 seed {}): errors are differences of ensemble means ± their standard error. ", p.ensemble.perturbation, p.ensemble.seed) } else { String::new() },
    ));
    Ok(out)
}

/// Tables `tall_resolution` (results, bit-identical at any thread count) and `tall_timing`
/// (wall times), and the scalars `tall_*`: the base setting's E_p/E_0 at 1 τ_c and
/// t_KEmax/τ_c, and the largest shift of either over the other settings.
fn tall_outputs(
    out: &mut Output,
    rows: &[super::mpm_tall::TallRow],
    t: &super::mpm_tall::TallCheck,
) -> anyhow::Result<()> {
    let col = |f: &dyn Fn(&super::mpm_tall::TallRow) -> f64| rows.iter().map(f).collect::<Vec<f64>>();
    out.table(
        "tall_resolution",
        frame(vec![
            ("a", col(&|_| t.a)),
            ("cells_across", col(&|r| r.cells as f64)),
            ("cell_size_m", col(&|r| r.cell_size)),
            ("ppc", col(&|r| r.ppc as f64)),
            ("points", col(&|r| r.points as f64)),
            ("steps", col(&|r| r.steps as f64)),
            ("ep_over_e0_0_5tau", col(&|r| r.ep[0])),
            ("ep_over_e0_1tau", col(&|r| r.ep[1])),
            ("ep_over_e0_2tau", col(&|r| r.ep[2])),
            ("t_kemax_over_tau_c", col(&|r| r.t_kemax)),
            ("runout_norm_end", col(&|r| r.runout_end)),
        ])?,
    );
    out.table(
        "tall_timing",
        frame(vec![
            ("cells_across", col(&|r| r.cells as f64)),
            ("ppc", col(&|r| r.ppc as f64)),
            ("wall_s", col(&|r| r.wall_s)),
        ])?,
    );
    if let Some(b) = rows.first() {
        let shift =
            |f: &dyn Fn(&super::mpm_tall::TallRow) -> f64| rows.iter().map(|r| (f(r) - f(b)).abs()).fold(0.0, f64::max);
        out.scalar("tall_ep_1tau_base", b.ep[1])
            .scalar("tall_ep_1tau_max_shift", shift(&|r| r.ep[1]))
            .scalar("tall_t_kemax_base", b.t_kemax)
            .scalar("tall_t_kemax_max_shift", shift(&|r| r.t_kemax));
        out.note(format!(
            "Tall-column check (a = {}, one knob at a time from {} cells across L_0 and {} PPC, Courant {}, to {} τ_c): E_p/E_0 at 1 τ_c = {:.3} (largest shift {:.3}), t_KEmax/τ_c = {:.3} (largest shift {:.3}); table tall_resolution.",
            t.a, b.cells, b.ppc, t.courant, t.until_tau, b.ep[1], shift(&|r| r.ep[1]), b.t_kemax, shift(&|r| r.t_kemax)
        ));
    }
    Ok(())
}

/// Cost (work-precision): points × steps summed over the sweep and its reference.
pub(super) fn cost(p: &WorkPrecisionParams, _: &CostCtx) -> Option<Work> {
    let mut total = 0.0;
    for &h in &p.cell_sizes {
        for &n in &p.ppc {
            for &k in &p.courants {
                total += points(p.area_m2, n as f64, h) * cfl(&p.mpm, k, h);
            }
        }
    }
    let (n, h, k) = p.reference;
    total += points(p.area_m2, n as f64, h) * cfl(&p.mpm, k, h);
    if let Some(t) = &p.tall {
        // cfl() counts the steps of a whole run (to rest); the check stops at until_tau
        let l0 = ColumnSpec::from_area(t.a, p.area_m2).l0;
        for (cells, ppc) in t.settings() {
            let h = l0 / cells as f64;
            total += points(p.area_m2, ppc as f64, h) * cfl(&p.mpm, t.courant, h);
        }
    }
    Some((vec![("points×steps of the sweep", total)], false))
}
