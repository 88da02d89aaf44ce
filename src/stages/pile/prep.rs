//! Kind `dem-pile-prep` (fig4-23; chapter 4 §4.4, docs/definitions.md SC-PILE): pour, shift
//! the wall, relax to rest; slope, packing, height.

use serde::{Deserialize, Serialize};

use super::common::{check_dem_pile, explain_pile};
use crate::analysis::pile::{D_NORM, envelope_packing, slope_deg, surface_profile};
use crate::dem::pile::{PileParams, prepare_pile};
use crate::dem::pour::pour;
use crate::dem::{DemParams, State};
use crate::pipeline::context::{Claim, Output, StageCtx, col_f64, frame};
use crate::report::plot::footer;
use crate::report::snapshot::{Segment, Shape, Snapshot};
use crate::stages::generic::psd::PsdParams;
use crate::stages::kind::{CostCtx, Work};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Parameters of a `dem-pile-prep` stage (SC-PILE, fig4-23).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PrepParams {
    /// Solver parameters of the pile grains (chapter: ρ = 2600, μ = 0.4; the rest UNSPEC).
    pub dem: DemParams,
    /// Softening of k_n, k_t, k_r (Δt grows by 1/√factor).
    pub stiffness_factor: f64,
    /// Number of PSD grains poured (0 = all of the PSD stage's).
    pub grains: usize,
    /// Pouring, wall shift and the rest criterion.
    pub pile: PileParams,
    /// The inclined part of the surface used for the slope fit, as fractions of L_0.
    pub slope_window: [f64; 2],
    /// Whether rolling resistance μ_r was chosen to meet the slope (then the slope claim is
    /// marked calibrated).
    pub slope_calibrated: bool,
}

impl Default for PrepParams {
    fn default() -> Self {
        PrepParams {
            dem: DemParams::default(),
            stiffness_factor: 1.0,
            grains: 0,
            pile: Default::default(),
            slope_window: [0.15, 0.85],
            slope_calibrated: true,
        }
    }
}

impl Validate for PrepParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        check_dem_pile(&self.dem, self.stiffness_factor, &mut c);
        c.positive("pile.deposition.width", self.pile.deposition.width);
        c.check(
            self.pile.shift_to > 1.0,
            "pile.shift_to",
            self.pile.shift_to,
            "> 1 (a multiple of the box width)",
        );
        c.positive("pile.max_time", self.pile.max_time);
        c.check(
            self.pile.min_time >= 0.0 && self.pile.min_time < self.pile.max_time,
            "pile.min_time",
            self.pile.min_time,
            ">= 0 and < pile.max_time",
        );
        // "when all grains come to rest": a looser criterion would hand the excitation a
        // pile still moving.
        c.check(
            self.pile.settle_ratio > 0.0 && self.pile.settle_ratio <= 1e-4,
            "pile.settle_ratio",
            self.pile.settle_ratio,
            "in (0, 1e-4]: (E_k + E_rot)/E_p of a pile at rest",
        );
        c.check(
            self.pile.settle_speed > 0.0 && self.pile.settle_speed <= 1e-2,
            "pile.settle_speed",
            self.pile.settle_speed,
            "in (0, 0.01] √(g d̄): every grain at rest",
        );
        let [a, b] = self.slope_window;
        c.check(
            a >= 0.0 && b <= 1.0 && a < b,
            "slope_window",
            format!("[{a}, {b}]"),
            "0 <= from < to <= 1 (fractions of L_0)",
        );
        c.issues
    }
}

/// Packing fraction of the interior: grains with centres more than 2 d below the surface,
/// 2 d above the base and 2 d from the wall, over the area of that region (raster-free:
/// Σπr² of the centres inside / region area).
fn interior_packing(s: &State, prof: &[(f64, f64)], l0: f64, d: f64) -> f64 {
    let bin = prof.get(1).map(|q| q.0 - prof[0].0).unwrap_or(2.0 * d);
    let mut solid = 0.0;
    for i in 0..s.len() {
        let top = crate::analysis::pile::surface_at(prof, s.x[i], l0);
        if s.x[i] > 2.0 * d && s.y[i] > 2.0 * d && s.y[i] < top - 2.0 * d {
            solid += std::f64::consts::PI * s.r[i] * s.r[i];
        }
    }
    let area: f64 = prof
        .iter()
        .filter(|q| q.1.is_finite() && q.0 > 2.0 * d)
        .map(|q| (q.1 - 4.0 * d).max(0.0) * bin)
        .sum();
    if area > 0.0 { solid / area } else { f64::NAN }
}

fn grains_frame(x: &[f64], y: &[f64], r: &[f64]) -> anyhow::Result<polars::prelude::DataFrame> {
    frame(vec![("x_m", x.to_vec()), ("y_m", y.to_vec()), ("r_m", r.to_vec())])
}

fn run_prep(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: PrepParams = decode(ctx)?;
    let run = p.dem.softened(p.stiffness_factor);
    let psd = ctx.input("psd")?;
    let mut radii: Vec<f64> = col_f64(&psd.table("table")?, "d_m")?.iter().map(|d| 0.5 * d).collect();
    if p.grains > 0 {
        anyhow::ensure!(
            p.grains <= radii.len(),
            "`grains` = {} but the PSD stage `{}` has {} grains",
            p.grains,
            psd.id,
            radii.len()
        );
        radii.truncate(p.grains);
    }
    let clock = std::time::Instant::now();
    // one layer of the rows the grains fill (crate::dem::pour: the deposition's wait)
    let pp = PileParams {
        deposition: pour(&radii, &p.pile.deposition),
        ..p.pile.clone()
    };
    let pile = prepare_pile(&radii, &run, &pp)?;
    let wall = clock.elapsed().as_secs_f64();
    let s = &pile.state;
    let d = D_NORM;
    let bin = 2.0 * d;
    let prof = surface_profile(&s.x, &s.y, &s.r, pile.l0, bin);
    let solid: f64 = (0..s.len())
        .filter(|&i| s.x[i] <= pile.l0)
        .map(|i| std::f64::consts::PI * s.r[i] * s.r[i])
        .sum();
    let phi = envelope_packing(&prof, bin, solid);
    let slope = slope_deg(&prof, pile.l0, p.slope_window[0], p.slope_window[1]);
    let mut out = Output::default();
    out.table("table", grains_frame(&s.x, &s.y, &s.r)?);
    out.table(
        "surface",
        frame(vec![
            ("x_m", prof.iter().map(|q| q.0).collect()),
            ("top_m", prof.iter().map(|q| q.1).collect()),
        ])?,
    );
    out.scalar("n", s.len() as f64)
        .scalar("l0_m", pile.l0)
        .scalar("h0_m", pile.h0)
        .scalar("l0_over_d", pile.l0 / d)
        .scalar("h0_over_d", pile.h0 / d)
        .scalar("slope_deg", slope)
        .scalar("packing_fraction", phi)
        .scalar("settled", if pile.settled { 1.0 } else { 0.0 })
        .scalar("relax_time_s", pile.relax_time)
        .scalar("ke_over_ep", pile.ke_over_ep)
        .scalar("v_max_over_sqrt_gd", pile.v_max / (run.gravity * d).sqrt())
        .scalar("stiffness_factor", p.stiffness_factor);
    let mut slope_claim = Claim::abs(
        "slope",
        "\"A stable granular slope of 13.2° is obtained when all grains come to rest\" (line fit of the top grain per 2d bin over the inclined part)",
        13.2,
        slope,
        1.0,
    );
    if p.slope_calibrated {
        slope_claim = slope_claim.calibrated();
    }
    out.claims.push(slope_claim);
    out.claims.push(Claim::abs(
        "packing",
        "\"This procedure leads to a mean packing fraction ≃ 0.82\" (solid area under the free surface, D09)",
        0.82,
        phi,
        0.02,
    ));
    // "of the order of 80 d" is the 13 000-grain pile's; a smaller pile (quick profile) is
    // checked against the right triangle of its own solid area at 13.2° and φ = 0.82.
    if s.len() as f64 >= 0.9 * 13000.0 {
        out.claims.push(Claim::rel("height", "\"The height of the pile being of the order of 80d\" (H_0/d; a 13 000-grain pile at 13.2° and φ = 0.82 is 76 d high)", 80.0, pile.h0 / d, 0.1));
    } else {
        let h_tri = (2.0 * solid / 0.82 * 13.2f64.to_radians().tan()).sqrt() / d;
        out.checks.push(Claim::rel("height-small-pile", &format!("H_0/d of this {}-grain pile against the triangle of its solid area at 13.2° and φ = 0.82 (the chapter's 80 d holds for 13 000 grains)", s.len()), h_tri, pile.h0 / d, 0.15));
    }
    out.scalar("packing_fraction_interior", interior_packing(s, &prof, pile.l0, d));
    out.checks.push(Claim::at_most("at-rest", "pile at rest before the excitation: (E_k+E_rot)/E_p below pile.settle_ratio and every grain below pile.settle_speed √(g d̄) (1 = not settled)", 0.0, if pile.settled { 0.0 } else { 1.0 }));
    let segs = vec![
        Segment {
            a: (0.0, 0.0),
            b: (0.0, 1.15 * pile.h0),
            color: "black",
            width: 2.5,
            dashed: false,
        },
        Segment {
            a: (0.0, 0.0),
            b: (1.05 * pile.l0, 0.0),
            color: "black",
            width: 2.5,
            dashed: false,
        },
        Segment {
            a: (0.0, pile.h0),
            b: (pile.h0 / (13.2f64).to_radians().tan(), 0.0),
            color: "#b00020",
            width: 1.2,
            dashed: true,
        },
    ];
    let snap = Snapshot {
        title: ctx.caption.clone().unwrap_or_else(|| "Granular pile".into()),
        footer: footer(
            &ctx.profile,
            &format!(
                "N = {}, H_0 = {:.1} d, L_0 = {:.1} d, measured slope {:.1}° (red dashed: 13.2° from H_0), φ = {:.3}; k_n × {}",
                s.len(),
                pile.h0 / d,
                pile.l0 / d,
                slope,
                phi,
                p.stiffness_factor
            ),
        ),
        x: &s.x,
        y: &s.y,
        half: &s.r,
        shape: Shape::Disk,
        field: None,
        black: None,
        fill: None,
        segments: segs,
        view: Some((-0.02 * pile.l0, 1.05 * pile.l0, -0.02 * pile.l0, 1.3 * pile.h0)),
        width_px: 900.0,
    };
    out.figure("figure", snap.to_svg());
    out.note(format!(
        "Poured into a {:.1} mm box, right wall shifted to {}× its width, relaxed {:.2} s: settled = {} ((E_k+E_rot)/E_p = {:.1e}, fastest grain {:.1e} √(g d)); wall time {wall:.1} s. Contact parameters of the pile are not in the chapter: see stages/pile/dem.yaml and stages/pile/prep.yaml.",
        p.pile.deposition.width * 1e3, p.pile.shift_to, pile.relax_time, pile.settled, pile.ke_over_ep, pile.v_max / (run.gravity * d).sqrt()
    ));
    Ok(out)
}

/// Kind `dem-pile-prep`.
pub const PREP_KIND: Kind = Kind {
    name: "dem-pile-prep",
    source: file!(),
    method: Some(crate::engines::Method::Dem),
    version: 5,
    about: "fig4-23: granular pile poured in a box whose right wall is then shifted; relaxed to rest",
    params: typed::<PrepParams>,
    run: run_prep,
    explain: Some(explain_pile),
    roles: crate::stages::kind::Roles::Fixed(&[("psd", crate::pipeline::context::Arity::One)]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "h0_m", "h0_over_d", "ke_over_ep", "l0_m", "l0_over_d", "n", "packing_fraction",
            "packing_fraction_interior", "relax_time_s", "settled", "slope_deg", "stiffness_factor",
            "v_max_over_sqrt_gd",
        ],
        tables: &[
            crate::stages::kind::TableDecl {
                name: "surface",
                columns: &["top_m", "x_m"],
            },
            crate::stages::kind::TableDecl {
                name: "table",
                columns: &["r_m", "x_m", "y_m"],
            },
        ],
        measurements: &["height", "packing", "slope"],
        texts: &[],
    },
    reads: None,
    cost: Some(cost),
    atlas: None,
};

/// Cost: grains poured; steps per simulated second times the longest pouring time.
fn cost(c: &CostCtx) -> Option<Work> {
    let p: PrepParams = c.typed()?;
    Some((
        vec![
            ("grains", grains(c)?),
            ("steps", p.dem.steps_per_second(p.stiffness_factor) * p.pile.max_time),
        ],
        false,
    ))
}

/// Grains of a pile preparation: its `grains` param when set (> 0), else all of its PSD's.
pub(crate) fn grains(c: &CostCtx) -> Option<f64> {
    let p: PrepParams = c.typed()?;
    if p.grains > 0 {
        Some(p.grains as f64)
    } else {
        c.input::<PsdParams>("psd").map(|s| s.n as f64)
    }
}
