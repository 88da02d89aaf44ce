//! MPM stage kinds: `mpm-geostatic` (fig4-04), `mpm-collapse` (column collapse time
//! series) and `mpm-work-precision` (run-out error against wall time over PPC × cell size
//! × Courant number).
//!
//! Multi-scale link: when a stage declares the inputs `shear` (DEM periodic shear test,
//! scalar `friction_angle_deg`) and/or `compression` (DEM confined compression, scalar
//! `youngs_modulus_pa`), those measured values replace table 4.3's φ and E — so a change
//! to a DEM parameter re-runs these stages through the DAG. `use_dem_calibration: false`
//! keeps the table values for comparison.

use serde::{Deserialize, Serialize};

use super::wp_summary::ensemble_error;
use super::{Kind, Validate, decode, typed};
use crate::mpm::column::{CollapseOptions, CollapseResult, ColumnSpec, collapse, fig4_04};
use crate::mpm::{Model, MpmParams, StepRule};
use crate::pipeline::context::{Claim, Output, StageCtx, frame};
use crate::report::plot::{Chart, Series, Style, footer};
use crate::report::snapshot::{Field, Segment, Shape, Snapshot};
use crate::validate::{Checker, Issue};

/// Inject the DEM-calibrated friction angle and modulus; returns a note for the report.
fn calibrate(ctx: &StageCtx, p: &mut MpmParams, enabled: bool) -> anyhow::Result<String> {
    if !enabled {
        return Ok(format!(
            "table 4.3 values: φ = {}°, E = {:.3e} Pa (DEM calibration disabled)",
            p.material.friction_deg, p.material.young_pa
        ));
    }
    let mut parts = Vec::new();
    if let Some(s) = ctx.input_opt("shear") {
        p.material.friction_deg = s.scalar("friction_angle_deg")?;
        parts.push(format!("φ = {:.2}° from `{}`", p.material.friction_deg, s.id));
        // μ(I)'s quasi-static friction is the same measured φ (docs/definitions.md I6: the
        // chapter's μ_min is tan of its critical-state angle), so μ(I) and Mohr–Coulomb
        // differ only by the rate term — the comparison of figs 4.14–4.15.
        let mu = p.material.friction_deg.to_radians().tan();
        match &mut p.material.model {
            Model::MuILinear { mu_min, .. } => {
                *mu_min = mu;
                parts.push(format!("μ_min = tan φ = {mu:.4}"));
            }
            Model::MuIJop { mu_s, mu_2, .. } => {
                let spread = *mu_2 - *mu_s;
                *mu_s = mu;
                *mu_2 = mu + spread;
                parts.push(format!("μ_s = tan φ = {mu:.4}"));
            }
            _ => {}
        }
    } else {
        parts.push(format!("φ = {}° (table 4.3)", p.material.friction_deg));
    }
    if let Some(c) = ctx.input_opt("compression") {
        p.material.young_pa = c.scalar("youngs_modulus_pa")?;
        parts.push(format!("E = {:.3e} Pa from `{}`", p.material.young_pa, c.id));
    } else {
        parts.push(format!("E = {:.3e} Pa (table 4.3)", p.material.young_pa));
    }
    Ok(parts.join(", "))
}

/// Largest speed the validation-time pre-flight expects: √(2 g H_0) of the tallest
/// column (a = 10, H_0 ≈ 0.197 m), docs/definitions.md c.3.
const PREFLIGHT_V_MAX: f64 = 1.97;

fn check_mpm(p: &MpmParams, c: &mut Checker) {
    for i in p.validate() {
        c.fail(&format!("mpm.{}", i.key), i.value, &i.allowed);
    }
    if !c.issues.is_empty() {
        return;
    }
    let dt = crate::mpm::preflight::planned_dt(p, PREFLIGHT_V_MAX);
    if let Err(e) = crate::mpm::preflight::preflight(p, dt, PREFLIGHT_V_MAX) {
        c.fail(
            "mpm.step",
            format!("{dt:.3e} s"),
            &format!("a stable step — {e}. `granrepro run --explain` prints the CFL table"),
        );
    }
}

/// `--explain`: the CFL pre-flight table of an MPM stage.
fn explain_mpm(v: &serde_json::Value) -> String {
    let p: MpmParams = v
        .get("mpm")
        .cloned()
        .and_then(|d| serde_json::from_value(d).ok())
        .unwrap_or_default();
    let dt = crate::mpm::preflight::planned_dt(&p, PREFLIGHT_V_MAX);
    match crate::mpm::preflight::preflight(&p, dt, PREFLIGHT_V_MAX) {
        Ok(r) => format!("{r}"),
        Err(e) => format!("refused: {e}"),
    }
}

/// Parameters of an `mpm-geostatic` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GeostaticParams {
    /// Solver and material (table 4.3 by default).
    pub mpm: MpmParams,
    /// Take φ and E from the DEM calibration inputs when declared.
    pub use_dem_calibration: bool,
    /// Cells shown in the zoomed mesh view (fig4-04a).
    pub zoom_cells: usize,
    /// Allowed relative error of the base stress (claim `geostatic-stress`).
    pub tolerance: f64,
}

impl Default for GeostaticParams {
    fn default() -> Self {
        GeostaticParams {
            mpm: MpmParams::default(),
            use_dem_calibration: true,
            zoom_cells: 4,
            tolerance: 0.02,
        }
    }
}

impl Validate for GeostaticParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_mpm(&self.mpm, &mut c);
        c.check(
            self.zoom_cells >= 1 && self.zoom_cells <= 100,
            "zoom_cells",
            self.zoom_cells,
            "an integer in [1, 100]",
        );
        c.in_open("tolerance", self.tolerance, 0.0, 1.0);
        c.issues
    }
}

fn run_geostatic(ctx: &StageCtx) -> anyhow::Result<Output> {
    let mut p: GeostaticParams = decode(ctx)?;
    let note = calibrate(ctx, &mut p.mpm, p.use_dem_calibration)?;
    let g = fig4_04(&p.mpm)?;
    let mut out = Output::default();
    out.note(format!("a = 1 column, {} material points, h = {} m, {} PPC; {note}; geostatic stage: gravity loading with local damping {} until E_k/E_p < {:.0e} ({} steps, {:.4} s simulated), gate as a roller.",
        g.x.len(), p.mpm.cell_size, p.mpm.ppc, p.mpm.geostatic.damping, p.mpm.geostatic.ke_tol, g.report.steps, g.report.time));
    out.table(
        "table",
        frame(vec![
            ("x_m", g.x.clone()),
            ("y_m", g.y.clone()),
            ("sigma_yy_pa", g.sigma_yy.clone()),
            ("sigma_xx_pa", g.sigma_xx.clone()),
        ])?,
    );
    // σ_yy profile along the centre line vs the analytic −ρg(H_0 − y).
    let s = p.mpm.spacing();
    let xc = g.spec.l0 / 2.0;
    let mut prof: Vec<(f64, f64)> =
        g.x.iter()
            .zip(&g.y)
            .zip(&g.sigma_yy)
            .filter(|((x, _), _)| (**x - xc).abs() <= s)
            .map(|((_, y), syy)| (*y, *syy))
            .collect();
    prof.sort_by(|a, b| a.0.total_cmp(&b.0));
    let rho_g = p.mpm.material.density * p.mpm.gravity;
    out.table(
        "profile",
        frame(vec![
            ("y_m", prof.iter().map(|v| v.0).collect()),
            ("sigma_yy_pa", prof.iter().map(|v| v.1).collect()),
            (
                "sigma_yy_analytic_pa",
                prof.iter().map(|v| -rho_g * (g.spec.h0 - v.0)).collect(),
            ),
        ])?,
    );
    out.scalar("l0_m", g.spec.l0)
        .scalar("h0_m", g.spec.h0)
        .scalar("points", g.x.len() as f64)
        .scalar("base_sigma_yy_pa", g.base_sigma_yy)
        .scalar("base_sigma_yy_analytic_pa", g.base_sigma_yy_analytic)
        .scalar("base_relative_error", g.base_error)
        .scalar("rho_g_h0_pa", rho_g * g.spec.h0)
        .scalar("friction_angle_deg", p.mpm.material.friction_deg)
        .scalar("youngs_modulus_pa", p.mpm.material.young_pa)
        .scalar("geostatic_steps", g.report.steps as f64);
    out.checks.push(Claim::rel(
        "geostatic-stress",
        "σ_yy at the base = −ρg(H_0 − y) (fig4-04b; max ≈ ρgH_0 = 1.18 kPa for H_0 = 62.4 mm)",
        g.base_sigma_yy_analytic,
        g.base_sigma_yy,
        p.tolerance,
    ));
    let smin = g.sigma_yy.iter().cloned().fold(f64::INFINITY, f64::min);
    let half = vec![g.half_width; g.x.len()];
    let walls = vec![
        Segment {
            a: (0.0, 0.0),
            b: (0.0, g.spec.h0 * 1.1),
            color: "black",
            width: 2.5,
            dashed: false,
        },
        Segment {
            a: (0.0, 0.0),
            b: (g.spec.l0 * 1.15, 0.0),
            color: "black",
            width: 2.5,
            dashed: false,
        },
        Segment {
            a: (g.spec.l0, 0.0),
            b: (g.spec.l0, g.spec.h0 * 1.1),
            color: "#666",
            width: 1.5,
            dashed: true,
        },
    ];
    let snap = Snapshot {
        title: ctx.caption.clone().unwrap_or_else(|| "Initial vertical stress".into()),
        footer: footer(
            &ctx.profile,
            &format!(
                "base σ_yy {:.1} Pa vs −ρg(H_0−y) {:.1} Pa ({:.2} %)",
                g.base_sigma_yy,
                g.base_sigma_yy_analytic,
                100.0 * g.base_error
            ),
        ),
        x: &g.x,
        y: &g.y,
        half: &half,
        shape: Shape::Square,
        field: Some(Field {
            values: &g.sigma_yy,
            label: "σ_yy [Pa] (compression negative)".into(),
            range: (smin, 0.0),
        }),
        black: None,
        fill: None,
        segments: walls.clone(),
        view: None,
        width_px: 520.0,
    };
    out.figure("figure", snap.to_svg());
    // fig4-04a: corner zoom with the mesh.
    let h = p.mpm.cell_size;
    let z = p.zoom_cells as f64 * h;
    let mut segs = Vec::new();
    for k in 0..=p.zoom_cells {
        let v = k as f64 * h;
        segs.push(Segment {
            a: (v, 0.0),
            b: (v, z),
            color: "#999",
            width: 1.0,
            dashed: false,
        });
        segs.push(Segment {
            a: (0.0, v),
            b: (z, v),
            color: "#999",
            width: 1.0,
            dashed: false,
        });
    }
    segs.extend(walls);
    let dots = vec![g.half_width * 0.25; g.x.len()];
    let mesh = Snapshot {
        title: format!(
            "Material points in the mesh: {} per cell, cell size {} m (corner of the a = 1 column)",
            p.mpm.ppc, h
        ),
        footer: footer(&ctx.profile, ""),
        x: &g.x,
        y: &g.y,
        half: &dots,
        shape: Shape::Disk,
        field: None,
        black: None,
        fill: None,
        segments: segs,
        view: Some((-0.1 * h, z + 0.1 * h, -0.1 * h, z + 0.1 * h)),
        width_px: 420.0,
    };
    out.figure("mesh", mesh.to_svg());
    Ok(out)
}

/// Kind `mpm-geostatic`.
pub const GEOSTATIC_KIND: Kind = Kind {
    name: "mpm-geostatic",
    version: 2,
    about: "fig4-04: MPM a = 1 column, material points in the mesh and geostatic vertical stress",
    params: typed::<GeostaticParams>,
    run: run_geostatic,
    explain: Some(explain_mpm),
};

/// Parameters of an `mpm-collapse` stage.
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
        if c.issues.is_empty() && self.area_m2 > 0.0 {
            if let Err(m) = crate::mpm::preflight::containment(
                &self.mpm,
                crate::mpm::column::ColumnSpec::from_area(self.a, self.area_m2),
            ) {
                c.fail("mpm.wall_friction", self.mpm.wall_friction, &m);
            }
        }
        c.check(
            self.area_m2.is_finite() && self.area_m2 > 1e-6 && self.area_m2 < 10.0,
            "area_m2",
            self.area_m2,
            "in (1e-6, 10) m²",
        );
        c.positive("run.sample_every_tau", self.run.sample_every_tau);
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

fn run_collapse_stage(ctx: &StageCtx) -> anyhow::Result<Output> {
    let mut p: CollapseParams = decode(ctx)?;
    let note = calibrate(ctx, &mut p.mpm, p.use_dem_calibration)?;
    let spec = ColumnSpec::from_area(p.a, p.area_m2);
    let t_end = p.run.max_time_tau * spec.tau_c(p.mpm.gravity);
    let r =
        crate::mpm::column::collapse_with_progress(&p.mpm, spec, &p.run, &mut |s, _| ctx.set_progress(s.t / t_end))?;
    let g = p.mpm.gravity;
    let tau = r.spec.tau_c(g);
    let mut out = Output::default();
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
        super::snapshot::mpm_rows(&r.snapshots, tau, p.mpm.half_width())?,
    );
    let e0 = r.series.first().map(|s| s.e.potential).unwrap_or(1.0);
    let last = r.series.last().copied();
    // D10: t_f = when the front settles to within 0.5 d̄ of its final position.
    let t_f = crate::analysis::front::stop_time(
        &r.series.iter().map(|s| s.t).collect::<Vec<_>>(),
        &r.series.iter().map(|s| s.l).collect::<Vec<_>>(),
        0.5 * p.mpm.material.grain_diameter,
    );
    let kmax = r
        .series
        .iter()
        .copied()
        .reduce(|a, s| if a.e.kinetic >= s.e.kinetic { a } else { s });
    out.scalar("a", r.spec.h0 / r.spec.l0)
        .scalar("l0_m", r.spec.l0)
        .scalar("h0_m", r.spec.h0)
        .scalar("tau_c_s", tau)
        .scalar("points", r.points as f64)
        .scalar("runout_norm", r.runout)
        .scalar("runout_q99_norm", r.runout_q99)
        .scalar("lf_m", r.final_front.length)
        .scalar("hf_over_l0", r.final_front.height / r.spec.l0)
        .scalar("t_end_over_tau_c", last.map(|s| s.t / tau).unwrap_or(0.0))
        .scalar("t_f_over_tau_c", t_f / tau)
        .scalar("t_kemax_over_tau_c", kmax.map(|s| s.t / tau).unwrap_or(f64::NAN))
        .scalar(
            "ed_over_e0_end",
            last.map(|s| 1.0 - (s.e.kinetic + s.e.potential) / e0)
                .unwrap_or(f64::NAN),
        )
        .scalar(
            "plastic_work_over_e0_end",
            last.map(|s| s.e.plastic_work / e0).unwrap_or(f64::NAN),
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
    // Per-run analysis shared with the DEM (stages::column_analysis).
    {
        let lp = p.mpm.half_width();
        super::front_rules::report_mpm(&mut out, &r, lp, p.mpm.material.grain_diameter, tau, p.run.front)?;
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
        let tt: Vec<f64> = r.series.iter().map(|v| v.t).collect();
        let ll: Vec<f64> = r.series.iter().map(|v| v.l).collect();
        let hh: Vec<f64> = r.series.iter().map(|v| v.h).collect();
        let ek: Vec<f64> = r.series.iter().map(|v| v.e.kinetic).collect();
        let ep: Vec<f64> = r.series.iter().map(|v| v.e.potential).collect();
        let ist: Vec<_> = r.series.iter().map(|v| v.inertial_cg).collect();
        super::column_analysis::analyse(
            &mut out,
            &super::column_analysis::Run {
                method: "MPM",
                l0: r.spec.l0,
                h0: r.spec.h0,
                tau,
                d: p.mpm.material.grain_diameter,
                t: &tt,
                l: &ll,
                h: &hh,
                ek: &ek,
                ep: &ep,
                inertial: &ist,
                gaps: &p.run.link_gap_sensitivity,
                gap_lengths: &r.gap_lengths,
                link_gap: if p.run.link_grid {
                    f64::NAN
                } else {
                    p.run.link_gap.unwrap_or(f64::NAN)
                },
                at_tau: at_tau.as_ref(),
                x_start: &r.initial.x,
                x_end: &x_end,
                mass: &r.initial.mass,
                phi_deg: p.mpm.material.friction_deg,
                mu_grain: f64::NAN,
                at_rest: r.stopped,
                g,
            },
        )?;
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
                "Stop rule (shared with the DEM): after {} τ_c, grid E_k < {:.0e} E_0 and L, H moved < {} d̄/τ_c × {} τ_c over the last {} τ_c; upper bound {} τ_c. Main mass: {}.",
                rule.t_min, rule.ke_ratio, rule.front_speed, rule.window, rule.window, rule.t_max,
                if p.run.link_grid { "points linked when they share a background-grid node (uGIMP support h + l_p: the MPM's interaction, as contact is the DEM's; the edge-gap sensitivity table is kept)".to_string() } else { format!("points (half-size l_p) linked when their edges are within {} d̄ (the DEM's D01 rule)", p.run.link_gap.map(|g| g.to_string()).unwrap_or_else(|| "1.5 spacings (centre distance)".into())) }
            ));
        }
    }
    out.claims.push(Claim::abs("comes-to-rest", "\"the granular mass comes to rest at about t = 3τ_c\" (MPM, a = 0.4): t_f/τ_c, front within 0.5 d̄ of L_f (D10)", 3.0, t_f / tau, 1.0));
    let t: Vec<f64> = r.series.iter().map(|s| s.t / tau).collect();
    let chart = Chart {
        title: ctx
            .caption
            .clone()
            .unwrap_or_else(|| format!("MPM column collapse, a = {a:.2}")),
        footer: footer(
            &ctx.profile,
            &format!(
                "h = {} mm, {} PPC, ΔL = {:.3}",
                p.mpm.cell_size * 1e3,
                p.mpm.ppc,
                r.runout
            ),
        ),
        x_label: "t/τ_c".into(),
        y_label: "(L − L_0)/L_0,  H/L_0".into(),
        series: vec![
            Series::new(
                "MPM (L − L_0)/L_0",
                Style::Line,
                t.iter()
                    .copied()
                    .zip(r.series.iter().map(|s| (s.l - r.spec.l0) / r.spec.l0))
                    .collect(),
                0,
            ),
            Series::new(
                "MPM H/L_0",
                Style::Line,
                t.iter()
                    .copied()
                    .zip(r.series.iter().map(|s| s.h / r.spec.l0))
                    .collect(),
                1,
            ),
        ],
        ..Default::default()
    };
    out.figure("figure", chart.to_svg()?);
    let en = Chart {
        title: format!("MPM energy evolution, a = {a:.2}"),
        footer: footer(&ctx.profile, ""),
        x_label: "t/τ_c".into(),
        y_label: "E/E_0".into(),
        series: vec![
            Series::new(
                "E_p/E_0",
                Style::Line,
                t.iter()
                    .copied()
                    .zip(r.series.iter().map(|s| s.e.potential / e0))
                    .collect(),
                0,
            ),
            Series::new(
                "E_k/E_0",
                Style::Line,
                t.iter()
                    .copied()
                    .zip(r.series.iter().map(|s| s.e.kinetic / e0))
                    .collect(),
                1,
            ),
            Series::new(
                "E_kx/E_0",
                Style::Line,
                t.iter()
                    .copied()
                    .zip(r.series.iter().map(|s| s.e.kinetic_x / e0))
                    .collect(),
                3,
            ),
            Series::new(
                "E_ky/E_0",
                Style::Line,
                t.iter()
                    .copied()
                    .zip(r.series.iter().map(|s| s.e.kinetic_y / e0))
                    .collect(),
                4,
            ),
            Series::new(
                "E_d/E_0 (eq 4.12)",
                Style::Line,
                t.iter()
                    .copied()
                    .zip(r.series.iter().map(|s| 1.0 - (s.e.kinetic + s.e.potential) / e0))
                    .collect(),
                2,
            ),
            Series::new(
                "plastic work/E_0",
                Style::Line,
                t.iter()
                    .copied()
                    .zip(r.series.iter().map(|s| s.e.plastic_work / e0))
                    .collect(),
                5,
            ),
        ],
        ..Default::default()
    };
    out.figure("energy", en.to_svg()?);
    Ok(out)
}

/// Kind `mpm-collapse`.
pub const COLLAPSE_KIND: Kind = Kind {
    name: "mpm-collapse",
    version: 11,
    about: "MPM granular column collapse: L(t), H(t), energies, plastic work until it stops",
    params: typed::<CollapseParams>,
    run: run_collapse_stage,
    explain: Some(explain_mpm),
};

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

/// Parameters of an `mpm-work-precision` stage.
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
            &mut col.solver,
            &mut col.state,
            col.spec.h0,
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

fn setting_label(s: &WpSetting) -> String {
    let mut l = format!("{} PPC, h = {} mm, Courant {}", s.0, s.1 * 1e3, s.2);
    if s.3 != crate::mpm::params::Shape::Gimp {
        l.push_str(", linear shape functions");
    }
    if s.4 != crate::mpm::Scheme::Usl {
        l.push_str(&format!(", {}", s.4.name()));
    }
    l
}

fn run_wp(ctx: &StageCtx) -> anyhow::Result<Output> {
    use crate::mpm::Scheme;
    use crate::mpm::params::Shape;
    use rayon::prelude::*;
    let mut p: WorkPrecisionParams = decode(ctx)?;
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
    let mut series = Vec::new();
    let mut ci = 0;
    for &h in &p.cell_sizes {
        for &k in &p.courants {
            let sel: Vec<&(WpSetting, WpRuns)> = rows
                .iter()
                .filter(|r| r.0.1 == h && r.0.2 == k && r.0.3 == shape0 && r.0.4 == scheme0)
                .collect();
            let s = Series::new(
                format!("h = {} mm, Courant {k} (PPC {:?})", h * 1e3, p.ppc),
                Style::LinePoints,
                sel.iter().map(|r| (r.1.wall_s, err(&r.1).max(1e-6))).collect(),
                ci,
            );
            series.push(if members > 1 {
                s.with_errors(sel.iter().map(|r| err_se(&r.1)).collect())
            } else {
                s
            });
            ci += 1;
        }
    }
    for (s, r) in rows.iter().filter(|r| r.0.3 != shape0 || r.0.4 != scheme0) {
        let ser = Series::new(setting_label(s), Style::Points, vec![(r.wall_s, err(r).max(1e-6))], ci);
        series.push(if members > 1 {
            ser.with_errors(vec![err_se(r)])
        } else {
            ser
        });
        ci += 1;
    }
    let chart = Chart::work_precision(
        ctx.caption.clone().unwrap_or_else(|| "MPM work-precision".into()),
        footer(
            &ctx.profile,
            &format!(
                "reference ΔL = {ref_dl:.4} ({} PPC, h = {} mm, Courant {}){}",
                p.reference.0,
                p.reference.1 * 1e3,
                p.reference.2,
                if members > 1 {
                    format!(", {members} starts per setting, ± s.e.")
                } else {
                    String::new()
                }
            ),
        ),
        series,
    );
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `mpm-work-precision`.
pub const WP_KIND: Kind = Kind {
    name: "mpm-work-precision",
    version: 4,
    about: "MPM column run-out error vs wall time over PPC × cell size × Courant number",
    params: typed::<WorkPrecisionParams>,
    run: run_wp,
    explain: Some(explain_mpm),
};
