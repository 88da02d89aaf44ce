//! Kind `pile-compare`: the chapter's comparisons between pile runs (§4.4.3, §4.4.5), one
//! mechanism — pair `pile-run` outputs and test a stated relation on them. It makes tables
//! and claims; the figures that show them are `plot` declarations reading the same runs.
//!
//! - `profiles` (stage pile-profiles, drawn by fig4-44): gradient against uniform
//!   excitation per method, ΔL and t_f paired per energy, and the three statements of
//!   §4.4.5.
//! - `restitution` (text claim attached to fig4-33, drawn by pile-cd-restitution-fig): CD
//!   runs that differ only in ε_n = ε_t; spread of the run-out per energy.
//! - `cavity` (fig4-42): cavity behind the mass at one instant, uniform against gradient
//!   (the snapshot runs' `snapshot_metrics`).
//! - `front` (fig4-43): MPM against DEM front L(t) at equal times (the runs' `series`).
//! - `ensemble` (issue 28: chaotic outputs as ensemble means with their spread): runs of
//!   any method whose energies come in perturbed groups (E_0 × {0.99, 1, 1.01}); per group
//!   and method the mean, standard deviation and extremes of ΔL/L_0 and t_f, so that a
//!   single-member verdict of fig4-33 can be read against the chaos of the run it rests on.

use serde::{Deserialize, Serialize};

use crate::pipeline::context::{Claim, InputRef, Output, StageCtx, col_f64, frame};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// What to compare.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum What {
    /// Gradient vs uniform (roles `gradient`, `uniform`: one run stage per method each).
    #[default]
    Profiles,
    /// CD restitution sweep (role `runs`).
    Restitution,
    /// Cavity, uniform vs gradient (roles `gradient`, `uniform`: snapshot runs).
    Cavity,
    /// Front, MPM vs DEM (roles `mpm`, `dem`).
    Front,
    /// Spread of perturbed-energy ensembles (role `runs`, any methods).
    Ensemble,
}

/// Parameters of a `pile-compare` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CompareParams {
    /// Comparison.
    pub what: What,
    /// Regime split [mgd] (`profiles`).
    pub split_mgd: f64,
    /// "significantly longer": smallest ratio ΔL_gradient/ΔL_uniform below the split.
    pub longer_ratio: f64,
    /// "weak dependence": largest |ΔL_gradient/ΔL_uniform − 1| above the split.
    pub weak_tolerance: f64,
    /// Largest relative spread (max − min)/mean of ΔL over the restitution values.
    pub spread_tolerance: f64,
    /// Energies within this relative distance of each other form one ensemble (perturbed
    /// starts of a chaotic run): the spread is of the ensemble means (`restitution`; 0: none;
    /// `ensemble`: required > 0).
    pub ensemble_rel: f64,
    /// Instant [√(d/g)] (`cavity`).
    pub at: f64,
    /// Input energy [mgd] and instants [√(d/g)] of the `front` comparison.
    pub e0_mgd: f64,
    /// Instants [√(d/g)] (`front`).
    pub times: Vec<f64>,
    /// Largest relative front difference |L_MPM − L_DEM|/L_DEM (`front`; chapter: "~5 %").
    pub front_tolerance: f64,
}

impl Default for CompareParams {
    fn default() -> Self {
        CompareParams {
            what: What::Profiles,
            split_mgd: 40.0,
            longer_ratio: 1.2,
            weak_tolerance: 0.2,
            spread_tolerance: 0.02,
            ensemble_rel: 0.0,
            at: 20.0,
            e0_mgd: 61.0,
            times: vec![],
            front_tolerance: 0.05,
        }
    }
}

impl Validate for CompareParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.check(
            self.split_mgd.is_finite() && self.split_mgd > 0.0,
            "split_mgd",
            self.split_mgd,
            "a finite energy > 0 [mgd]",
        );
        c.check(
            self.longer_ratio.is_finite() && self.longer_ratio >= 1.0,
            "longer_ratio",
            self.longer_ratio,
            ">= 1",
        );
        c.check(
            self.weak_tolerance.is_finite() && self.weak_tolerance > 0.0,
            "weak_tolerance",
            self.weak_tolerance,
            "> 0",
        );
        c.check(
            self.spread_tolerance.is_finite() && self.spread_tolerance > 0.0,
            "spread_tolerance",
            self.spread_tolerance,
            "> 0",
        );
        c.check(
            self.ensemble_rel.is_finite() && (0.0..0.2).contains(&self.ensemble_rel),
            "ensemble_rel",
            self.ensemble_rel,
            "in [0, 0.2): relative width of a perturbed-energy ensemble",
        );
        c.check(
            self.front_tolerance.is_finite() && self.front_tolerance > 0.0,
            "front_tolerance",
            self.front_tolerance,
            "> 0",
        );
        c.check(
            self.at.is_finite() && self.at >= 0.0,
            "at",
            self.at,
            "an instant >= 0 [√(d/g)]",
        );
        if self.what == What::Ensemble {
            c.check(
                self.ensemble_rel > 0.0,
                "ensemble_rel",
                self.ensemble_rel,
                "> 0 for `what: ensemble` (e.g. 0.015 for energies E_0 × {0.99, 1, 1.01})",
            );
        }
        if self.what == What::Front {
            c.check(
                !self.times.is_empty() && self.times.iter().all(|t| t.is_finite() && *t > 0.0),
                "times",
                format!("{:?}", self.times),
                "a non-empty list of instants > 0 [√(d/g)]",
            );
            c.check(
                self.e0_mgd.is_finite() && self.e0_mgd > 0.0,
                "e0_mgd",
                self.e0_mgd,
                "an input energy > 0 [mgd]",
            );
        }
        c.issues
    }
}

/// Input roles by comparison (for `pipeline::check::roles`).
pub fn roles(params: &serde_json::Value) -> Vec<(&'static str, crate::pipeline::context::Arity)> {
    use crate::pipeline::context::Arity::*;
    match params.get("what").and_then(|w| w.as_str()).unwrap_or("profiles") {
        "restitution" | "ensemble" => vec![("runs", Many)],
        "front" => vec![("mpm", One), ("dem", One)],
        _ => vec![("gradient", Many), ("uniform", Many)],
    }
}

struct Run {
    method: String,
    e: Vec<f64>,
    dl: Vec<f64>,
    tf: Vec<f64>,
}

fn run_of(inp: &InputRef) -> anyhow::Result<Run> {
    let method = inp
        .params
        .get("method")
        .and_then(|m| m.as_str())
        .ok_or_else(|| anyhow::anyhow!("input `{}` is not a pile-run (no `method`)", inp.id))?
        .to_uppercase();
    let df = inp.table("table")?;
    Ok(Run {
        method,
        e: col_f64(&df, "e0_mgd")?,
        dl: col_f64(&df, "dl")?,
        tf: col_f64(&df, "tf")?,
    })
}

/// The runs of role `runs`, one per pile-run stage (the members of an `energies_mgd`
/// sweep joined, sorted by energy; [`super::members`]), each with its first input.
fn joined_runs(ctx: &StageCtx) -> anyhow::Result<Vec<(&InputRef, Run)>> {
    let mut out = Vec::new();
    for group in super::members::by_stage(ctx.inputs_of("runs")) {
        let mut acc = run_of(group[0])?;
        for inp in &group[1..] {
            let r = run_of(inp)?;
            acc.e.extend(r.e);
            acc.dl.extend(r.dl);
            acc.tf.extend(r.tf);
        }
        super::members::sort_by_energy(&mut acc.e, &mut [&mut acc.dl, &mut acc.tf]);
        out.push((group[0], acc));
    }
    Ok(out)
}

/// Values of `b` at the energies of `a` (exact matches only): (E_0, a, b).
fn paired(ea: &[f64], ya: &[f64], eb: &[f64], yb: &[f64]) -> Vec<(f64, f64, f64)> {
    ea.iter()
        .zip(ya)
        .filter_map(|(e, y)| {
            eb.iter()
                .position(|x| (x - e).abs() <= 1e-9 * e.abs())
                .map(|j| (*e, *y, yb[j]))
        })
        .collect()
}

/// Geometric mean of positive ratios (NaN when none).
fn geo_mean(r: &[f64]) -> f64 {
    let v: Vec<f64> = r.iter().cloned().filter(|x| *x > 0.0 && x.is_finite()).collect();
    if v.is_empty() {
        f64::NAN
    } else {
        (v.iter().map(|x| x.ln()).sum::<f64>() / v.len() as f64).exp()
    }
}

fn run_profiles(ctx: &StageCtx, p: &CompareParams, out: &mut Output) -> anyhow::Result<()> {
    let grad: Vec<Run> = ctx
        .inputs_of("gradient")
        .iter()
        .map(run_of)
        .collect::<anyhow::Result<_>>()?;
    let unif: Vec<Run> = ctx
        .inputs_of("uniform")
        .iter()
        .map(run_of)
        .collect::<anyhow::Result<_>>()?;
    let mut rows: Vec<(String, f64, f64, f64, f64, f64)> = Vec::new();
    for g in &grad {
        let u = unif
            .iter()
            .find(|u| u.method == g.method)
            .ok_or_else(|| anyhow::anyhow!("no uniform run of method {} among the `uniform` inputs", g.method))?;
        let m = g.method.to_lowercase();
        let dl = paired(&g.e, &g.dl, &u.e, &u.dl);
        let tf = paired(&g.e, &g.tf, &u.e, &u.tf);
        anyhow::ensure!(
            !dl.is_empty(),
            "the {} gradient and uniform runs share no input energy",
            g.method
        );
        for ((e, dg, du), (_, tg, tu)) in dl.iter().zip(&tf) {
            rows.push((g.method.clone(), *e, *dg, *du, *tg, *tu));
        }
        let low: Vec<f64> = dl.iter().filter(|q| q.0 < p.split_mgd).map(|q| q.1 / q.2).collect();
        let high: Vec<f64> = dl.iter().filter(|q| q.0 > p.split_mgd).map(|q| q.1 / q.2).collect();
        let tfr: Vec<f64> = tf.iter().map(|q| q.1 / q.2).collect();
        let (rl, rh, rt) = (geo_mean(&low), geo_mean(&high), geo_mean(&tfr));
        out.scalar(&format!("{m}_dl_ratio_low"), rl)
            .scalar(&format!("{m}_dl_ratio_high"), rh)
            .scalar(&format!("{m}_tf_ratio"), rt);
        out.claims.push(Claim::at_least(
            &format!("{m}-gradient-longer-low"),
            &format!("{}: \"At low input energy, the gradient velocity distribution shows significantly longer run-out in comparison to uniform velocity distribution\" (geometric mean of ΔL_gradient/ΔL_uniform below {} mgd over {} energies; 'significantly': ≥ {})", g.method, p.split_mgd, low.len(), p.longer_ratio),
            p.longer_ratio,
            rl,
        ));
        out.claims.push(Claim::abs(
            &format!("{m}-weak-dependence-high"),
            &format!("{}: \"at higher input energy … the run-out distance has a weak dependence on the distribution of velocity\" (geometric mean of ΔL_gradient/ΔL_uniform above {} mgd over {} energies; within ±{})", g.method, p.split_mgd, high.len(), p.weak_tolerance),
            1.0,
            rh,
            p.weak_tolerance,
        ));
        out.claims.push(Claim::at_most(
            &format!("{m}-tf-gradient-shorter"),
            &format!("{}: \"a slope subjected to a gradient velocity flows quicker than a slope subjected to a uniform horizontal velocity\" (geometric mean of t_f,gradient/t_f,uniform over {} energies; < 1)", g.method, tfr.len()),
            1.0,
            rt,
        ));
    }
    out.table(
        "table",
        polars::prelude::DataFrame::new_infer_height(vec![
            polars::prelude::Column::new("method".into(), rows.iter().map(|r| r.0.clone()).collect::<Vec<_>>()),
            polars::prelude::Column::new("e0_mgd".into(), rows.iter().map(|r| r.1).collect::<Vec<_>>()),
            polars::prelude::Column::new("dl_gradient".into(), rows.iter().map(|r| r.2).collect::<Vec<_>>()),
            polars::prelude::Column::new("dl_uniform".into(), rows.iter().map(|r| r.3).collect::<Vec<_>>()),
            polars::prelude::Column::new("tf_gradient".into(), rows.iter().map(|r| r.4).collect::<Vec<_>>()),
            polars::prelude::Column::new("tf_uniform".into(), rows.iter().map(|r| r.5).collect::<Vec<_>>()),
        ])?,
    );
    Ok(())
}

/// Ensembles of perturbed starts: `energies`, sorted, chained while neighbours are within
/// `rel` of each other; a run's members of a group are its energies inside the group's
/// (lowest, highest) range.
fn ensembles(energies: &[f64], rel: f64) -> Vec<(f64, f64)> {
    let tol = rel.max(1e-9);
    let mut sorted = energies.to_vec();
    sorted.sort_by(|a, b| a.total_cmp(b));
    let mut groups: Vec<(f64, f64)> = Vec::new();
    for e in sorted {
        match groups.last_mut() {
            Some(g) if e / g.1 - 1.0 <= tol => g.1 = e,
            _ => groups.push((e, e)),
        }
    }
    groups
}

/// Mean, sample standard deviation (NaN for one value), least and largest of `v`.
fn moments(v: &[f64]) -> (f64, f64, f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let sd = if v.len() > 1 {
        (v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0)).sqrt()
    } else {
        f64::NAN
    };
    let lo = v.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = v.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    (mean, sd, lo, hi)
}

/// The spread of each method's perturbed-energy ensembles (table only; the figure is the
/// declared plot `pile-ensembles-fig`).
fn run_ensemble(ctx: &StageCtx, p: &CompareParams, out: &mut Output) -> anyhow::Result<()> {
    // (method, geometric-mean E_0, members, ΔL moments, t_f moments)
    type Row = (String, f64, usize, [f64; 4], [f64; 4]);
    let mut rows: Vec<Row> = Vec::new();
    for (inp, r) in joined_runs(ctx)? {
        let m = r.method.to_lowercase();
        let groups: Vec<(f64, f64)> = ensembles(&r.e, p.ensemble_rel)
            .into_iter()
            .filter(|(lo, hi)| hi > lo)
            .collect();
        anyhow::ensure!(
            !groups.is_empty(),
            "input `{}` has no ensemble: no two of its energies {:?} mgd lie within ensemble_rel = {} of each other",
            inp.id,
            r.e,
            p.ensemble_rel
        );
        let (mut worst_dl, mut worst_tf) = (0.0f64, 0.0f64);
        for (lo, hi) in groups {
            let inside: Vec<usize> = (0..r.e.len())
                .filter(|&i| r.e[i] >= lo * (1.0 - 1e-9) && r.e[i] <= hi * (1.0 + 1e-9))
                .collect();
            let dl = moments(&inside.iter().map(|&i| r.dl[i]).collect::<Vec<_>>());
            let tf = moments(&inside.iter().map(|&i| r.tf[i]).collect::<Vec<_>>());
            let e = (lo * hi).sqrt();
            out.scalar(&format!("{m}_dl_rel_sd_at_{e:.2}"), dl.1 / dl.0)
                .scalar(&format!("{m}_tf_rel_sd_at_{e:.2}"), tf.1 / tf.0);
            worst_dl = worst_dl.max(dl.1 / dl.0);
            worst_tf = worst_tf.max(tf.1 / tf.0);
            rows.push((
                r.method.clone(),
                e,
                inside.len(),
                [dl.0, dl.1, dl.2, dl.3],
                [tf.0, tf.1, tf.2, tf.3],
            ));
        }
        out.scalar(&format!("{m}_dl_rel_sd_max"), worst_dl)
            .scalar(&format!("{m}_tf_rel_sd_max"), worst_tf);
    }
    let num = |name: &str, f: &dyn Fn(&Row) -> f64| {
        polars::prelude::Column::new(name.into(), rows.iter().map(f).collect::<Vec<f64>>())
    };
    let df = polars::prelude::DataFrame::new_infer_height(vec![
        polars::prelude::Column::new("method".into(), rows.iter().map(|r| r.0.clone()).collect::<Vec<_>>()),
        num("e0_mgd", &|r| r.1),
        num("members", &|r| r.2 as f64),
        num("dl_mean", &|r| r.3[0]),
        num("dl_sd", &|r| r.3[1]),
        num("dl_min", &|r| r.3[2]),
        num("dl_max", &|r| r.3[3]),
        num("tf_mean", &|r| r.4[0]),
        num("tf_sd", &|r| r.4[1]),
        num("tf_min", &|r| r.4[2]),
        num("tf_max", &|r| r.4[3]),
    ])?;
    out.table("table", df);
    Ok(())
}

fn run_restitution(ctx: &StageCtx, p: &CompareParams, out: &mut Output) -> anyhow::Result<()> {
    let mut runs = Vec::new();
    for (inp, r) in joined_runs(ctx)? {
        let eps = inp
            .params
            .pointer("/cd/restitution_n")
            .and_then(|v| v.as_f64())
            .ok_or_else(|| anyhow::anyhow!("input `{}` is not a CD pile-run (no cd.restitution_n)", inp.id))?;
        runs.push((eps, r));
    }
    anyhow::ensure!(
        runs.len() >= 2,
        "a restitution comparison needs at least two runs, got {}",
        runs.len()
    );
    let groups = ensembles(&runs[0].1.e, p.ensemble_rel);
    let (mut ce, mut cs, mut cm, mut cw, mut cn) = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (lo, hi) in &groups {
        let inside = |e: f64| e >= lo * (1.0 - 1e-9) && e <= hi * (1.0 + 1e-9);
        let mut means = Vec::new();
        let mut within: f64 = 0.0;
        let mut members = usize::MAX;
        for (_, r) in &runs {
            let v: Vec<f64> =
                r.e.iter()
                    .zip(&r.dl)
                    .filter(|(e, _)| inside(**e))
                    .map(|(_, d)| *d)
                    .collect();
            if v.is_empty() {
                break;
            }
            let m = v.iter().sum::<f64>() / v.len() as f64;
            within = within.max(
                (v.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - v.iter().cloned().fold(f64::INFINITY, f64::min))
                    / m,
            );
            members = members.min(v.len());
            means.push(m);
        }
        if means.len() < runs.len() {
            continue;
        }
        let mean = means.iter().sum::<f64>() / means.len() as f64;
        ce.push((lo * hi).sqrt());
        cs.push(
            (means.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
                - means.iter().cloned().fold(f64::INFINITY, f64::min))
                / mean,
        );
        cm.push(mean);
        cw.push(within);
        cn.push(members as f64);
    }
    anyhow::ensure!(
        !ce.is_empty(),
        "the restitution runs share no input energy (within ensemble_rel = {})",
        p.ensemble_rel
    );
    for (e, w) in ce.iter().zip(&cw) {
        out.scalar(&format!("scatter_at_{e:.2}"), *w);
    }
    out.scalar("scatter_max", cw.iter().cloned().fold(0.0, f64::max));
    let worst = cs.iter().cloned().fold(0.0, f64::max);
    for (e, s) in ce.iter().zip(&cs) {
        out.scalar(&format!("spread_at_{e:.2}"), *s);
    }
    out.scalar("spread_max", worst);
    out.table(
        "table",
        frame(vec![
            ("e0_mgd", ce.clone()),
            ("dl_mean", cm),
            ("dl_spread", cs.clone()),
            ("dl_scatter_within_eps", cw.clone()),
            ("members", cn),
        ])?,
    );
    let eps: Vec<String> = runs.iter().map(|r| format!("{}", r.0)).collect();
    out.claims.push(Claim::at_most(
        "restitution-no-difference",
        &format!("\"CD simulations using different values of coefficient of restitution show no difference in the run-out behaviour\": largest relative spread (max − min)/mean of ΔL over ε ∈ {{{}}} at E_0 ∈ {:?} mgd (means over the energies within ±{} of each; the scatter within one ε, the runs' chaos, is up to {:.1} %; bound {})", eps.join(", "), ce, p.ensemble_rel, 100.0 * cw.iter().cloned().fold(0.0, f64::max), p.spread_tolerance),
        p.spread_tolerance,
        worst,
    ));
    Ok(())
}

fn metric_at(inp: &InputRef, col: &str, t: f64) -> anyhow::Result<f64> {
    let df = inp
        .table("snapshot_metrics")
        .map_err(|e| anyhow::anyhow!("input `{}` has no snapshot_metrics (give it `snapshots`): {e}", inp.id))?;
    let ts = col_f64(&df, "t_over_sqrt_d_g")?;
    let v = col_f64(&df, col)?;
    // frames are taken at sample instants; a fixed-step solver lands within a step of them
    let k = ts.iter().position(|x| (x - t).abs() < 0.1).ok_or_else(|| {
        anyhow::anyhow!(
            "input `{}` has no snapshot within 0.1 √(d/g) of t = {t} √(d/g) (it has {ts:?})",
            inp.id
        )
    })?;
    Ok(v[k])
}

fn run_cavity(ctx: &StageCtx, p: &CompareParams, out: &mut Output) -> anyhow::Result<()> {
    let g = ctx.inputs_of("gradient");
    let u = ctx.inputs_of("uniform");
    anyhow::ensure!(
        g.len() == u.len() && !g.is_empty(),
        "give as many `gradient` as `uniform` snapshot runs (got {} and {})",
        g.len(),
        u.len()
    );
    for (gi, ui) in g.iter().zip(u) {
        let m = gi
            .params
            .get("method")
            .and_then(|m| m.as_str())
            .unwrap_or("?")
            .to_string();
        let (cg, cu) = (metric_at(gi, "cavity_d2", p.at)?, metric_at(ui, "cavity_d2", p.at)?);
        out.scalar(&format!("{m}_cavity_gradient_d2"), cg)
            .scalar(&format!("{m}_cavity_uniform_d2"), cu);
        let ratio = if cg > 0.0 {
            cu / cg
        } else if cu > 0.0 {
            f64::INFINITY
        } else {
            f64::NAN
        };
        out.scalar(
            &format!("{m}_cavity_ratio"),
            if ratio.is_finite() { ratio } else { -1.0 },
        );
        out.claims.push(Claim::at_least(
            &format!("{m}-cavity-larger-uniform"),
            &format!("{}: \"unlike the gradient input velocity, the cavity left behind the granular mass is not filled\" — cavity area at t = {} √(d/g), uniform over gradient, > 1 (uniform {cu:.1} d², gradient {cg:.1} d²)", m.to_uppercase(), p.at),
            1.0 + 1e-9,
            if ratio.is_finite() { ratio } else if cu > 0.0 { 1e9 } else { f64::NAN },
        ));
    }
    Ok(())
}

fn run_front(ctx: &StageCtx, p: &CompareParams, out: &mut Output) -> anyhow::Result<()> {
    let series = |role: &str| -> anyhow::Result<(Vec<f64>, Vec<f64>)> {
        let inp = ctx.input(role)?;
        let df = inp.table("series")?;
        let (e, t, l) = (col_f64(&df, "e0_mgd")?, col_f64(&df, "t")?, col_f64(&df, "l_d")?);
        let keep: Vec<usize> = (0..e.len())
            .filter(|&i| (e[i] - p.e0_mgd).abs() <= 1e-9 * p.e0_mgd)
            .collect();
        anyhow::ensure!(
            !keep.is_empty(),
            "input `{}` has no run at E_0 = {} mgd",
            inp.id,
            p.e0_mgd
        );
        Ok((
            keep.iter().map(|&i| t[i]).collect(),
            keep.iter().map(|&i| l[i]).collect(),
        ))
    };
    let (tm, lm) = series("mpm")?;
    let (td, ld) = series("dem")?;
    let mut worst = 0.0f64;
    let mut cols = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for &t in &p.times {
        let a = crate::analysis::pile::interp(&tm, &lm, t);
        let b = crate::analysis::pile::interp(&td, &ld, t);
        let r = (a - b).abs() / b;
        worst = worst.max(r);
        cols.0.push(t);
        cols.1.push(a);
        cols.2.push(b);
        cols.3.push(r);
        out.scalar(&format!("rel_diff_at_{t}"), r);
    }
    out.scalar("rel_diff_max", worst);
    out.table(
        "table",
        frame(vec![
            ("t_over_sqrt_d_g", cols.0),
            ("l_mpm_d", cols.1),
            ("l_dem_d", cols.2),
            ("rel_diff", cols.3),
        ])?,
    );
    out.claims.push(Claim::at_most(
        "mpm-dem-front",
        &format!("\"the continuum behaviour is identical to that of grain-scale simulations\": largest |L_MPM − L_DEM|/L_DEM of the front at t ∈ {:?} √(d/g), E_0 = {} mgd (docs/definitions.md fig4-42: within ~5 %)", p.times, p.e0_mgd),
        p.front_tolerance,
        worst,
    ));
    Ok(())
}

fn run(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: CompareParams = decode(ctx)?;
    let mut out = Output::default();
    match p.what {
        What::Profiles => run_profiles(ctx, &p, &mut out)?,
        What::Restitution => run_restitution(ctx, &p, &mut out)?,
        What::Cavity => run_cavity(ctx, &p, &mut out)?,
        What::Front => run_front(ctx, &p, &mut out)?,
        What::Ensemble => run_ensemble(ctx, &p, &mut out)?,
    }
    Ok(out)
}

/// Kind `pile-compare`.
pub const KIND: Kind = Kind {
    name: "pile-compare",
    source: file!(),
    method: None,
    version: 5,
    about: "pile comparisons of §4.4 (tables and claims; plots draw them): gradient vs uniform (fig4-44), CD restitution sweep, cavity uniform vs gradient (fig4-42), MPM vs DEM front (fig4-43), spread of perturbed-energy ensembles",
    params: typed::<CompareParams>,
    run,
    explain: None,
    roles: crate::stages::kind::Roles::ByParams(roles),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "dem_cavity_gradient_d2", "dem_cavity_ratio", "dem_cavity_uniform_d2", "dem_dl_ratio_high",
            "dem_dl_ratio_low", "dem_tf_ratio", "*_dl_rel_sd_at_*", "*_dl_rel_sd_max", "*_tf_rel_sd_at_*",
            "*_tf_rel_sd_max", "mpm_cavity_gradient_d2", "mpm_cavity_ratio", "mpm_cavity_uniform_d2",
            "mpm_dl_ratio_high", "mpm_dl_ratio_low", "mpm_tf_ratio", "rel_diff_at_*", "rel_diff_max", "scatter_at_*",
            "scatter_max", "spread_at_*", "spread_max",
        ],
        tables: &[crate::stages::kind::TableDecl {
            name: "table",
            columns: &[
                "dl_gradient", "dl_max", "dl_mean", "dl_min", "dl_scatter_within_eps", "dl_sd", "dl_spread",
                "dl_uniform", "e0_mgd", "l_dem_d", "l_mpm_d", "members", "method", "rel_diff", "t_over_sqrt_d_g",
                "tf_gradient", "tf_max", "tf_mean", "tf_min", "tf_sd", "tf_uniform",
            ],
        }],
        measurements: &[
            "dem-cavity-larger-uniform", "dem-gradient-longer-low", "dem-tf-gradient-shorter",
            "dem-weak-dependence-high", "mpm-cavity-larger-uniform", "mpm-dem-front", "mpm-gradient-longer-low",
            "mpm-tf-gradient-shorter", "mpm-weak-dependence-high", "restitution-no-difference",
        ],
        texts: &[],
    },
    reads: None,
    cost: None,
    atlas: None,
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_only_shared_energies_and_geo_means_ratios() {
        let p = paired(&[1.0, 2.0, 3.0], &[10.0, 20.0, 30.0], &[3.0, 1.0], &[3.0, 5.0]);
        assert_eq!(p, vec![(1.0, 10.0, 5.0), (3.0, 30.0, 3.0)]);
        assert!((geo_mean(&[2.0, 8.0]) - 4.0).abs() < 1e-12);
        assert!(geo_mean(&[]).is_nan());
    }

    #[test]
    fn ensembles_chain_perturbed_energies_and_keep_lone_ones_apart() {
        let g = ensembles(&[51.94, 12.85, 13.11, 12.98, 52.46, 51.42, 100.0], 0.015);
        assert_eq!(g, vec![(12.85, 13.11), (51.42, 52.46), (100.0, 100.0)]);
        // 1 % apart is one ensemble at 0.015, two at 0.005
        assert_eq!(ensembles(&[10.0, 10.1], 0.005).len(), 2);
    }

    #[test]
    fn moments_give_the_sample_spread_and_none_for_one_member() {
        let (m, sd, lo, hi) = moments(&[1.0, 2.0, 3.0]);
        assert_eq!((m, lo, hi), (2.0, 1.0, 3.0));
        assert!((sd - 1.0).abs() < 1e-12);
        assert!(moments(&[4.0]).1.is_nan());
    }

    #[test]
    fn an_ensemble_comparison_needs_a_width() {
        let p = CompareParams {
            what: What::Ensemble,
            ..CompareParams::default()
        };
        assert!(p.validate().iter().any(|i| format!("{i:?}").contains("ensemble_rel")));
        let p = CompareParams {
            what: What::Ensemble,
            ensemble_rel: 0.015,
            ..CompareParams::default()
        };
        assert!(p.validate().is_empty());
    }
}
