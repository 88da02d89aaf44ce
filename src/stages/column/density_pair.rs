//! Kind `column-density-pair` (figs 4.19–4.21): the r = 6 dense/loose column pair.

use serde::{Deserialize, Serialize};

use super::analysis::value_at;
use super::common::{series, snap_of};
use crate::analysis::runout::{poly_r2, surface_profile};
use crate::pipeline::context::{Claim, InputRef, Output, StageCtx};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Parameters of a `column-density-pair` stage (roles loose, dense: collapses;
/// loose_prep, dense_prep: their samples; emin, emax: the reference packings, P4a).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct PairParams {
    /// The chapter's relative densities (dense, loose) [-].
    pub target_dr: [f64; 2],
    /// Tolerance on D_r (a check on our preparation, not a claim).
    pub dr_tolerance: f64,
    /// Time at which the compaction loss is read [τ_c].
    pub t_compare: f64,
    /// D01 linking gap for the deposit's main mass [d̄].
    pub link_gap: f64,
    /// Surface-profile bins [d̄].
    pub bin: f64,
    /// "More parabolic": the loose deposit's R² gain of a quadratic over a linear fit of
    /// h(x) beyond L_0 must exceed the dense one's by at least this.
    pub shape_margin: f64,
}

impl Default for PairParams {
    fn default() -> Self {
        PairParams {
            target_dr: [0.74, 0.22],
            dr_tolerance: 0.1,
            t_compare: 6.0,
            link_gap: 0.5,
            bin: 1.0,
            shape_margin: 0.01,
        }
    }
}

impl Validate for PairParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        for (k, v) in self.target_dr.iter().enumerate() {
            c.in_closed(&format!("target_dr[{k}]"), *v, 0.0, 1.0);
        }
        c.positive("dr_tolerance", self.dr_tolerance);
        c.positive("t_compare", self.t_compare);
        c.positive("bin", self.bin);
        c.positive("shape_margin", self.shape_margin);
        c.issues
    }
}

/// Packing fraction of a prepared sample for D_r: the prep stage's window measure
/// `packing_fraction_core` (solid area / window area, the window ≥ 2 d̄ from the walls and
/// the free surface; D09's "fixed window"). The plain Voronoi cells of
/// `analysis::voronoi` are not used here: with r = 6 a bisector between a 2 mm and a
/// 0.33 mm grain cuts through the large one, and interior-cell φ came out 0.94–0.96.
fn sample_phi(inp: &InputRef) -> anyhow::Result<f64> {
    inp.scalar("packing_fraction_core")
}

/// R² of linear and quadratic fits of the deposit surface h(x) beyond x = L_0 (the
/// front, where the two deposits differ: docs/definitions.md fig4-20).
fn front_shape(inp: &InputRef, l0: f64, gap_d: f64, bin_d: f64) -> anyhow::Result<(f64, f64, usize)> {
    let snap = snap_of(inp, None)?;
    let d = snap.d_mean();
    let main = snap.main(gap_d * d);
    let prof: Vec<(f64, f64)> = surface_profile(&main.x, &main.y, &main.half, bin_d * d)
        .into_iter()
        .filter(|q| q.0 >= l0 && q.1 > 0.0)
        .collect();
    let (x, h): (Vec<f64>, Vec<f64>) = prof.iter().cloned().unzip();
    Ok((poly_r2(&x, &h, 1), poly_r2(&x, &h, 2), x.len()))
}

fn value_at_t(t: &[f64], y: &[f64], at: f64) -> f64 {
    value_at(t, y, at)
}

fn run_pair(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: PairParams = decode(ctx)?;
    let mut out = Output::default();
    // D09: relative density from the P4a reference packings.
    let phi_min_e = sample_phi(ctx.input("emin")?)?;
    let phi_max_e = sample_phi(ctx.input("emax")?)?;
    let e = |phi: f64| (1.0 - phi) / phi;
    let (e_min, e_max) = (e(phi_min_e), e(phi_max_e));
    anyhow::ensure!(
        e_max > e_min,
        "reference packings: e_max = {e_max:.4} (input `{}`) is not above e_min = {e_min:.4} (input `{}`): the loosest protocol packed denser",
        ctx.input("emax")?.id,
        ctx.input("emin")?.id
    );
    out.scalar("e_min", e_min)
        .scalar("e_max", e_max)
        .scalar("phi_ref_dense", phi_min_e)
        .scalar("phi_ref_loose", phi_max_e);
    let mut dr = [0.0; 2];
    let mut ek_peak = [0.0; 2];
    let mut ed_at = [0.0; 2];
    let mut ed_tau = [0.0; 2];
    let mut runout = [0.0; 2];
    let mut shape_gain = [0.0; 2];
    for (k, role) in ["dense", "loose"].iter().enumerate() {
        let prep = ctx.input(&format!("{role}_prep"))?;
        let phi = sample_phi(prep)?;
        dr[k] = (e_max - e(phi)) / (e_max - e_min);
        let run = ctx.input(role)?;
        let t = series(run, "table", "t_over_tau_c")?;
        let ek = series(run, "table", "ek_over_e0")?;
        let ed = series(run, "table", "ed_over_e0")?;
        ek_peak[k] = ek.iter().cloned().fold(0.0, f64::max);
        ed_at[k] = value_at_t(&t, &ed, p.t_compare);
        ed_tau[k] = value_at_t(&t, &ed, 1.0);
        runout[k] = run.scalar("runout_norm")?;
        let (r1, r2, n) = front_shape(run, run.scalar("l0_m")?, p.link_gap, p.bin)?;
        shape_gain[k] = r2 - r1;
        out.scalar(&format!("{role}_phi"), phi)
            .scalar(&format!("{role}_dr"), dr[k])
            .scalar(&format!("{role}_runout_norm"), runout[k])
            .scalar(&format!("{role}_ek_peak_over_e0"), ek_peak[k])
            .scalar(&format!("{role}_ed_over_e0_at_compare"), ed_at[k])
            .scalar(&format!("{role}_front_r2_linear"), r1)
            .scalar(&format!("{role}_front_r2_quadratic"), r2)
            .scalar(&format!("{role}_front_bins"), n as f64)
            .scalar(
                &format!("{role}_t_end_over_tau_c"),
                t.last().copied().unwrap_or(f64::NAN),
            );
        out.checks.push(Claim::abs(&format!("{role}-relative-density"), &format!("{role} sample: D_r = (e_max − e)/(e_max − e_min) against the chapter's {:.0} % (window φ ≥ 2 d̄ inside; e_min/e_max from the P4a reference packings; set by the deposition friction, calibrated)", 100.0 * p.target_dr[k]), p.target_dr[k], dr[k], p.dr_tolerance).calibrated());
    }
    if t_end_short(&out, p.t_compare) {
        out.note(format!(
            "A run ended before t = {} τ_c: its E_d is read at its last sample.",
            p.t_compare
        ));
    }
    out.claims.push(Claim::at_least("r6-dense-longer-runout", "fig 4.19: \"the dense granular column exhibits longer run-out distance\" (r = 6, a = 0.8) — ΔL_dense/ΔL_loose (> 1)", 1.0, runout[0] / runout[1]));
    out.claims.push(Claim::abs("r6-peak-ek", "fig 4.21: \"The peak kinetic energy in the dense condition is ~20 % higher than the loose condition\" — max E_k/E_0, dense over loose (tolerance 0.1)", 1.2, ek_peak[0] / ek_peak[1], 0.1));
    out.claims.push(Claim::abs(
        "r6-compaction-loss",
        &format!("fig 4.21: \"almost 20 % of the normalised initial potential energy … is lost in densification\" — (E_d/E_0)_loose − (E_d/E_0)_dense at t = {} τ_c, both at rest (our metric; tolerance 0.07)", p.t_compare),
        0.2, ed_at[1] - ed_at[0], 0.07,
    ));
    out.claims.push(Claim::at_least(
        "r6-front-shape",
        &format!("fig 4.20: \"The loose column exhibits a more parabolic final deposit profile … the dense column … a triangular deposit at the front\" — (R²_quad − R²_lin) of h(x) beyond L_0, loose minus dense (≥ {}, stated)", p.shape_margin),
        p.shape_margin, shape_gain[1] - shape_gain[0],
    ));
    out.scalar("runout_ratio", runout[0] / runout[1])
        .scalar("ek_peak_ratio", ek_peak[0] / ek_peak[1])
        .scalar("compaction_loss_over_e0", ed_at[1] - ed_at[0])
        .scalar("compaction_loss_over_e0_at_tau_c", ed_tau[1] - ed_tau[0]);
    out.note(format!(
        "D_r: e = (1 − φ)/φ with φ the packing fraction of each prepared sample in a window ≥ 2 d̄ from its walls and surface (the plain Voronoi cells are biased at r = 6); e_min = {e_min:.4} (φ = {phi_min_e:.4}, frictionless deposition) and e_max = {e_max:.4} (φ = {phi_max_e:.4}, high-friction deposition) from the P4a reference packings (docs/definitions.md P4a). Dense D_r = {:.0} %, loose {:.0} % (chapter 74 %, 22 %). Compaction loss (our metric for \"20 % lost in densification\"): (E_d/E_0)_loose − (E_d/E_0)_dense = {:.3} at {} τ_c ({:.3} at τ_c).",
        100.0 * dr[0], 100.0 * dr[1], ed_at[1] - ed_at[0], p.t_compare, ed_tau[1] - ed_tau[0]
    ));
    Ok(out)
}

fn t_end_short(out: &Output, t: f64) -> bool {
    ["dense", "loose"].iter().any(|r| {
        out.scalars
            .get(&format!("{r}_t_end_over_tau_c"))
            .is_some_and(|v| *v < t - 0.05)
    })
}

/// Kind `column-density-pair`.
pub const PAIR_KIND: Kind = Kind {
    name: "column-density-pair",
    source: file!(),
    method: None,
    version: 1,
    about: "dense/loose column pair (r = 6): relative densities from reference packings, run-out, peak E_k, compaction loss and deposit front shape against figs 4.19–4.21",
    params: typed::<PairParams>,
    run: run_pair,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[
        ("loose", crate::pipeline::context::Arity::One),
        ("dense", crate::pipeline::context::Arity::One),
        ("loose_prep", crate::pipeline::context::Arity::One),
        ("dense_prep", crate::pipeline::context::Arity::One),
        ("emin", crate::pipeline::context::Arity::One),
        ("emax", crate::pipeline::context::Arity::One),
    ]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "compaction_loss_over_e0", "compaction_loss_over_e0_at_tau_c", "dense_dr", "dense_ed_over_e0_at_compare",
            "dense_ek_peak_over_e0", "dense_front_bins", "dense_front_r2_linear", "dense_front_r2_quadratic",
            "dense_phi", "dense_runout_norm", "dense_t_end_over_tau_c", "e_max", "e_min", "ek_peak_ratio", "loose_dr",
            "loose_ed_over_e0_at_compare", "loose_ek_peak_over_e0", "loose_front_bins", "loose_front_r2_linear",
            "loose_front_r2_quadratic", "loose_phi", "loose_runout_norm", "loose_t_end_over_tau_c", "phi_ref_dense",
            "phi_ref_loose", "runout_ratio",
        ],
        tables: &[],
        measurements: &[
            "r6-compaction-loss", "r6-dense-longer-runout", "r6-front-shape", "r6-peak-ek",
        ],
        texts: &[],
    },
    reads: None,
    cost: None,
    atlas: None,
};
