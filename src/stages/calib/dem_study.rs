//! The rolling model's part in the DEM calibration (issue 24, item 2): an on-demand study
//! over the rolling model, its dashpot and μ_r. Each setting is a matrix of
//! `dem-calibration-point` stages ([`super::dem_calibration`]: the shear test's φ_cs and the
//! ensemble run-outs at a = 0.4 and a ≈ 6); this stage gathers them, states the dashpot of
//! each setting as a ratio to the critical one, and finds, per setting, the two μ_r windows:
//! φ_cs within the friction-angle target, and both ensemble-mean run-outs within ±tol of
//! eq 4.6. Between grid points φ_cs and the run-outs are interpolated linearly; a window is
//! the set of sampled μ_r where the interpolants meet the target, so it is only as fine as
//! the grid, and the run-out window ignores the ensemble spread (the table gives it).
//!
//! Tables (drawn by a `plot` stage, the study's figure):
//! - `table`: one row per grid point, with its setting's index;
//! - `windows`: the sampled μ_r inside each window (`target` 0: friction angle, 1: run-out,
//!   2: both), at the height `level` = setting + offset, so a plot draws them as bars;
//! - `settings`: per setting, its dashpot, the windows' extents and whether they overlap;
//! - `bands`: the two targets' bands across the grid's μ_r span.

use serde::{Deserialize, Serialize};

use super::dem_calibration::{PointParams, eq46};
use crate::dem::RollingModel;
use crate::pipeline::context::{InputRef, Output, StageCtx, col_f64, frame};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Parameters of a `dem-calibration-study` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StudyParams {
    /// Target friction angle [°] (the chapter's 22.2°).
    pub friction_angle_deg: f64,
    /// Allowed |φ − target| [°].
    pub friction_tolerance_deg: f64,
    /// Allowed relative deviation of the ensemble-mean run-outs from eq 4.6.
    pub runout_tolerance: f64,
    /// μ_r samples per unit of μ_r at which the windows are evaluated.
    pub samples_per_unit: usize,
}

impl Default for StudyParams {
    fn default() -> Self {
        StudyParams {
            friction_angle_deg: 22.2,
            friction_tolerance_deg: 1.0,
            runout_tolerance: 0.15,
            samples_per_unit: 400,
        }
    }
}

impl Validate for StudyParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.check(
            self.friction_angle_deg.is_finite() && self.friction_angle_deg > 0.0 && self.friction_angle_deg < 60.0,
            "friction_angle_deg",
            self.friction_angle_deg,
            "in (0, 60)°",
        );
        c.positive("friction_tolerance_deg", self.friction_tolerance_deg);
        c.in_open("runout_tolerance", self.runout_tolerance, 0.0, 1.0);
        c.check(
            (10..=100_000).contains(&self.samples_per_unit),
            "samples_per_unit",
            self.samples_per_unit,
            "an integer in [10, 100000]",
        );
        c.issues
    }
}

/// One grid point of the study.
#[derive(Debug, Clone)]
pub struct StudyPoint {
    /// μ_r.
    pub mu_r: f64,
    /// Capped model (else EPSD).
    pub capped: bool,
    /// Rolling dashpot c_r the point ran with (softening does not scale it) [N·m·s/rad].
    pub cr: f64,
    /// φ_cs [°].
    pub phi: f64,
    /// (a, mean, s.d.) of the run-outs, by a.
    pub runouts: Vec<(f64, f64, f64)>,
}

/// c_r = 2√(k_r I_eff) of the mean grain pair, I_eff = Ī/2, Ī the mean of ½ρπr⁴ over
/// `radii` (per unit thickness) [N·m·s/rad]: the rolling dashpot of critical damping.
pub fn critical_cr(radii: &[f64], density: f64, kr: f64) -> f64 {
    let n = radii.len().max(1) as f64;
    let i_mean = radii
        .iter()
        .map(|r| 0.5 * density * std::f64::consts::PI * r.powi(4))
        .sum::<f64>()
        / n;
    2.0 * (kr * 0.5 * i_mean).sqrt()
}

/// Linear interpolation of sorted (x, y) at `x` (None outside the span).
fn interp(pts: &[(f64, f64)], x: f64) -> Option<f64> {
    let first = pts.first()?;
    if pts.len() == 1 {
        return (x == first.0).then_some(first.1);
    }
    pts.windows(2).find(|w| x >= w[0].0 && x <= w[1].0).map(|w| {
        let t = if w[1].0 > w[0].0 {
            (x - w[0].0) / (w[1].0 - w[0].0)
        } else {
            0.0
        };
        w[0].1 + t * (w[1].1 - w[0].1)
    })
}

/// The windows of one setting, sampled: (μ_r, in friction window, in run-out window).
pub fn windows(pts: &[StudyPoint], p: &StudyParams) -> Vec<(f64, bool, bool)> {
    let mut by_mu: Vec<&StudyPoint> = pts.iter().collect();
    by_mu.sort_by(|a, b| a.mu_r.total_cmp(&b.mu_r));
    let phi: Vec<(f64, f64)> = by_mu.iter().map(|q| (q.mu_r, q.phi)).collect();
    let a_list: Vec<f64> = by_mu
        .first()
        .map(|q| q.runouts.iter().map(|r| r.0).collect())
        .unwrap_or_default();
    let ratio: Vec<Vec<(f64, f64)>> = a_list
        .iter()
        .map(|&a| {
            by_mu
                .iter()
                .filter_map(|q| q.runouts.iter().find(|r| r.0 == a).map(|r| (q.mu_r, r.1 / eq46(a))))
                .collect()
        })
        .collect();
    let (lo, hi) = match (phi.first(), phi.last()) {
        (Some(l), Some(h)) => (l.0, h.0),
        _ => return vec![],
    };
    let n = (((hi - lo) * p.samples_per_unit as f64).round() as usize).max(1);
    (0..=n)
        .map(|k| {
            let x = lo + (hi - lo) * k as f64 / n as f64;
            let f = interp(&phi, x).is_some_and(|v| (v - p.friction_angle_deg).abs() <= p.friction_tolerance_deg);
            let r = !ratio.is_empty()
                && ratio
                    .iter()
                    .all(|c| interp(c, x).is_some_and(|v| (v - 1.0).abs() <= p.runout_tolerance));
            (x, f, r)
        })
        .collect()
}

/// Extent (first, last sampled μ_r) and the number of disjoint pieces of a window.
fn extent(samples: &[(f64, bool)]) -> (f64, f64, usize) {
    let inside: Vec<f64> = samples.iter().filter(|s| s.1).map(|s| s.0).collect();
    let pieces =
        samples.windows(2).filter(|w| w[1].1 && !w[0].1).count() + usize::from(samples.first().is_some_and(|s| s.1));
    match (inside.first(), inside.last()) {
        (Some(&a), Some(&b)) => (a, b, pieces),
        _ => (f64::NAN, f64::NAN, 0),
    }
}

/// A grid point: its setting from its typed params, its measurements from its scalars.
/// Returns the point and the critical c_r of its (softened) spring and density.
fn read_point(input: &InputRef, radii: &[f64]) -> anyhow::Result<(StudyPoint, f64)> {
    let pp: PointParams = serde_json::from_value(input.params.clone())
        .map_err(|e| anyhow::anyhow!("input `{}` is not a dem-calibration-point: {e}", input.id))?;
    let sc = input.scalars()?;
    let get = |k: &str| {
        sc.get(k)
            .copied()
            .ok_or_else(|| anyhow::anyhow!("input `{}` has no scalar `{k}`", input.id))
    };
    let mut runouts = Vec::new();
    for (k, &m) in sc.iter().filter(|(k, _)| k.starts_with("runout_mean_a")) {
        let key = &k["runout_mean_a".len()..];
        runouts.push((key.parse::<f64>()?, m, get(&format!("runout_std_a{key}"))?));
    }
    runouts.sort_by(|x, y| x.0.total_cmp(&y.0));
    let rolling = &pp.dem.rolling;
    let point = StudyPoint {
        mu_r: pp.mu_r,
        capped: pp.model == RollingModel::Capped,
        cr: if rolling.enabled { rolling.cr } else { 0.0 },
        phi: get("friction_angle_deg")?,
        runouts,
    };
    Ok((
        point,
        critical_cr(radii, pp.dem.density, rolling.kr * pp.stiffness_factor),
    ))
}

fn run_study(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: StudyParams = decode(ctx)?;
    let radii: Vec<f64> = col_f64(&ctx.input("psd")?.table("table")?, "d_m")?
        .iter()
        .map(|d| 0.5 * d)
        .collect();
    let inputs = ctx.inputs_of("points");
    anyhow::ensure!(
        !inputs.is_empty(),
        "stage `{}` needs `points` inputs (dem-calibration-point stages)",
        ctx.id
    );
    // Settings in the order their first point is declared: (capped, c_r) → points.
    // μ_r = 0 is no rolling resistance in every model (the cap is zero, so neither spring
    // nor dashpot acts): such a point joins every setting that lacks its own.
    let mut settings: Vec<((bool, f64), Vec<StudyPoint>)> = Vec::new();
    let mut shared: Vec<StudyPoint> = Vec::new();
    let mut crit = Vec::new();
    for input in inputs {
        let (q, c) = read_point(input, &radii)?;
        crit.push(c);
        if q.mu_r == 0.0 {
            shared.push(q);
            continue;
        }
        match settings.iter_mut().find(|s| s.0 == (q.capped, q.cr)) {
            Some(s) => s.1.push(q),
            None => settings.push(((q.capped, q.cr), vec![q])),
        }
    }
    if settings.is_empty() {
        settings.extend(shared.drain(..).map(|q| ((q.capped, q.cr), vec![q])));
    }
    for (_, pts) in settings.iter_mut() {
        if !pts.iter().any(|q| q.mu_r == 0.0)
            && let Some(z) = shared.first()
        {
            pts.push(z.clone());
        }
    }
    let cr_crit = crit[0];
    anyhow::ensure!(
        crit.iter().all(|c| (c / cr_crit - 1.0).abs() < 1e-9),
        "stage `{}`: the points differ in k_r, density or softening, so no one critical c_r describes them",
        ctx.id
    );
    let a_list: Vec<f64> = settings[0].1[0].runouts.iter().map(|r| r.0).collect();
    let mut out = Output::default();
    // table: one row per point
    let mut rows: Vec<(String, Vec<f64>)> = [
        "setting", "mu_r", "model_capped", "rolling_cr", "cr_over_critical", "friction_angle_deg",
    ]
    .iter()
    .map(|n| (n.to_string(), vec![]))
    .collect();
    // Run-out columns named by regime (short: a ≤ 2.7, tall: above, as eq 4.6's branches),
    // not by a: the prepared column's a (5.8 at quick size, 5.9 at paper size) must not
    // change the names a plot reads.
    let regime = |a: f64| if a <= 2.7 { "short" } else { "tall" };
    let mut run_cols: Vec<(String, Vec<f64>)> = Vec::new();
    for &a in &a_list {
        for n in [
            "a", "runout_mean", "runout_std", "runout_over_eq46", "runout_std_over_eq46",
        ] {
            run_cols.push((format!("{n}_{}", regime(a)), vec![]));
        }
    }
    let (mut w_set, mut w_target, mut w_mu, mut w_level) = (vec![], vec![], vec![], vec![]);
    let mut s_cols: Vec<(&str, Vec<f64>)> = [
        "setting", "model_capped", "rolling_cr", "cr_over_critical", "points", "friction_lo", "friction_hi",
        "friction_pieces", "runout_lo", "runout_hi", "runout_pieces", "overlap_lo", "overlap_hi",
    ]
    .into_iter()
    .map(|n| (n, vec![]))
    .collect();
    let mut overlapping = 0usize;
    let mut lines = Vec::new();
    for (k, ((capped, cr), pts)) in settings.iter_mut().enumerate() {
        pts.sort_by(|a, b| a.mu_r.total_cmp(&b.mu_r));
        let kf = k as f64;
        for q in pts.iter() {
            for (v, x) in rows
                .iter_mut()
                .zip([kf, q.mu_r, f64::from(u8::from(*capped)), *cr, *cr / cr_crit, q.phi])
            {
                v.1.push(x);
            }
            let mut c = run_cols.iter_mut();
            for &a in &a_list {
                let r = q
                    .runouts
                    .iter()
                    .find(|r| r.0 == a)
                    .copied()
                    .unwrap_or((a, f64::NAN, f64::NAN));
                for v in [a, r.1, r.2, r.1 / eq46(a), r.2 / eq46(a)] {
                    c.next().expect("column").1.push(v);
                }
            }
        }
        let w = windows(pts, &p);
        for &(x, f, r) in &w {
            for (hit, t, off) in [(f, 0.0, 0.15), (r, 1.0, -0.15), (f && r, 2.0, 0.0)] {
                if hit {
                    w_set.push(kf);
                    w_target.push(t);
                    w_mu.push(x);
                    w_level.push(kf + off);
                }
            }
        }
        let ef = extent(&w.iter().map(|s| (s.0, s.1)).collect::<Vec<_>>());
        let er = extent(&w.iter().map(|s| (s.0, s.2)).collect::<Vec<_>>());
        let eb = extent(&w.iter().map(|s| (s.0, s.1 && s.2)).collect::<Vec<_>>());
        if eb.2 > 0 {
            overlapping += 1;
        }
        for (col, v) in s_cols.iter_mut().zip([
            kf,
            f64::from(u8::from(*capped)),
            *cr,
            *cr / cr_crit,
            pts.len() as f64,
            ef.0,
            ef.1,
            ef.2 as f64,
            er.0,
            er.1,
            er.2 as f64,
            eb.0,
            eb.1,
        ]) {
            col.1.push(v);
        }
        let show = |e: (f64, f64, usize)| {
            if e.2 == 0 {
                "empty".to_string()
            } else {
                format!("{:.3}–{:.3}{}", e.0, e.1, if e.2 > 1 { " (not connected)" } else { "" })
            }
        };
        lines.push(format!(
            "setting {k}: {} model, c_r = {cr:.3e} N·m·s/rad ({:.3} × critical), μ_r ∈ [{}, {}]: friction window {}, run-out window {}, both {}",
            if *capped { "capped" } else { "EPSD" },
            *cr / cr_crit,
            pts.first().map(|q| q.mu_r).unwrap_or(f64::NAN),
            pts.last().map(|q| q.mu_r).unwrap_or(f64::NAN),
            show(ef),
            show(er),
            show(eb)
        ));
    }
    rows.extend(run_cols);
    out.table(
        "table",
        frame(rows.iter().map(|(n, v)| (n.as_str(), v.clone())).collect())?,
    );
    out.table(
        "windows",
        frame(vec![
            ("setting", w_set),
            ("target", w_target),
            ("mu_r", w_mu),
            ("level", w_level),
        ])?,
    );
    out.table("settings", frame(s_cols)?);
    let (lo, hi) = settings
        .iter()
        .flat_map(|s| s.1.iter().map(|q| q.mu_r))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| (l.min(x), h.max(x)));
    out.table(
        "bands",
        frame(vec![
            ("mu_r", vec![lo, hi]),
            ("phi_lo", vec![p.friction_angle_deg - p.friction_tolerance_deg; 2]),
            ("phi_hi", vec![p.friction_angle_deg + p.friction_tolerance_deg; 2]),
            ("runout_lo", vec![1.0 - p.runout_tolerance; 2]),
            ("runout_hi", vec![1.0 + p.runout_tolerance; 2]),
        ])?,
    );
    out.scalar("settings", settings.len() as f64)
        .scalar("grid_points", inputs.len() as f64)
        .scalar("critical_cr", cr_crit)
        .scalar("settings_with_overlap", overlapping as f64);
    let verdict = if overlapping == 0 {
        "the two μ_r windows do not overlap in any setting".to_string()
    } else {
        format!(
            "the two μ_r windows overlap in {overlapping} of {} settings",
            settings.len()
        )
    };
    out.text("verdict", verdict.clone());
    out.note(format!(
        "{verdict} (φ_cs = {} ± {}°; run-outs at a = {} within ±{:.0} % of eq 4.6, ensemble means; windows interpolated linearly between grid points). Critical rolling dashpot of the mean grain pair: c_r = {cr_crit:.3e} N·m·s/rad.",
        p.friction_angle_deg,
        p.friction_tolerance_deg,
        a_list.iter().map(|a| format!("{a}")).collect::<Vec<_>>().join(" and "),
        100.0 * p.runout_tolerance
    ));
    for l in lines {
        out.note(l);
    }
    Ok(out)
}

/// Kind `dem-calibration-study`.
pub const STUDY_KIND: Kind = Kind {
    name: "dem-calibration-study",
    source: file!(),
    method: Some(crate::engines::Method::Dem),
    version: 1,
    about: "the rolling model's part in the DEM calibration: gathers dem-calibration-point settings (model, dashpot, μ_r), states each dashpot against the critical one, and finds per setting the μ_r windows of the friction angle and of the eq 4.6 run-outs, and whether they overlap",
    params: typed::<StudyParams>,
    run: run_study,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[
        ("points", crate::pipeline::context::Arity::Many),
        ("psd", crate::pipeline::context::Arity::One),
    ]),
    outputs: crate::stages::kind::Outputs {
        scalars: &["critical_cr", "grid_points", "settings", "settings_with_overlap"],
        tables: &[
            crate::stages::kind::TableDecl {
                name: "table",
                columns: &[
                    "a_short", "a_tall", "cr_over_critical", "friction_angle_deg", "model_capped", "mu_r",
                    "rolling_cr", "runout_mean_short", "runout_mean_tall", "runout_over_eq46_short",
                    "runout_over_eq46_tall", "runout_std_over_eq46_short", "runout_std_over_eq46_tall",
                    "runout_std_short", "runout_std_tall", "setting",
                ],
            },
            crate::stages::kind::TableDecl {
                name: "windows",
                columns: &["level", "mu_r", "setting", "target"],
            },
            crate::stages::kind::TableDecl {
                name: "settings",
                columns: &[
                    "cr_over_critical", "friction_hi", "friction_lo", "friction_pieces", "model_capped", "overlap_hi",
                    "overlap_lo", "points", "rolling_cr", "runout_hi", "runout_lo", "runout_pieces", "setting",
                ],
            },
            crate::stages::kind::TableDecl {
                name: "bands",
                columns: &["mu_r", "phi_hi", "phi_lo", "runout_hi", "runout_lo"],
            },
        ],
        measurements: &[],
        texts: &["verdict"],
    },
    reads: None,
    cost: None,
    atlas: None,
};

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(mu_r: f64, phi: f64, r04: f64, r6: f64) -> StudyPoint {
        StudyPoint {
            mu_r,
            capped: false,
            cr: 0.1,
            phi,
            runouts: vec![(0.4, r04 * eq46(0.4), 0.01), (5.8, r6 * eq46(5.8), 0.1)],
        }
    }

    /// Windows from a grid where φ rises through 22.2° between μ_r = 0.2 and 0.3 and the
    /// run-outs fall through ±15 % of eq 4.6 between 0.1 and 0.2: disjoint, and where the
    /// interpolants put them.
    #[test]
    fn windows_follow_the_interpolants_and_can_be_apart() {
        let g = vec![
            pt(0.0, 15.0, 1.5, 1.4),
            pt(0.1, 18.0, 1.1, 1.05),
            pt(0.2, 20.0, 0.8, 0.9),
            pt(0.3, 23.0, 0.6, 0.7),
        ];
        let p = StudyParams::default();
        let w = windows(&g, &p);
        let f = extent(&w.iter().map(|s| (s.0, s.1)).collect::<Vec<_>>());
        let r = extent(&w.iter().map(|s| (s.0, s.2)).collect::<Vec<_>>());
        // φ = 21.2 at μ_r = 0.2 + 0.1 × 1.2/3 = 0.24; up to 0.3 (23.0 ≤ 23.2)
        assert!(
            (f.0 - 0.24).abs() < 0.003 && (f.1 - 0.3).abs() < 1e-12 && f.2 == 1,
            "{f:?}"
        );
        // a = 0.4: 1.5 → 1.1 crosses 1.15 at 0.0875, 1.1 → 0.8 crosses 0.85 at 0.1833;
        // a = 5.8: inside from 0.0714 to 0.225; both columns: 0.0875–0.1833
        assert!((r.0 - 0.0875).abs() < 0.003 && (r.1 - 0.1833).abs() < 0.003, "{r:?}");
        assert!(w.iter().all(|s| !(s.1 && s.2)), "windows apart");
    }

    #[test]
    fn a_point_inside_both_targets_makes_an_overlap() {
        let g = vec![pt(0.1, 21.5, 1.0, 1.0), pt(0.2, 23.5, 0.7, 0.8)];
        let w = windows(&g, &StudyParams::default());
        assert!(w.first().is_some_and(|s| s.1 && s.2));
    }

    /// The relative rotation of two equal disks under the rolling spring and dashpot obeys
    /// I_eff θ̈ = −k_r θ − c_r θ̇: with the critical c_r it returns to rest without crossing
    /// zero, with 0.8 of it it overshoots.
    #[test]
    fn the_critical_dashpot_is_the_one_that_just_stops_overshoot() {
        let r: f64 = 5.75e-4;
        let (rho, kr) = (2500.0, 10.0);
        let i_eff = 0.25 * rho * std::f64::consts::PI * r.powi(4);
        let c = critical_cr(&[r, r], rho, kr);
        let min_theta = |c: f64| {
            let w0 = (kr / i_eff).sqrt();
            let h = 1e-3 / w0;
            let (mut th, mut om, mut lo) = (1.0_f64, 0.0_f64, 1.0_f64);
            for _ in 0..200_000 {
                om += h * (-kr * th - c * om) / i_eff;
                th += h * om;
                lo = lo.min(th);
            }
            lo
        };
        assert!(min_theta(c) > -1e-3, "critical: {}", min_theta(c));
        assert!(min_theta(0.8 * c) < -1e-3, "under-critical: {}", min_theta(0.8 * c));
    }
}
