//! The DEM's column collapse (L(t), H(t), energy ledger, until at rest): the `dem` method
//! of the `column-collapse` kind ([`super::collapse`]), which runs the analysis shared
//! with the MPM on the [`ColumnTrace`] this returns.

use serde::{Deserialize, Serialize};

use super::dem_common::{check_dem, column_from};
use crate::dem::DemParams;
use crate::dem::column::{CollapseParams, CollapseResult, collapse};
use crate::dem::prep::Column;
use crate::engines::Method;
use crate::engines::column::{Collapsed, ColumnEngine, ColumnTrace, EnergyCurve, Shared};
use crate::pipeline::context::{Claim, Output, StageCtx, frame};
use crate::stages::Validate;
use crate::stages::column::dem_prep::PrepParams;
use crate::stages::kind::{CostCtx, Work};
use crate::validate::{Checker, Issue};

/// Parameters of a `column-collapse` stage with `method: dem`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CollapseStageParams {
    /// Solver parameters.
    pub dem: DemParams,
    /// Softening (must match the prep stage's for a consistent state).
    pub stiffness_factor: f64,
    /// Run control.
    pub run: CollapseParams,
    /// Write `.vtp` snapshots at the snapshot times.
    pub vtk: bool,
    /// An ensemble member's start: absent, the column as prepared (member 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start: Option<PerturbedStart>,
}

/// A perturbed start of the prepared column, one member of an ensemble (the run-out is
/// chaotic: ±0.05 at a = 0.4 from a 1e-9 m perturbation). The same perturbation as the
/// calibration's ensembles (`dem::prep::Column::perturbed`): with the same seed and
/// amplitude, member k here is member k there.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PerturbedStart {
    /// Member index (≥ 1; member 0 is the column as prepared).
    pub member: usize,
    /// Largest displacement of a grain [m].
    pub perturbation_m: f64,
    /// Seed of the perturbations.
    pub seed: u64,
}

impl Default for CollapseStageParams {
    fn default() -> Self {
        CollapseStageParams {
            dem: DemParams::default(),
            stiffness_factor: 1.0,
            run: CollapseParams::default(),
            vtk: false,
            start: None,
        }
    }
}

impl Validate for CollapseStageParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_dem(&self.dem, self.stiffness_factor, &mut c);
        c.check(
            self.run.t_max > self.run.t_min,
            "run.t_max",
            format!("{} (with run.t_min = {})", self.run.t_max, self.run.t_min),
            "> run.t_min",
        );
        c.positive("run.sample_every", self.run.sample_every);
        if let Some(rule) = self.run.stop {
            for (k, v, a) in rule.issues() {
                c.fail(&format!("run.stop.{k}"), v, a);
            }
        }
        c.check(self.run.link_gap >= 0.0, "run.link_gap", self.run.link_gap, "≥ 0 [d̄]");
        super::front_rules::check(&self.run.front, &mut c);
        c.check(
            self.run.link_gap_sensitivity.iter().all(|g| *g >= 0.0 && g.is_finite()),
            "run.link_gap_sensitivity",
            format!("{:?}", self.run.link_gap_sensitivity),
            "gaps ≥ 0 [d̄]",
        );
        c.positive("run.inertial_cell", self.run.inertial_cell);
        if let Some(st) = &self.start {
            c.check(
                (1..=64).contains(&st.member),
                "start.member",
                st.member,
                "1 … 64 (member 0 is the column as prepared: leave `start` out)",
            );
            c.check(
                st.perturbation_m.is_finite() && st.perturbation_m > 0.0 && st.perturbation_m < 1e-4,
                "start.perturbation_m",
                st.perturbation_m,
                "> 0 and < 1e-4 m (a perturbation, far below a grain)",
            );
        }
        c.issues
    }
}

fn collapse_table(r: &CollapseResult) -> anyhow::Result<polars::prelude::DataFrame> {
    let s = &r.samples;
    let e0 = s.first().map(|v| v.ep).unwrap_or(1.0);
    let l0 = r.l0;
    frame(vec![
        ("t_s", s.iter().map(|v| v.t).collect()),
        ("t_over_tau_c", s.iter().map(|v| v.t / r.tau_c).collect()),
        ("l_m", s.iter().map(|v| v.length).collect()),
        ("h_m", s.iter().map(|v| v.height).collect()),
        ("runout_norm", s.iter().map(|v| (v.length - l0) / l0).collect()),
        (
            "runout_gathered_norm",
            s.iter().map(|v| (v.length_gathered - l0) / l0).collect(),
        ),
        ("h_over_l0", s.iter().map(|v| v.height / l0).collect()),
        ("ep_j", s.iter().map(|v| v.ep).collect()),
        ("ek_j", s.iter().map(|v| v.ekx + v.eky).collect()),
        ("ekx_j", s.iter().map(|v| v.ekx).collect()),
        ("eky_j", s.iter().map(|v| v.eky).collect()),
        ("erot_j", s.iter().map(|v| v.erot).collect()),
        ("elastic_j", s.iter().map(|v| v.elastic).collect()),
        ("w_collisional_j", s.iter().map(|v| v.ledger.collisional()).collect()),
        ("w_frictional_j", s.iter().map(|v| v.ledger.frictional()).collect()),
        ("balance_residual_j", s.iter().map(|v| v.residual).collect()),
        ("ep_over_e0", s.iter().map(|v| v.ep / e0).collect()),
        ("ek_over_e0", s.iter().map(|v| (v.ekx + v.eky) / e0).collect()),
        (
            "ed_over_e0",
            s.iter().map(|v| 1.0 - (v.ekx + v.eky + v.ep) / e0).collect(),
        ),
        ("i_cg_mean", s.iter().map(|v| v.inertial.mean).collect()),
        ("i_cg_median", s.iter().map(|v| v.inertial.median).collect()),
        ("i_cg_p95", s.iter().map(|v| v.inertial.p95).collect()),
        ("i_cg_max", s.iter().map(|v| v.inertial.max).collect()),
        (
            "i_cg_flowing_fraction",
            s.iter().map(|v| v.inertial.flowing_fraction).collect(),
        ),
    ])
}

/// D09: Voronoi packing fraction of the interior cells at release and at each snapshot,
/// over the whole mass, inside the initial footprint (x < L_0) and beyond it.
fn packing_table(col: &Column, r: &CollapseResult) -> anyhow::Result<(polars::prelude::DataFrame, f64, f64)> {
    use crate::analysis::voronoi::{cells, packing_fraction};
    let reach = 0.4 * r.d_mean; // interior: every vertex within r_i + 0.4 d̄ (analysis::voronoi)
    let mut rows: Vec<[f64; 6]> = Vec::new();
    let states = std::iter::once((0.0, &col.state)).chain(r.snapshots.iter().map(|s| (s.t, &s.state)));
    for (t, st) in states {
        let c = cells(&st.x, &st.y, &st.r, reach);
        let (all, n) = packing_fraction(&c, &st.r, |_| true);
        let (inside, _) = packing_fraction(&c, &st.r, |i| st.x[i] < r.l0);
        let (outside, _) = packing_fraction(&c, &st.r, |i| st.x[i] >= r.l0);
        rows.push([t / r.tau_c, all, inside, outside, n as f64, st.len() as f64]);
    }
    let col_of = |k: usize| rows.iter().map(|v| v[k]).collect::<Vec<f64>>();
    let df = frame(vec![
        ("t_over_tau_c", col_of(0)),
        ("phi_voronoi", col_of(1)),
        ("phi_voronoi_footprint", col_of(2)),
        ("phi_voronoi_beyond_l0", col_of(3)),
        ("interior_cells", col_of(4)),
        ("grains", col_of(5)),
    ])?;
    Ok((df, rows[0][1], rows[rows.len() - 1][1]))
}

impl crate::engines::Preflight for CollapseStageParams {
    fn preflight(&self) -> String {
        super::dem_common::preflight_dem(&self.dem, self.stiffness_factor, super::dem_common::PREFLIGHT_SIZES)
    }
}

impl ColumnEngine for CollapseStageParams {
    fn collapse<'a>(&'a self, ctx: &'a StageCtx, out: &mut Output) -> anyhow::Result<Collapsed<'a>> {
        let mut p = self.clone();
        let calibrated = crate::stages::calib::dem_calibration::apply_calibration(ctx, &mut p.dem)?;
        let run = p.dem.softened(p.stiffness_factor);
        let col = column_from(ctx.input("column")?, run.density)?;
        let col = match &p.start {
            Some(st) => col.perturbed(st.member, st.perturbation_m, st.seed),
            None => col,
        };
        let r = collapse(&col, &run, &p.run)?;
        out.table("table", collapse_table(&r)?);
        out.table(
            "snapshots",
            crate::stages::generic::snapshot::dem_rows(&r.snapshots, r.tau_c)?,
        );
        let s = &r.samples;
        let e0 = s.first().map(|v| v.ep).unwrap_or(1.0);
        let last = s.last().copied();
        let d_mean = col.state.volume_mean_diameter();
        let a = r.h0 / r.l0;
        let dl = r.delta_l();
        let at_rest = r.stop == crate::dem::column::StopReason::AtRest;
        let max_res = s.iter().map(|v| v.residual.abs()).fold(0.0, f64::max);
        out.scalar("n", col.state.len() as f64)
            .scalar(
                "w_frictional_over_e0_end",
                last.map(|v| v.ledger.frictional() / e0).unwrap_or(f64::NAN),
            )
            .scalar(
                "w_collisional_over_e0_end",
                last.map(|v| v.ledger.collisional() / e0).unwrap_or(f64::NAN),
            )
            .scalar("erot_over_e0_end", last.map(|v| v.erot / e0).unwrap_or(f64::NAN))
            .scalar("elastic_over_e0_end", last.map(|v| v.elastic / e0).unwrap_or(f64::NAN))
            .scalar("max_balance_residual_over_e0", max_res / e0)
            .scalar("max_overlap_fraction", r.max_overlap_fraction)
            .scalar("dt_s", r.dt)
            .scalar("steps", r.steps as f64)
            .scalar("at_rest", f64::from(u8::from(at_rest)));
        // One run of a chaotic flow is not a claim: eq 4.6 is checked on ensemble means (with
        // their spread) by calib-dem; this stage shows the flow evolution of member 0.
        out.scalar("mu_r", p.dem.rolling.mu_r)
            .scalar("runout_eq46", crate::stages::calib::dem_calibration::eq46(a));
        out.note(format!("Single run: ΔL = {dl:.3} against eq 4.6's {:.3}; the run-out is chaotic (±0.05 from a 1e-9 m perturbation), so the claim is made on ensemble means by calib-dem.", crate::stages::calib::dem_calibration::eq46(a)));
        if calibrated {
            out.note(format!(
                "Rolling friction μ_r = {} ({:?} model) from the joint calibration (calibrated).",
                p.dem.rolling.mu_r, p.dem.rolling.model
            ));
        }
        out.checks.push(Claim::at_most(
            "energy-balance",
            "E_0 = E_p + E_k + E_rot + elastic + dissipated: max |residual|/E_0 (docs/definitions.md D07: within 1 %)",
            0.01,
            max_res / e0,
        ));
        use crate::dem::column::cloud;
        let phi = match ctx.input_opt("calibration") {
            Some(c) => c.scalar("friction_angle_deg")?,
            None => f64::NAN,
        };
        let at_tau = r
            .snapshots
            .iter()
            .min_by(|a, b| (a.t - r.tau_c).abs().total_cmp(&(b.t - r.tau_c).abs()))
            .filter(|s| (s.t / r.tau_c - 1.0).abs() < 0.05)
            .map(|s| cloud(&s.state, s.t));
        let fin = &r.snapshots[r.snapshots.len() - 1].state;
        let clouds: Vec<_> = r.snapshots.iter().map(|s| cloud(&s.state, s.t)).collect();
        let thick = super::front_rules::report(out, &clouds, d_mean, (r.l0, r.tau_c), p.run.front)?;
        out.note(format!("Run-out at rest: runout_norm = {dl:.3} is the chapter's rule (\"the farthest grain which has at least one contact with the main mass\": edges within {} d̄) and carries the DEM claims, as the chapter defines it; runout_thick_norm = {thick:.3} is the rule the MPM uses (the deposit connected to the main mass at least {} d̄ thick; table runout_by_threshold).", p.run.link_gap, p.run.front.threshold_d));
        let series = |f: &dyn Fn(&crate::dem::column::Sample) -> f64| s.iter().map(f).collect::<Vec<f64>>();
        let over_e0 = |label: &str, color: usize, f: &dyn Fn(&crate::dem::column::Sample) -> f64| EnergyCurve {
            label: label.into(),
            color,
            over_e0: s.iter().map(|v| f(v) / e0).collect(),
        };
        let trace = ColumnTrace {
            method: Method::Dem,
            l0: r.l0,
            h0: r.h0,
            tau: r.tau_c,
            d: d_mean,
            g: p.dem.gravity,
            t: series(&|v| v.t),
            l: series(&|v| v.length),
            l_gathered: series(&|v| v.length_gathered),
            h: series(&|v| v.height),
            ek: series(&|v| v.ekx + v.eky),
            ep: series(&|v| v.ep),
            inertial: s.iter().map(|v| v.inertial).collect(),
            gaps: p.run.link_gap_sensitivity.clone(),
            gap_lengths: r.gap_lengths.clone(),
            link_gap: p.run.link_gap,
            at_tau,
            x_start: col.state.x.clone(),
            x_end: fin.x.clone(),
            mass: col.state.m.clone(),
            phi_deg: phi,
            mu_grain: p.dem.grain.friction,
            at_rest,
            runout_norm: dl,
            lf_m: r.runout(),
            hf_m: last.map(|v| v.height).unwrap_or(f64::NAN),
            energies: vec![
                over_e0("E_p/E_0", 0, &|v| v.ep),
                over_e0("E_k/E_0", 1, &|v| v.ekx + v.eky),
                EnergyCurve {
                    label: "E_d/E_0 (eq 4.12)".into(),
                    color: 2,
                    over_e0: s.iter().map(|v| 1.0 - (v.ekx + v.eky + v.ep) / e0).collect(),
                },
                over_e0("frictional W_f/E_0", 3, &|v| v.ledger.frictional()),
                over_e0("collisional W_c/E_0", 4, &|v| v.ledger.collisional()),
            ],
            footer: format!("ΔL = {dl:.3}, stiffness factor {}", p.stiffness_factor),
        };
        let finish = move |out: &mut Output, _: &Shared| -> anyhow::Result<()> {
            let s = &r.samples;
            if s.len() > 1 {
                out.claims.push(Claim::abs(
                    "motion-persists-6tau",
                    "DEM: \"some motion still persists along the free surface … up to t ≈ 6τ_c\" — end of the run by the stated stop rule (E_k < ke_ratio·E_0 and a still front), t_stop/τ_c (tolerance 1.5)",
                    6.0, s.last().map(|v| v.t / r.tau_c).unwrap_or(f64::NAN), 1.5,
                ));
            }
            let (pk, phi0, phi1) = packing_table(&col, &r)?;
            out.table("packing", pk);
            out.scalar("phi_voronoi_initial", phi0)
                .scalar("phi_voronoi_final", phi1);
            let rule = p.run.rule();
            out.note(format!(
                "Stop rule (shared with the MPM): after {} τ_c, E_k + E_rot < {:.0e} E_0 and L, H moved < {} d̄/τ_c × {} τ_c over the last {} τ_c; upper bound {} τ_c. Main mass: grains linked when their edges are within {} d̄ (D01; sensitivity table `link_gap_sensitivity`).",
                rule.t_min, rule.ke_ratio, rule.front_speed, rule.window, rule.window, rule.t_max, p.run.link_gap
            ));
            out.note(format!(
                "{} grains, Δt = {:.3e} s, {} steps, stop: {:?}, wall {:.1} s; max overlap {:.3} % of d.",
                col.state.len(),
                r.dt,
                r.steps,
                r.stop,
                r.wall_s,
                100.0 * r.max_overlap_fraction
            ));
            if p.vtk {
                for (i, snap) in r.snapshots.iter().enumerate() {
                    out.files.push((
                        format!("snapshot-{i:02}-t{:.3}tau.vtp", snap.t / r.tau_c),
                        snap.to_vtp().into_bytes(),
                    ));
                }
            }
            Ok(())
        };
        Ok(Collapsed {
            trace,
            finish: Box::new(finish),
        })
    }
}

/// Cost: grains ∝ the input column's area, steps per simulated second.
pub(super) fn cost(p: &CollapseStageParams, c: &CostCtx) -> Option<Work> {
    let area = c.input::<PrepParams>("column")?.area_m2;
    Some((
        vec![("grains", area), ("steps", p.dem.steps_per_second(p.stiffness_factor))],
        false,
    ))
}
