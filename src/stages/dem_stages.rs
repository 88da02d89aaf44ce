//! DEM stage kinds: column preparation, collapse, snapshots, the two calibration tests
//! that feed the MPM through the DAG (periodic shear → friction angle, confined
//! compression → modulus) and the DEM work-precision sweep.
//!
//! Every kind takes `dem` (the solver's own parameter schema, `stages/dem-column.yaml`)
//! and `stiffness_factor`: the quick profile softens k_n, k_t, k_r by this factor (the
//! step grows by 1/√factor); what that costs in accuracy is measured by
//! `wp-dem-column` and printed on the figures.

use serde::{Deserialize, Serialize};

use super::dem_common::{check_dem, column_from, explain_dem, grains_table, histories_table};
use super::wp_summary::ensemble_error;
use super::{Kind, Validate, decode, typed};
use crate::dem::column::{CollapseParams, CollapseResult, Variant, collapse, work_precision};
use crate::dem::compress::{CompressionParams, compression_test};
use crate::dem::prep::{Column, DepositionParams, deposited_column, hex_column};
use crate::dem::shear::{ShearParams, shear_test};
use crate::dem::{DemParams, State};
use crate::math::{G, PI};
use crate::pipeline::context::{Claim, Output, StageCtx, col_f64, frame};
use crate::report::plot::{Chart, Series, Style, footer};
use crate::report::snapshot::{Field, Segment, Shape, Snapshot};
use crate::validate::{Checker, Issue};

/// How a column is packed.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Default)]
#[serde(rename_all = "snake_case")]
pub enum Packing {
    /// Ballistic deposition of the PSD grains, trimmed to L_0 × H_0 (RB).
    #[default]
    Ballistic,
    /// Monodisperse hexagonal lattice (HEX).
    Hex,
}

/// Parameters of a `dem-column-prep` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PrepParams {
    /// Solver parameters (run values; deposition may soften them, see `deposition`).
    pub dem: DemParams,
    /// Softening of the run stiffness (1 = table 4.2).
    pub stiffness_factor: f64,
    /// Aspect ratio a = H_0/L_0.
    pub a: f64,
    /// Column area L_0·H_0 [m²] (SC-COL: 3.9e-3 ≈ 3000 grains at φ ≈ 0.8).
    pub area_m2: f64,
    /// Packing method.
    pub packing: Packing,
    /// Ballistic deposition settings (width is set to L_0).
    pub deposition: DepositionParams,
    /// Grain diameter of the hexagonal lattice [m] (docs/definitions.md SC-PSD, HEX: 1.15 mm).
    pub hex_diameter_m: f64,
    /// The chapter's packing fraction for this sample, checked against the core packing
    /// (≥ 2 d̄ from walls and the surface; D09 leaves the region open). None: no claim.
    pub target_packing_fraction: Option<f64>,
}

impl Default for PrepParams {
    fn default() -> Self {
        PrepParams {
            dem: DemParams::default(),
            stiffness_factor: 1.0,
            a: 0.8,
            area_m2: 3.9e-3,
            packing: Packing::Ballistic,
            deposition: DepositionParams::default(),
            hex_diameter_m: 1.15e-3,
            target_packing_fraction: None,
        }
    }
}

impl Validate for PrepParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_dem(&self.dem, self.stiffness_factor, &mut c);
        c.in_closed("a", self.a, 0.05, 20.0);
        c.positive("area_m2", self.area_m2);
        c.positive("hex_diameter_m", self.hex_diameter_m);
        c.positive("deposition.drop_height", self.deposition.drop_height);
        c.in_open_closed("deposition.softening", self.deposition.softening, 0.0, 1.0);
        c.positive("deposition.max_settle_time", self.deposition.max_settle_time);
        c.issues
    }
}

/// Grain–grain contacts of a packing at rest: (i, j, overlap δ). With the linear contact
/// law at one k_n, F_n = k_n δ, so δ is the normal force up to that constant. Sweep over
/// grains sorted by x (a packing at rest has few neighbours within 2 r_max).
pub(crate) fn contacts_at_rest(s: &State) -> Vec<(usize, usize, f64)> {
    let n = s.x.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| s.x[a].total_cmp(&s.x[b]));
    let rmax = s.r.iter().copied().fold(0.0, f64::max);
    let mut out = Vec::new();
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            if s.x[j] - s.x[i] > s.r[i] + rmax {
                break;
            }
            let d = ((s.x[j] - s.x[i]).powi(2) + (s.y[j] - s.y[i]).powi(2)).sqrt();
            let delta = s.r[i] + s.r[j] - d;
            if delta > 0.0 {
                out.push((i.min(j), i.max(j), delta));
            }
        }
    }
    out.sort_by(|a, b| (a.0, a.1).cmp(&(b.0, b.1)));
    out
}

fn column_snapshot(
    title: String,
    foot: String,
    s: &State,
    l0: f64,
    h0: f64,
    colour_by_size: bool,
    gate: bool,
) -> String {
    column_snapshot_with(title, foot, s, l0, h0, colour_by_size, gate, &[])
}

#[allow(clippy::too_many_arguments)]
fn column_snapshot_with(
    title: String,
    foot: String,
    s: &State,
    l0: f64,
    h0: f64,
    colour_by_size: bool,
    gate: bool,
    network: &[(usize, usize, f64)],
) -> String {
    let d: Vec<f64> = s.r.iter().map(|r| 2e3 * r).collect();
    let (dmin, dmax) = d
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
    let mut segs = vec![
        Segment {
            a: (0.0, 0.0),
            b: (0.0, 1.1 * h0),
            color: "black",
            width: 2.5,
            dashed: false,
        },
        Segment {
            a: (0.0, 0.0),
            b: (1.15 * l0, 0.0),
            color: "black",
            width: 2.5,
            dashed: false,
        },
    ];
    if gate {
        segs.push(Segment {
            a: (l0, 0.0),
            b: (l0, 1.1 * h0),
            color: "#555",
            width: 2.0,
            dashed: true,
        });
    }
    let fmax = network.iter().map(|c| c.2).fold(0.0, f64::max);
    for &(i, j, f) in network {
        segs.push(Segment {
            a: (s.x[i], s.y[i]),
            b: (s.x[j], s.y[j]),
            color: "#b2182b",
            width: 0.2 + 2.8 * f / fmax.max(1e-300),
            dashed: false,
        });
    }
    Snapshot {
        title,
        footer: foot,
        x: &s.x,
        y: &s.y,
        half: &s.r,
        shape: Shape::Disk,
        field: colour_by_size.then(|| Field {
            values: &d,
            label: "grain diameter [mm]".into(),
            range: (dmin, dmax.max(dmin + 1e-9)),
        }),
        black: None,
        fill: (!network.is_empty()).then_some("#c8c8c8"),
        segments: segs,
        view: None,
        width_px: 640.0,
    }
    .to_svg()
}

fn run_prep(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: PrepParams = decode(ctx)?;
    let run = p.dem.softened(p.stiffness_factor);
    let l0 = (p.area_m2 / p.a).sqrt();
    let h0 = p.a * l0;
    let col = match p.packing {
        Packing::Ballistic => {
            let psd = ctx.input("psd")?;
            let d = col_f64(&psd.table("table")?, "d_m")?;
            let mut radii: Vec<f64> = d.iter().map(|d| 0.5 * d).collect();
            // Rain only what the column needs (+15 % to trim): the PSD order is shuffled,
            // so its first k grains follow the same distribution.
            let need = p.area_m2 * 0.85 / (radii.iter().map(|r| PI * r * r).sum::<f64>() / radii.len() as f64);
            let k = (1.15 * need).ceil() as usize;
            anyhow::ensure!(
                radii.len() >= k,
                "the PSD input `{}` has {} grains; a {:.4} m² column needs about {k} before trimming: raise its `n`",
                psd.id,
                radii.len(),
                p.area_m2
            );
            radii.truncate(k);
            deposited_column(&radii, l0, h0, &run, &p.deposition)?
        }
        Packing::Hex => hex_column(l0, h0, p.hex_diameter_m, &run, p.deposition.max_settle_time)?,
    };
    let mut out = Output::default();
    out.table("table", grains_table(&col.state)?);
    out.table("contacts", histories_table(&col.histories)?);
    out.scalar("n", col.state.len() as f64)
        .scalar("a", col.h0 / col.l0)
        .scalar("l0_m", col.l0)
        .scalar("h0_m", col.h0)
        .scalar("packing_fraction", col.packing_fraction)
        .scalar("packing_fraction_core", col.packing_fraction_core)
        .scalar("settle_time_s", col.settle.time)
        .scalar("settle_ke_over_ep", col.settle.ke_over_ep)
        .scalar("stiffness_factor", p.stiffness_factor)
        .scalar("seed", p.deposition.seed as f64);
    out.checks.push(Claim::at_most(
        "at-rest",
        "stable state before release: E_k/E_p < 1e-6 (docs/definitions.md fig4-02)",
        1e-6,
        col.settle.ke_over_ep,
    ));
    if let Some(t) = p.target_packing_fraction {
        out.claims.push(Claim::abs(
            "packing-fraction",
            "loose 79 % / dense 83 % packing (chapter §4.2.3), core packing fraction",
            t,
            col.packing_fraction_core,
            0.015,
        ));
    }
    out.note(format!(
        "{:?} packing, {} grains, L_0 = {:.2} mm, H_0 = {:.2} mm (a = {:.3}), φ = {:.3}; k_n = {:.3e} N/m (stiffness factor {}), Δt = {:.3e} s; settled to E_k/E_p = {:.1e}.",
        p.packing, col.state.len(), col.l0 * 1e3, col.h0 * 1e3, col.h0 / col.l0, col.packing_fraction, run.grain.kn, p.stiffness_factor, run.dt, col.settle.ke_over_ep
    ));
    let svg = column_snapshot(
        ctx.caption
            .clone()
            .unwrap_or_else(|| format!("DEM column a = {:.2}", p.a)),
        footer(
            &ctx.profile,
            &format!(
                "N = {}, φ = {:.3}, L_0 = {:.1} mm, H_0 = {:.1} mm",
                col.state.len(),
                col.packing_fraction,
                col.l0 * 1e3,
                col.h0 * 1e3
            ),
        ),
        &col.state,
        col.l0,
        col.h0,
        p.packing == Packing::Ballistic,
        true,
    );
    out.figure("figure", svg);
    Ok(out)
}

/// Kind `dem-column-prep`.
pub const PREP_KIND: Kind = Kind {
    name: "dem-column-prep",
    version: 4,
    about: "DEM column sample: ballistic deposition of the PSD (trimmed to L0 x H0) or hexagonal lattice",
    params: typed::<PrepParams>,
    run: run_prep,
    explain: Some(explain_dem),
};

/// Parameters of a `dem-snapshot` stage (figures of a prepared column).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SnapshotParams {
    /// Colour grains by diameter (fig4-01a) or uniformly (fig4-02).
    pub colour_by_size: bool,
    /// Draw the gate at x = L_0.
    pub gate: bool,
    /// Grains grey with the contact-force network over them: one line per grain–grain
    /// contact between the centres, width ∝ normal force (fig4-01a as the original).
    pub force_network: bool,
}

impl Default for SnapshotParams {
    fn default() -> Self {
        SnapshotParams {
            colour_by_size: false,
            gate: true,
            force_network: false,
        }
    }
}

impl Validate for SnapshotParams {
    fn validate(&self) -> Vec<Issue> {
        vec![]
    }
}

fn run_snapshot(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: SnapshotParams = decode(ctx)?;
    let input = ctx.input("column")?;
    let col = column_from(input, 2500.0)?;
    let mut out = Output::default();
    out.scalar("n", col.state.len() as f64)
        .scalar("packing_fraction", col.packing_fraction)
        .scalar("l0_m", col.l0)
        .scalar("h0_m", col.h0)
        .scalar("a", col.h0 / col.l0);
    let network = if p.force_network {
        contacts_at_rest(&col.state)
    } else {
        Vec::new()
    };
    let mut foot = format!(
        "N = {}, φ = {:.3}, L_0 = {:.1} mm, H_0 = {:.1} mm, at rest (E_k/E_p = {:.1e})",
        col.state.len(),
        col.packing_fraction,
        col.l0 * 1e3,
        col.h0 * 1e3,
        col.settle.ke_over_ep
    );
    if p.force_network {
        let z = 2.0 * network.len() as f64 / col.state.len() as f64;
        out.scalar("grain_contacts", network.len() as f64)
            .scalar("coordination_number", z);
        foot.push_str(&format!(
            "; {} grain contacts (z = {z:.2}), line width ∝ F_n",
            network.len()
        ));
    }
    let svg = column_snapshot_with(
        ctx.caption.clone().unwrap_or_else(|| "DEM column".into()),
        footer(&ctx.profile, &foot),
        &col.state,
        col.l0,
        col.h0,
        p.colour_by_size,
        p.gate,
        &network,
    );
    out.figure("figure", svg);
    out.table("table", grains_table(&col.state)?);
    Ok(out)
}

/// Kind `dem-snapshot`.
pub const SNAPSHOT_KIND: Kind = Kind {
    name: "dem-snapshot",
    version: 2,
    about: "snapshot figure of a prepared DEM column (fig4-01a, fig4-02)",
    params: typed::<SnapshotParams>,
    run: run_snapshot,
    explain: None,
};

/// Parameters of a `dem-collapse` stage.
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
}

impl Default for CollapseStageParams {
    fn default() -> Self {
        CollapseStageParams {
            dem: DemParams::default(),
            stiffness_factor: 1.0,
            run: CollapseParams::default(),
            vtk: false,
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
            self.run.t_max,
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

fn run_collapse_stage(ctx: &StageCtx) -> anyhow::Result<Output> {
    let mut p: CollapseStageParams = decode(ctx)?;
    let calibrated = super::calib::apply_calibration(ctx, &mut p.dem)?;
    let run = p.dem.softened(p.stiffness_factor);
    let col = column_from(ctx.input("column")?, run.density)?;
    let r = collapse(&col, &run, &p.run)?;
    let mut out = Output::default();
    out.table("table", collapse_table(&r)?);
    out.table("snapshots", super::snapshot::dem_rows(&r.snapshots, r.tau_c)?);
    let s = &r.samples;
    let e0 = s.first().map(|v| v.ep).unwrap_or(1.0);
    let last = s.last().copied();
    // D10: t_f = when the front settles to within 0.5 d̄ of its final position (d̄ the
    // volume-mean diameter, as docs/definitions.md SC-PSD defines it).
    let d_mean = col.state.volume_mean_diameter();
    let t_f = crate::analysis::front::stop_time(
        &s.iter().map(|v| v.t).collect::<Vec<_>>(),
        &s.iter().map(|v| v.length).collect::<Vec<_>>(),
        0.5 * d_mean,
    );
    let kmax = s
        .iter()
        .copied()
        .fold(None::<crate::dem::column::Sample>, |a, v| match a {
            Some(x) if x.ekx + x.eky >= v.ekx + v.eky => Some(x),
            _ => Some(v),
        });
    let a = r.h0 / r.l0;
    let dl = r.delta_l();
    let at_rest = r.stop == crate::dem::column::StopReason::AtRest;
    let max_res = s.iter().map(|v| v.residual.abs()).fold(0.0, f64::max);
    out.scalar("a", a)
        .scalar("l0_m", r.l0)
        .scalar("h0_m", r.h0)
        .scalar("tau_c_s", r.tau_c)
        .scalar("n", col.state.len() as f64)
        .scalar("runout_norm", dl)
        .scalar("lf_m", r.runout())
        .scalar("hf_over_l0", last.map(|v| v.height / r.l0).unwrap_or(f64::NAN))
        .scalar("t_end_over_tau_c", last.map(|v| v.t / r.tau_c).unwrap_or(f64::NAN))
        .scalar("t_f_over_tau_c", t_f / r.tau_c)
        .scalar("t_kemax_over_tau_c", kmax.map(|v| v.t / r.tau_c).unwrap_or(f64::NAN))
        .scalar(
            "ed_over_e0_end",
            last.map(|v| 1.0 - (v.ekx + v.eky + v.ep) / e0).unwrap_or(f64::NAN),
        )
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
        .scalar("runout_eq46", super::calib::eq46(a));
    out.note(format!("Single run: ΔL = {dl:.3} against eq 4.6's {:.3}; the run-out is chaotic (±0.05 from a 1e-9 m perturbation), so the claim is made on ensemble means by calib-dem.", super::calib::eq46(a)));
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
    // Per-run analysis shared with the MPM (stages::column_analysis).
    {
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
        let thick = super::front_rules::report(&mut out, &clouds, d_mean, (r.l0, r.tau_c), p.run.front)?;
        out.note(format!("Run-out at rest: runout_norm = {dl:.3} is the chapter's rule (\"the farthest grain which has at least one contact with the main mass\": edges within {} d̄) and carries the DEM claims, as the chapter defines it; runout_thick_norm = {thick:.3} is the rule the MPM uses (the deposit connected to the main mass at least {} d̄ thick; table runout_by_threshold).", p.run.link_gap, p.run.front.threshold_d));
        let tt: Vec<f64> = s.iter().map(|v| v.t).collect();
        let ll: Vec<f64> = s.iter().map(|v| v.length).collect();
        let hh: Vec<f64> = s.iter().map(|v| v.height).collect();
        let ek: Vec<f64> = s.iter().map(|v| v.ekx + v.eky).collect();
        let ep: Vec<f64> = s.iter().map(|v| v.ep).collect();
        let ist: Vec<_> = s.iter().map(|v| v.inertial).collect();
        super::column_analysis::analyse(
            &mut out,
            &super::column_analysis::Run {
                method: "DEM",
                l0: r.l0,
                h0: r.h0,
                tau: r.tau_c,
                d: d_mean,
                t: &tt,
                l: &ll,
                h: &hh,
                ek: &ek,
                ep: &ep,
                inertial: &ist,
                gaps: &p.run.link_gap_sensitivity,
                gap_lengths: &r.gap_lengths,
                link_gap: p.run.link_gap,
                at_tau: at_tau.as_ref(),
                x_start: &col.state.x,
                x_end: &fin.x,
                mass: &col.state.m,
                phi_deg: phi,
                mu_grain: p.dem.grain.friction,
                at_rest,
                g: p.dem.gravity,
            },
        )?;
        if s.len() > 1 {
            out.claims.push(Claim::abs(
                "motion-persists-6tau",
                "DEM: \"some motion still persists along the free surface … up to t ≈ 6τ_c\" — end of the run by the stated stop rule (E_k < ke_ratio·E_0 and a still front), t_stop/τ_c (tolerance 1.5)",
                6.0, last.map(|v| v.t / r.tau_c).unwrap_or(f64::NAN), 1.5,
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
    }
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
    let t: Vec<f64> = s.iter().map(|v| v.t / r.tau_c).collect();
    let chart = Chart {
        title: ctx
            .caption
            .clone()
            .unwrap_or_else(|| format!("DEM column collapse, a = {a:.2}")),
        footer: footer(
            &ctx.profile,
            &format!("ΔL = {dl:.3}, stiffness factor {}", p.stiffness_factor),
        ),
        x_label: "t/τ_c".into(),
        y_label: "(L − L_0)/L_0,  H/L_0".into(),
        series: vec![
            Series::new(
                "DEM (L − L_0)/L_0",
                Style::Line,
                t.iter()
                    .copied()
                    .zip(s.iter().map(|v| (v.length - r.l0) / r.l0))
                    .collect(),
                0,
            ),
            Series::new(
                "DEM H/L_0",
                Style::Line,
                t.iter().copied().zip(s.iter().map(|v| v.height / r.l0)).collect(),
                1,
            ),
        ],
        ..Default::default()
    };
    out.figure("figure", chart.to_svg()?);
    let en = Chart {
        title: format!("DEM energy evolution, a = {a:.2}"),
        footer: footer(&ctx.profile, ""),
        x_label: "t/τ_c".into(),
        y_label: "E/E_0".into(),
        series: vec![
            Series::new(
                "E_p/E_0",
                Style::Line,
                t.iter().copied().zip(s.iter().map(|v| v.ep / e0)).collect(),
                0,
            ),
            Series::new(
                "E_k/E_0",
                Style::Line,
                t.iter().copied().zip(s.iter().map(|v| (v.ekx + v.eky) / e0)).collect(),
                1,
            ),
            Series::new(
                "E_d/E_0 (eq 4.12)",
                Style::Line,
                t.iter()
                    .copied()
                    .zip(s.iter().map(|v| 1.0 - (v.ekx + v.eky + v.ep) / e0))
                    .collect(),
                2,
            ),
            Series::new(
                "frictional W_f/E_0",
                Style::Line,
                t.iter()
                    .copied()
                    .zip(s.iter().map(|v| v.ledger.frictional() / e0))
                    .collect(),
                3,
            ),
            Series::new(
                "collisional W_c/E_0",
                Style::Line,
                t.iter()
                    .copied()
                    .zip(s.iter().map(|v| v.ledger.collisional() / e0))
                    .collect(),
                4,
            ),
        ],
        ..Default::default()
    };
    out.figure("energy", en.to_svg()?);
    Ok(out)
}

/// Kind `dem-collapse`.
pub const COLLAPSE_KIND: Kind = Kind {
    name: "dem-collapse",
    version: 7,
    about: "DEM granular column collapse: L(t), H(t), energy ledger, until at rest",
    params: typed::<CollapseStageParams>,
    run: run_collapse_stage,
    explain: Some(explain_dem),
};

/// Parameters of a `dem-shear` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShearStageParams {
    /// Solver parameters.
    pub dem: DemParams,
    /// Softening.
    pub stiffness_factor: f64,
    /// Test settings.
    pub shear: ShearParams,
    /// Allowed |φ − 22.2°| for the claim [°].
    pub tolerance_deg: f64,
}

impl Default for ShearStageParams {
    fn default() -> Self {
        ShearStageParams {
            dem: DemParams::default(),
            stiffness_factor: 1.0,
            shear: ShearParams::default(),
            tolerance_deg: 1.0,
        }
    }
}

impl Validate for ShearStageParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_dem(&self.dem, self.stiffness_factor, &mut c);
        c.check(
            self.shear.pressures.len() >= 2 && self.shear.pressures.iter().all(|p| *p > 0.0),
            "shear.pressures",
            format!("{:?}", self.shear.pressures),
            "at least two pressures > 0 [Pa]",
        );
        c.in_open("shear.inertial_number", self.shear.inertial_number, 0.0, 1.0);
        c.positive("shear.strain", self.shear.strain);
        c.positive("tolerance_deg", self.tolerance_deg);
        c.issues
    }
}

fn run_shear(ctx: &StageCtx) -> anyhow::Result<Output> {
    let mut p: ShearStageParams = decode(ctx)?;
    super::calib::apply_calibration(ctx, &mut p.dem)?;
    let run = p.dem.softened(p.stiffness_factor);
    let psd = ctx.input("psd")?;
    let radii: Vec<f64> = col_f64(&psd.table("table")?, "d_m")?.iter().map(|d| 0.5 * d).collect();
    let total = p.shear.pressures.len();
    ctx.set_progress(0.0);
    let r = shear_test(&radii, &run, &p.shear)?;
    ctx.set_progress(1.0);
    let pts = &r.points;
    let mut out = Output::default();
    out.table(
        "table",
        frame(vec![
            ("pressure_pa", pts.iter().map(|q| q.pressure).collect()),
            ("sigma_n_pa", pts.iter().map(|q| q.sigma_n).collect()),
            ("tau_pa", pts.iter().map(|q| q.tau).collect()),
            ("mu", pts.iter().map(|q| q.mu).collect()),
            ("inertial_number", pts.iter().map(|q| q.inertial_number).collect()),
            ("velocity_m_s", pts.iter().map(|q| q.velocity).collect()),
        ])?,
    );
    let mut sp = Vec::new();
    let mut ss = Vec::new();
    let mut sm = Vec::new();
    for q in pts {
        for s in &q.series {
            sp.push(q.pressure);
            ss.push(s.strain);
            sm.push(if s.sigma_n > 0.0 { s.tau / s.sigma_n } else { f64::NAN });
        }
    }
    out.table(
        "series",
        frame(vec![
            ("pressure_pa", sp),
            ("shear_strain", ss),
            ("tau_over_sigma_n", sm),
        ])?,
    );
    out.scalar("friction_angle_deg", r.friction_angle_deg)
        .scalar("friction_angle_free_fit_deg", r.friction_angle_free_deg)
        .scalar("cohesion_free_fit_pa", r.cohesion_free)
        .scalar("grains", r.grains as f64)
        .scalar("pressures", total as f64)
        .scalar(
            "max_inertial_number",
            pts.iter().map(|q| q.inertial_number).fold(0.0, f64::max),
        )
        .scalar("mu_r", p.dem.rolling.mu_r)
        .scalar("stiffness_factor", p.stiffness_factor);
    out.claims.push(
        Claim::abs(
            "friction-angle",
            "\"A critical state friction angle of 22.2° was obtained\" (table 4.3: 22.2 ± 0.2°)",
            22.2,
            r.friction_angle_deg,
            p.tolerance_deg,
        )
        .calibrated(),
    );
    out.checks.push(Claim::at_most("quasi-static", "quasi-static shear: inertial number I < 1e-3 (SC-SHEAR-DEM; imposed through the shear rate) — largest measured I", 1.5e-3, pts.iter().map(|q| q.inertial_number).fold(0.0, f64::max)));
    let smax = pts.iter().map(|q| q.sigma_n).fold(0.0, f64::max) * 1.1 / 1e3;
    let slope = r.friction_angle_deg.to_radians().tan();
    let chart = Chart {
        title: ctx.caption.clone().unwrap_or_else(|| "Periodic shear test".into()),
        footer: footer(
            &ctx.profile,
            &format!(
                "{} grains, φ_cs = {:.2}°, stiffness factor {}",
                r.grains, r.friction_angle_deg, p.stiffness_factor
            ),
        ),
        x_label: "normal stress σ'_n [kPa]".into(),
        y_label: "critical-state shear stress τ [kPa]".into(),
        x_range: Some((0.0, smax)),
        y_range: Some((0.0, smax * slope.max(0.3) * 1.2)),
        series: vec![
            Series::new(
                "DEM, time-averaged critical state",
                Style::Points,
                pts.iter().map(|q| (q.sigma_n / 1e3, q.tau / 1e3)).collect(),
                0,
            ),
            Series::new(
                format!("fit through origin: tan φ, φ = {:.2}°", r.friction_angle_deg),
                Style::Dashed,
                vec![(0.0, 0.0), (smax, smax * slope)],
                1,
            ),
            Series::new(
                "stated: φ = 22.2°",
                Style::Dashed,
                vec![(0.0, 0.0), (smax, smax * 22.2f64.to_radians().tan())],
                7,
            ),
        ],
        ..Default::default()
    };
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `dem-shear`.
pub const SHEAR_KIND: Kind = Kind {
    name: "dem-shear",
    version: 2,
    about: "fig4-03: bi-periodic DEM shear test at several pressures -> critical-state friction angle",
    params: typed::<ShearStageParams>,
    run: run_shear,
    explain: Some(explain_dem),
};

/// Parameters of a `dem-compress` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CompressStageParams {
    /// Solver parameters.
    pub dem: DemParams,
    /// Softening.
    pub stiffness_factor: f64,
    /// Test settings.
    pub compression: CompressionParams,
}

impl Default for CompressStageParams {
    fn default() -> Self {
        CompressStageParams {
            dem: DemParams::default(),
            stiffness_factor: 1.0,
            compression: CompressionParams::default(),
        }
    }
}

impl Validate for CompressStageParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_dem(&self.dem, self.stiffness_factor, &mut c);
        c.positive("compression.strain_rate", self.compression.strain_rate);
        c.positive("compression.max_strain", self.compression.max_strain);
        c.check(
            self.compression.fit_strain > 0.0 && self.compression.fit_strain <= self.compression.max_strain,
            "compression.fit_strain",
            self.compression.fit_strain,
            "in (0, max_strain]",
        );
        c.in_open("compression.poisson", self.compression.poisson, -1.0, 0.5);
        c.issues
    }
}

fn run_compress(ctx: &StageCtx) -> anyhow::Result<Output> {
    let mut p: CompressStageParams = decode(ctx)?;
    super::calib::apply_calibration(ctx, &mut p.dem)?;
    let run = p.dem.softened(p.stiffness_factor);
    let col = column_from(ctx.input("column")?, run.density)?;
    let r = compression_test(&col, &run, &p.compression)?;
    let mut out = Output::default();
    out.table(
        "table",
        frame(vec![
            ("axial_strain", r.curve.iter().map(|c| c.strain).collect()),
            ("axial_stress_pa", r.curve.iter().map(|c| c.stress).collect()),
            ("lateral_stress_pa", r.curve.iter().map(|c| c.lateral).collect()),
        ])?,
    );
    // Measured at the stiffness it ran with (the sample is re-settled at that stiffness
    // first): no rescaling. A low-stress packing's modulus does not scale with k_n (its
    // seating response is dominated by contact creation, tests/dem_compression.rs).
    out.scalar("constrained_modulus_pa", r.modulus)
        .scalar("youngs_modulus_pa", r.young)
        .scalar("k0", r.k0)
        .scalar("height_m", r.height)
        .scalar("stiffness_factor", p.stiffness_factor);
    out.claims.push(Claim::rel("youngs-modulus", "E = 1.98e6 N/m², \"initial slope of the stress-strain plot of a uni-axial compression of a laterally confined granular column\" (I12: that slope is M; E = M(1+ν)(1−2ν)/(1−ν))", 1.98e6, r.young, 0.25));
    out.note(format!("Constrained modulus M = {:.3e} Pa (slope over the first {:.2} % strain), E = {:.3e} Pa with ν = {}; K_0 = {:.3}. Contact stiffness factor {} (the affine estimate of docs/definitions.md I12 scales with k_n).", r.modulus, 100.0 * p.compression.fit_strain, r.young, p.compression.poisson, r.k0, p.stiffness_factor));
    let chart = Chart {
        title: ctx
            .caption
            .clone()
            .unwrap_or_else(|| "Laterally confined compression".into()),
        footer: footer(
            &ctx.profile,
            &format!("M = {:.3e} Pa, E = {:.3e} Pa", r.modulus, r.young),
        ),
        x_label: "axial strain [-]".into(),
        y_label: "stress [Pa]".into(),
        series: vec![
            Series::new(
                "axial σ_yy",
                Style::Line,
                r.curve.iter().map(|c| (c.strain, c.stress)).collect(),
                0,
            ),
            Series::new(
                "lateral σ_xx",
                Style::Line,
                r.curve.iter().map(|c| (c.strain, c.lateral)).collect(),
                1,
            ),
            Series::new(
                format!("fit: slope M = {:.3e} Pa", r.modulus),
                Style::Dashed,
                vec![
                    (0.0, r.curve.first().map(|c| c.stress).unwrap_or(0.0)),
                    (
                        p.compression.fit_strain,
                        r.curve.first().map(|c| c.stress).unwrap_or(0.0) + r.modulus * p.compression.fit_strain,
                    ),
                ],
                2,
            ),
        ],
        ..Default::default()
    };
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `dem-compress`.
pub const COMPRESS_KIND: Kind = Kind {
    name: "dem-compress",
    version: 2,
    about: "laterally confined uniaxial compression of a DEM column -> constrained and Young's modulus",
    params: typed::<CompressStageParams>,
    run: run_compress,
    explain: Some(explain_dem),
};

/// Parameters of a `dem-work-precision` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WpParams {
    /// Base solver parameters (table 4.2).
    pub dem: DemParams,
    /// Variants: the first is the reference (stiffest, finest).
    pub variants: Vec<Variant>,
    /// Run control.
    pub run: CollapseParams,
    /// Perturbed starts per variant (the run-out is chaotic: errors are differences of
    /// ensemble means, with their standard error).
    pub ensemble: super::calib::Ensemble,
    /// Grain-count knob: the variant (label) run on the coarser column of the optional
    /// input `coarser` (the same a, fewer grains); empty = the second variant.
    #[serde(skip_serializing_if = "String::is_empty")]
    pub grains_at: String,
}

impl Default for WpParams {
    fn default() -> Self {
        WpParams {
            dem: DemParams::default(),
            variants: vec![],
            run: CollapseParams::default(),
            ensemble: super::calib::Ensemble::default(),
            grains_at: String::new(),
        }
    }
}

impl Validate for WpParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_dem(&self.dem, 1.0, &mut c);
        c.check(
            self.variants.len() >= 2,
            "variants",
            self.variants.len(),
            "at least two (the first is the reference)",
        );
        for (i, v) in self.variants.iter().enumerate() {
            c.in_open_closed(&format!("variants[{i}].stiffness_factor"), v.stiffness_factor, 0.0, 1.0);
            c.in_open_closed(&format!("variants[{i}].dt_fraction"), v.dt_fraction, 0.0, 0.5);
        }
        c.check(
            self.ensemble.members >= 3 && self.ensemble.members <= 64,
            "ensemble.members",
            self.ensemble.members,
            "an integer in [3, 64] (an error needs a spread)",
        );
        if !self.grains_at.is_empty() {
            c.check(
                self.variants.iter().any(|v| v.label == self.grains_at),
                "grains_at",
                &self.grains_at,
                "the label of one of `variants`",
            );
        }
        c.issues
    }
}

fn run_wp(ctx: &StageCtx) -> anyhow::Result<Output> {
    let mut p: WpParams = decode(ctx)?;
    super::calib::apply_calibration(ctx, &mut p.dem)?;
    let col = column_from(ctx.input("column")?, p.dem.density)?;
    let mut rows = work_precision(
        &col,
        &p.dem,
        &p.run,
        &p.variants,
        p.ensemble.members,
        p.ensemble.perturbation_m,
        p.ensemble.seed,
    )?;
    let mut grains: Vec<f64> = vec![col.state.len() as f64; rows.len()];
    // Grain-count knob: one variant on the coarser column, its error against the reference
    // (the stiffest, finest setting on the full column) as every other row's.
    if let Some(inp) = ctx.input_opt("coarser") {
        let coarse = column_from(inp, p.dem.density)?;
        let v = if p.grains_at.is_empty() {
            p.variants[1].clone()
        } else {
            p.variants
                .iter()
                .find(|v| v.label == p.grains_at)
                .cloned()
                .unwrap_or_else(|| p.variants[1].clone())
        };
        let mut r = work_precision(
            &coarse,
            &p.dem,
            &p.run,
            std::slice::from_ref(&v),
            p.ensemble.members,
            p.ensemble.perturbation_m,
            p.ensemble.seed,
        )?
        .remove(0);
        let (m0, s0, n0) = (rows[0].mean, rows[0].spread, rows[0].delta_l.len() as f64);
        let n = r.delta_l.len() as f64;
        r.error = (r.mean - m0).abs() / m0.abs().max(1e-12);
        r.error_spread = (r.spread * r.spread / n + s0 * s0 / n0).sqrt() / m0.abs().max(1e-12);
        r.variant.label = format!("{}-n{}", v.label, coarse.state.len());
        rows.push(r);
        grains.push(coarse.state.len() as f64);
    }
    let n_full = col.state.len() as f64;
    let mut out = Output::default();
    let idx: Vec<f64> = (0..rows.len()).map(|i| i as f64).collect();
    out.table(
        "table",
        frame(vec![
            ("variant", idx.clone()),
            (
                "stiffness_factor",
                rows.iter().map(|r| r.variant.stiffness_factor).collect(),
            ),
            ("dt_fraction", rows.iter().map(|r| r.variant.dt_fraction).collect()),
            ("grains", grains.clone()),
            ("dt_s", rows.iter().map(|r| r.dt).collect()),
            ("steps", rows.iter().map(|r| r.steps as f64).collect()),
            ("members", rows.iter().map(|r| r.delta_l.len() as f64).collect()),
            ("runout_norm_mean", rows.iter().map(|r| r.mean).collect()),
            ("runout_norm_std", rows.iter().map(|r| r.spread).collect()),
            ("hf_over_l0", rows.iter().map(|r| r.h_final_over_l0).collect()),
            ("runout_rel_error", rows.iter().map(|r| r.error).collect()),
            ("runout_rel_error_se", rows.iter().map(|r| r.error_spread).collect()),
            // the other quantities the column figures report: duration (fig 4.11's stop) and
            // final energy (fig 4.13's E_p(end)/E_p(0)), same ensemble-mean measure
            (
                "duration_tau_mean",
                rows.iter()
                    .map(|r| ensemble_error(&r.duration, &rows[0].duration).0)
                    .collect(),
            ),
            (
                "duration_rel_error",
                rows.iter()
                    .map(|r| ensemble_error(&r.duration, &rows[0].duration).1)
                    .collect(),
            ),
            (
                "duration_rel_error_se",
                rows.iter()
                    .map(|r| ensemble_error(&r.duration, &rows[0].duration).2)
                    .collect(),
            ),
            (
                "ep_final_mean",
                rows.iter()
                    .map(|r| ensemble_error(&r.ep_final, &rows[0].ep_final).0)
                    .collect(),
            ),
            (
                "ep_final_rel_error",
                rows.iter()
                    .map(|r| ensemble_error(&r.ep_final, &rows[0].ep_final).1)
                    .collect(),
            ),
            (
                "ep_final_rel_error_se",
                rows.iter()
                    .map(|r| ensemble_error(&r.ep_final, &rows[0].ep_final).2)
                    .collect(),
            ),
        ])?,
    );
    out.table(
        "timing",
        frame(vec![
            ("variant", idx),
            ("wall_s", rows.iter().map(|r| r.wall_s).collect()),
            ("settle_wall_s", rows.iter().map(|r| r.settle_wall_s).collect()),
        ])?,
    );
    out.scalar("reference_runout_mean", rows[0].mean)
        .scalar("reference_runout_std", rows[0].spread)
        .scalar("grains", col.state.len() as f64)
        .scalar("members", p.ensemble.members as f64);
    for r in &rows {
        let key = r.variant.label.replace(|c: char| !c.is_ascii_alphanumeric(), "_");
        out.scalar(&format!("error_{key}"), r.error)
            .scalar(&format!("error_se_{key}"), r.error_spread)
            .scalar(&format!("runout_mean_{key}"), r.mean)
            .scalar(&format!("runout_std_{key}"), r.spread);
        let (_, de, dse) = ensemble_error(&r.duration, &rows[0].duration);
        let (_, ee, ese) = ensemble_error(&r.ep_final, &rows[0].ep_final);
        out.scalar(&format!("duration_error_{key}"), de)
            .scalar(&format!("duration_error_se_{key}"), dse)
            .scalar(&format!("ep_final_error_{key}"), ee)
            .scalar(&format!("ep_final_error_se_{key}"), ese);
    }
    out.note(format!(
        "Each setting re-settled at its own stiffness and step, then {} perturbed starts (≤ {:.0e} m). Reference: {} (k factor {}, Δt = {:.2} t_c) → ΔL = {:.4} ± {:.4} (s.d.). Per setting, mean ± s.d. and one-collapse wall time: {}.",
        p.ensemble.members, p.ensemble.perturbation_m, rows[0].variant.label, rows[0].variant.stiffness_factor, rows[0].variant.dt_fraction, rows[0].mean, rows[0].spread,
        rows.iter().map(|r| format!("{} {:.3} ± {:.3}, {:.1} s", r.variant.label, r.mean, r.spread, r.wall_s)).collect::<Vec<_>>().join("; ")
    ));
    let mut factors: Vec<f64> = rows
        .iter()
        .zip(&grains)
        .skip(1)
        .filter(|(_, g)| **g == n_full)
        .map(|(r, _)| r.variant.stiffness_factor)
        .collect();
    factors.sort_by(|a, b| b.total_cmp(a));
    factors.dedup();
    let series = factors
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let sel: Vec<&crate::dem::column::WorkPrecisionRow> = rows
                .iter()
                .zip(&grains)
                .skip(1)
                .filter(|(r, g)| r.variant.stiffness_factor == *f && **g == n_full)
                .map(|(r, _)| r)
                .collect();
            Series::new(
                format!("k_n × {f} (mean error ± s.e.)"),
                Style::LinePoints,
                sel.iter().map(|r| (r.wall_s, r.error.max(1e-4))).collect(),
                k,
            )
            .with_errors(sel.iter().map(|r| r.error_spread).collect())
        })
        .collect::<Vec<_>>();
    let mut series = series;
    for (r, g) in rows.iter().zip(&grains).filter(|(_, g)| **g != n_full) {
        series.push(
            Series::new(
                format!("{g} grains (of {n_full}), {}", r.variant.label),
                Style::Points,
                vec![(r.wall_s, r.error.max(1e-4))],
                6,
            )
            .with_errors(vec![r.error_spread]),
        );
    }
    let chart = Chart::work_precision(
        ctx.caption.clone().unwrap_or_else(|| "DEM work-precision".into()),
        footer(
            &ctx.profile,
            &format!(
                "reference: {} (ΔL = {:.3} ± {:.3}), {} grains, {} starts per setting",
                rows[0].variant.label,
                rows[0].mean,
                rows[0].spread,
                col.state.len(),
                p.ensemble.members
            ),
        ),
        series,
    );
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `dem-work-precision`.
pub const WP_KIND: Kind = Kind {
    name: "dem-work-precision",
    version: 4,
    about: "DEM column run-out error vs wall time over stiffness and time-step fraction (ensembles, re-settled per setting)",
    params: typed::<WpParams>,
    run: run_wp,
    explain: None,
};

/// Gravity used by the DEM stages (for documentation of τ_c).
pub const GRAVITY: f64 = G;

#[cfg(test)]
mod network_tests {
    use super::*;

    #[test]
    fn contacts_at_rest_finds_each_overlap_once() {
        // Three 1 mm disks on a line, centres 1.9 mm apart (δ = 0.1 mm each), and a fourth
        // far away; a brute-force count over all pairs agrees.
        let mut s = State::new();
        for x in [0.0, 1.9e-3, 3.8e-3, 9.0e-3] {
            s.insert(x, 0.0, 1.0e-3, 2500.0);
        }
        s.insert(0.95e-3, 1.7e-3, 1.0e-3, 2500.0); // on top of the first two: 2 more contacts
        let c = contacts_at_rest(&s);
        let mut brute = 0;
        for i in 0..s.x.len() {
            for j in i + 1..s.x.len() {
                if ((s.x[i] - s.x[j]).powi(2) + (s.y[i] - s.y[j]).powi(2)).sqrt() < s.r[i] + s.r[j] {
                    brute += 1;
                }
            }
        }
        assert_eq!(c.len(), brute);
        assert_eq!(c.len(), 4);
        assert!((c[0].2 - 0.1e-3).abs() < 1e-12, "{c:?}");
        assert!(c.iter().all(|&(i, j, d)| i < j && d > 0.0));
    }
}
