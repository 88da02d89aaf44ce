//! The MPM's column collapse (L(t), H(t), energies, plastic work until it stops): the
//! `mpm` method of the `column-collapse` kind ([`super::collapse`]), which runs the
//! analysis shared with the DEM on the [`ColumnTrace`] this returns.

use serde::{Deserialize, Serialize};

use super::mpm_common::cfl;
use super::mpm_common::points;
use super::mpm_common::{calibrate, check_mpm};
use crate::engines::Method;
use crate::engines::column::{Collapsed, ColumnEngine, ColumnTrace, EnergyCurve, Shared};
use crate::mpm::MpmParams;
use crate::mpm::column::{CollapseOptions, CollapseResult, ColumnSpec};
use crate::mpm::params::StepRule;
use crate::pipeline::context::{Claim, Output, StageCtx, frame};
use crate::stages::Validate;
use crate::stages::kind::Work;
use crate::validate::{Checker, Issue};

/// Parameters of a `column-collapse` stage with `method: mpm`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CollapseParams {
    /// Solver and material.
    pub mpm: MpmParams,
    /// Aspect ratio a = H_0/L_0 (column area of the DEM columns, docs/definitions.md SC-COL).
    pub a: f64,
    /// Column area L_0·H_0 [m²]: the DEM columns' (stages/col-dem-prep.yaml), so DEM and
    /// MPM columns of one profile have the same L_0 and H_0 (docs/definitions.md I11).
    pub area_m2: f64,
    /// Run control (sampling, stop criterion, snapshots).
    pub run: CollapseOptions,
    /// Take φ and E from the DEM calibration inputs when declared.
    pub use_dem_calibration: bool,
    /// Write `.vtp` material-point snapshots (stress, velocity, plastic strain) at
    /// `run.snapshot_tau`.
    pub vtk: bool,
}

impl Default for CollapseParams {
    fn default() -> Self {
        CollapseParams {
            mpm: MpmParams::default(),
            a: 0.4,
            area_m2: crate::mpm::column::DEM_COLUMN_AREA,
            run: CollapseOptions::default(),
            use_dem_calibration: true,
            vtk: false,
        }
    }
}

impl Validate for CollapseParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_mpm(&self.mpm, &mut c);
        c.in_closed("a", self.a, 0.05, 20.0);
        if c.issues.is_empty()
            && self.area_m2 > 0.0
            && let Err(m) = crate::mpm::preflight::containment(
                &self.mpm,
                crate::mpm::column::ColumnSpec::from_area(self.a, self.area_m2),
            )
        {
            c.fail("mpm.wall_friction", self.mpm.wall_friction, &m);
        }
        c.check(
            self.area_m2.is_finite() && self.area_m2 > 1e-6 && self.area_m2 < 10.0,
            "area_m2",
            self.area_m2,
            "in (1e-6, 10) m²",
        );
        c.positive("run.sample_every_tau", self.run.sample_every_tau);
        c.non_negative("run.gate_lift_speed", self.run.gate_lift_speed);
        c.check(
            self.run.max_time_tau > self.run.min_time_tau,
            "run.max_time_tau",
            self.run.max_time_tau,
            "> run.min_time_tau",
        );
        if let Some(rule) = self.run.stop {
            for (k, v, a) in rule.issues() {
                c.fail(&format!("run.stop.{k}"), v, a);
            }
        }
        if let Some(g) = self.run.link_gap {
            c.check(g >= 0.0 && g.is_finite(), "run.link_gap", g, "≥ 0 [d̄]");
        }
        super::front_rules::check(&self.run.front, &mut c);
        c.check(
            self.run.link_gap_sensitivity.iter().all(|g| *g >= 0.0 && g.is_finite()),
            "run.link_gap_sensitivity",
            format!("{:?}", self.run.link_gap_sensitivity),
            "gaps ≥ 0 [d̄]",
        );
        c.positive("run.inertial_cell", self.run.inertial_cell);
        c.issues
    }
}

/// Time series table of a collapse (shared column names with the DEM runs).
pub fn series_table(r: &CollapseResult, g: f64) -> anyhow::Result<polars::prelude::DataFrame> {
    let tau = r.spec.tau_c(g);
    let e0 = r.series.first().map(|s| s.e.potential).unwrap_or(1.0);
    let l0 = r.spec.l0;
    let s = &r.series;
    frame(vec![
        ("t_s", s.iter().map(|v| v.t).collect()),
        ("t_over_tau_c", s.iter().map(|v| v.t / tau).collect()),
        ("l_m", s.iter().map(|v| v.l).collect()),
        ("h_m", s.iter().map(|v| v.h).collect()),
        ("runout_norm", s.iter().map(|v| (v.l - l0) / l0).collect()),
        (
            "runout_gathered_norm",
            s.iter().map(|v| (v.l_gathered - l0) / l0).collect(),
        ),
        ("h_over_l0", s.iter().map(|v| v.h / l0).collect()),
        ("ep_j", s.iter().map(|v| v.e.potential).collect()),
        ("ek_j", s.iter().map(|v| v.e.kinetic).collect()),
        ("ekx_j", s.iter().map(|v| v.e.kinetic_x).collect()),
        ("eky_j", s.iter().map(|v| v.e.kinetic_y).collect()),
        ("elastic_j", s.iter().map(|v| v.e.elastic).collect()),
        ("plastic_work_j", s.iter().map(|v| v.e.plastic_work).collect()),
        ("wall_friction_work_j", s.iter().map(|v| v.e.wall_friction).collect()),
        ("ep_over_e0", s.iter().map(|v| v.e.potential / e0).collect()),
        ("ek_over_e0", s.iter().map(|v| v.e.kinetic / e0).collect()),
        (
            "ed_over_e0",
            s.iter().map(|v| 1.0 - (v.e.kinetic + v.e.potential) / e0).collect(),
        ),
        ("ek_grid_j", s.iter().map(|v| v.e.kinetic_grid).collect()),
        ("i_cg_mean", s.iter().map(|v| v.inertial_cg.mean).collect()),
        ("i_cg_median", s.iter().map(|v| v.inertial_cg.median).collect()),
        ("i_cg_p95", s.iter().map(|v| v.inertial_cg.p95).collect()),
        ("i_cg_max", s.iter().map(|v| v.inertial_cg.max).collect()),
        (
            "i_cg_flowing_fraction",
            s.iter().map(|v| v.inertial_cg.flowing_fraction).collect(),
        ),
        ("i_point_mean", s.iter().map(|v| v.inertial.mean_flowing).collect()),
        ("i_point_median", s.iter().map(|v| v.inertial.median_flowing).collect()),
        (
            "i_point_mean_deep",
            s.iter().map(|v| v.inertial.mean_flowing_deep).collect(),
        ),
        ("i_point_p95", s.iter().map(|v| v.inertial.p95_flowing).collect()),
        (
            "i_point_flowing_fraction",
            s.iter().map(|v| v.inertial.flowing_fraction).collect(),
        ),
        (
            "stress_free_fraction",
            s.iter().map(|v| v.inertial.stress_free_fraction).collect(),
        ),
    ])
}

impl crate::engines::Preflight for CollapseParams {
    fn preflight(&self) -> String {
        super::mpm_common::preflight_mpm(&self.mpm)
    }
}

impl ColumnEngine for CollapseParams {
    fn collapse<'a>(&'a self, ctx: &'a StageCtx, out: &mut Output) -> anyhow::Result<Collapsed<'a>> {
        let mut p = self.clone();
        let note = calibrate(ctx, &mut p.mpm, p.use_dem_calibration)?;
        let spec = ColumnSpec::from_area(p.a, p.area_m2);
        let t_end = p.run.max_time_tau * spec.tau_c(p.mpm.gravity);
        let r = crate::mpm::column::collapse_with_progress(&p.mpm, spec, &p.run, &mut |s, _| {
            ctx.set_progress(s.t / t_end)
        })?;
        let g = p.mpm.gravity;
        let tau = r.spec.tau_c(g);
        if p.vtk {
            for (i, s) in r.snapshots.iter().enumerate() {
                let ids: Vec<f64> = s.id.iter().map(|&v| v as f64).collect();
                let svg_free = crate::vtk::polydata(
                    &s.x,
                    &s.y,
                    &[
                        ("id", crate::vtk::Field::Scalar(&ids)),
                        ("velocity", crate::vtk::Field::Vector(&s.vx, &s.vy)),
                        ("stress", crate::vtk::Field::SymTensor(&s.sxx, &s.syy, &s.sxy)),
                        ("plastic_strain", crate::vtk::Field::Scalar(&s.eps_p)),
                        ("inertial_number", crate::vtk::Field::Scalar(&s.inertial)),
                    ],
                );
                out.files.push((
                    format!("snapshot-{i:02}-t{:.3}tau.vtp", s.t / tau),
                    svg_free.into_bytes(),
                ));
            }
        }
        out.table("table", series_table(&r, g)?);
        out.table(
            "snapshots",
            crate::stages::generic::snapshot::mpm_rows(&r.snapshots, tau, p.mpm.half_width())?,
        );
        let e0 = r.series.first().map(|s| s.e.potential).unwrap_or(1.0);
        out.scalar("points", r.points as f64)
            .scalar("runout_q99_norm", r.runout_q99)
            .scalar(
                "plastic_work_over_e0_end",
                r.series.last().map(|s| s.e.plastic_work / e0).unwrap_or(f64::NAN),
            )
            .scalar("stopped", if r.stopped { 1.0 } else { 0.0 })
            .scalar("steps", r.steps as f64)
            .scalar("friction_angle_deg", p.mpm.material.friction_deg);
        out.note("Run-out: D01 (farthest point linked to the main mass within 1.5 initial spacings) is the chapter's definition; at coarse resolution the 1–2-point-thick toe can detach and cut it suddenly, so runout_q99_norm (x below which 99 % of the mass lies, + l_p) is reported beside it.");
        out.note(format!("{} scheme, h = {} m, {} PPC ({} points), {note}; stopped = {} after {} steps; wall time {:.1} s (P2G {:.1} s, stress {:.1} s, G2P {:.1} s).",
            r.scheme, p.mpm.cell_size, p.mpm.ppc, r.points, r.stopped, r.steps, r.wall_s, r.times.p2g.as_secs_f64(), r.times.update_stress.as_secs_f64(), r.times.g2p.as_secs_f64()));
        let a = r.spec.h0 / r.spec.l0;
        if a <= 2.7 {
            out.claims.push(Claim::rel(
                "runout-eq4.6",
                "(L_f − L_0)/L_0 ≈ 1.67a for a ≲ 2.7 (eq 4.6; MPM follows it, fig 4.5)",
                1.67 * a,
                r.runout,
                0.15,
            ));
        }
        if a <= 0.7 {
            out.claims.push(Claim::rel(
                "height-undisturbed",
                "H_f = H_0 for a ≤ 0.7: H_f/L_0 = a (eq 4.7, fig 4.6)",
                a,
                r.final_front.height / r.spec.l0,
                0.05,
            ));
        }
        let lp = p.mpm.half_width();
        super::front_rules::report_mpm(out, &r, lp, p.mpm.material.grain_diameter, tau, p.run.front)?;
        let at_tau = r
            .snapshots
            .iter()
            .min_by(|a, b| (a.t - tau).abs().total_cmp(&(b.t - tau).abs()))
            .filter(|s| (s.t / tau - 1.0).abs() < 0.05)
            .map(|s| s.cloud(lp));
        // D17 needs each point's start and end x: match them by id.
        let mut x_end = vec![f64::NAN; r.initial.id.len()];
        let pos: std::collections::HashMap<u32, usize> =
            r.initial.id.iter().enumerate().map(|(k, id)| (*id, k)).collect();
        for (k, id) in r.final_state.id.iter().enumerate() {
            if let Some(&i) = pos.get(id) {
                x_end[i] = r.final_state.x[k];
            }
        }
        let series = |f: &dyn Fn(&crate::mpm::column::Sample) -> f64| r.series.iter().map(f).collect::<Vec<f64>>();
        let over_e0 = |label: &str, color: usize, f: &dyn Fn(&crate::mpm::column::Sample) -> f64| EnergyCurve {
            label: label.into(),
            color,
            over_e0: r.series.iter().map(|v| f(v) / e0).collect(),
        };
        let trace = ColumnTrace {
            method: Method::Mpm,
            l0: r.spec.l0,
            h0: r.spec.h0,
            tau,
            d: p.mpm.material.grain_diameter,
            g,
            t: series(&|v| v.t),
            l: series(&|v| v.l),
            l_gathered: series(&|v| v.l_gathered),
            h: series(&|v| v.h),
            ek: series(&|v| v.e.kinetic),
            ep: series(&|v| v.e.potential),
            inertial: r.series.iter().map(|v| v.inertial_cg).collect(),
            gaps: p.run.link_gap_sensitivity.clone(),
            gap_lengths: r.gap_lengths.clone(),
            link_gap: if p.run.link_grid {
                f64::NAN
            } else {
                p.run.link_gap.unwrap_or(f64::NAN)
            },
            at_tau,
            x_start: r.initial.x.clone(),
            x_end,
            mass: r.initial.mass.clone(),
            phi_deg: p.mpm.material.friction_deg,
            mu_grain: f64::NAN,
            at_rest: r.stopped,
            runout_norm: r.runout,
            lf_m: r.final_length,
            hf_m: r.final_front.height,
            energies: vec![
                over_e0("E_p/E_0", 0, &|v| v.e.potential),
                over_e0("E_k/E_0", 1, &|v| v.e.kinetic),
                over_e0("E_kx/E_0", 3, &|v| v.e.kinetic_x),
                over_e0("E_ky/E_0", 4, &|v| v.e.kinetic_y),
                EnergyCurve {
                    label: "E_d/E_0 (eq 4.12)".into(),
                    color: 2,
                    over_e0: r
                        .series
                        .iter()
                        .map(|v| 1.0 - (v.e.kinetic + v.e.potential) / e0)
                        .collect(),
                },
                over_e0("plastic work/E_0", 5, &|v| v.e.plastic_work),
            ],
            footer: format!(
                "h = {} mm, {} PPC, ΔL = {:.3}",
                p.mpm.cell_size * 1e3,
                p.mpm.ppc,
                r.runout
            ),
        };
        let finish = move |out: &mut Output, shared: &Shared| -> anyhow::Result<()> {
            // D08 diagnosis: the point-wise (stress-based) statistic against the coarse-grained one.
            let fl = |f: &dyn Fn(&crate::mpm::column::Sample) -> f64| r.series.iter().map(f).fold(0.0, f64::max);
            let pt_mean = fl(&|v| v.inertial.mean_flowing);
            let pt_median = fl(&|v| v.inertial.median_flowing);
            let pt_deep = fl(&|v| v.inertial.mean_flowing_deep);
            let pt_p95 = fl(&|v| v.inertial.p95_flowing);
            let free = fl(&|v| v.inertial.stress_free_fraction);
            let cg = fl(&|v| v.inertial_cg.mean);
            let pt_all = fl(&|v| v.inertial.mean_flowing * v.inertial.flowing_fraction);
            let cg_all = fl(&|v| v.inertial_cg.mean * v.inertial_cg.flowing_fraction);
            out.scalar("i_point_mean_max", pt_mean)
                .scalar("i_point_median_max", pt_median)
                .scalar("i_point_mean_deep_max", pt_deep)
                .scalar("i_point_p95_max", pt_p95)
                .scalar("stress_free_fraction_max", free)
                .scalar("i_point_mean_all_mass_max", pt_all)
                .scalar("i_max_cap", p.mpm.material.i_max);
            out.note(format!(
                "Inertial number (D08), maxima over time: point-wise I = γ̇ d̄/√(p/ρ_s) from each point's velocity gradient and p = −tr σ/3, mass-weighted over flowing points: mean {pt_mean:.3}, median {pt_median:.4}, mean over points with p ≥ ρ_s g d̄ {pt_deep:.4}, 95th percentile {pt_p95:.3} (cap i_max = {}); coarse-grained (the DEM's measure: {}-d̄ cells, lithostatic p) mean {cg:.4}. Averaged over the whole mass, static points counted as I = 0: point-wise {pt_all:.4}, coarse-grained {cg_all:.4}. Cause of the gap to the chapter's ≤ 0.012: the statistic, not the flow — over the flowing layer alone I ≈ 0.1 (γ̇ ≈ v/h_flow with p of a few grains of overburden), the free-surface points (p → 0, I → i_max) lift the point-wise mean further, and only a whole-mass average (static zone at I = 0) reaches the chapter's order 0.01.",
                p.mpm.material.i_max, p.run.inertial_cell
            ));
            if let Some(rule) = p.run.stop {
                out.note(format!(
                    "Stop rule (shared with the DEM): after {} τ_c, grid E_k < {:.0e} E_0 and L, H moved < {} d̄/τ_c × {} τ_c over the last {} τ_c; upper bound {} τ_c. Front L(t) and run-out: {}. Main mass (H(t), H_f): {}.",
                    rule.t_min, rule.ke_ratio, rule.front_speed, rule.window, rule.window, rule.t_max,
                    match p.run.front_rule {
                        crate::analysis::gathered_front::FrontRule::Gathered => "the gathered length over every point (bins of one d̄, each counted by its covered length × min(1, thickness/d̄); docs/definitions.md D01), the rule the DEM columns also publish as runout_gathered_norm",
                        crate::analysis::gathered_front::FrontRule::Links => "the right edge of the main mass",
                    },
                    if p.run.link_grid { "points linked when they share a background-grid node (uGIMP support h + l_p: the MPM's interaction, as contact is the DEM's; the edge-gap sensitivity table is kept)".to_string() } else { format!("points (half-size l_p) linked when their edges are within {} d̄ (the DEM's D01 rule)", p.run.link_gap.map(|g| g.to_string()).unwrap_or_else(|| "1.5 spacings (centre distance)".into())) }
                ));
            }
            out.claims.push(Claim::abs("comes-to-rest", "\"the granular mass comes to rest at about t = 3τ_c\" (MPM, a = 0.4): t_f/τ_c, front within 0.5 d̄ of L_f (D10)", 3.0, shared.t_f / tau, 1.0));
            Ok(())
        };
        Ok(Collapsed {
            trace,
            finish: Box::new(finish),
        })
    }
}

/// Cost: the column's points, steps per simulated second (fixed Δt, or CFL capped by
/// `dt_max`).
pub(super) fn cost(p: &CollapseParams) -> Option<Work> {
    let (m, h) = (&p.mpm, p.mpm.cell_size);
    let rate = match m.step {
        StepRule::Fixed { dt } => 1.0 / dt,
        StepRule::Cfl { courant, dt_max } => cfl(m, courant, h).max(1.0 / dt_max),
    };
    Some((
        vec![("points", points(p.area_m2, m.ppc as f64, h)), ("steps", rate)],
        false,
    ))
}
