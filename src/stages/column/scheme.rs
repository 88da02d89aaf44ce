//! Kind `column-scheme` (fig 4.12): the energy-balance scheme of eqs 4.8–4.9 drawn from a
//! deposit. Like every analysis kind of the column study (issue 9), it reads the collapse
//! stages' tables and makes tables, scalars, checks and claims; the figures are `plot` /
//! `snapshot` declarations.

use serde::{Deserialize, Serialize};

use super::common::{series, snap_of};
use crate::analysis::runout::{polygon_area_centroid, surface_profile};
use crate::pipeline::context::{Claim, Output, StageCtx, frame};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Parameters of a `column-scheme` stage.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct SchemeParams {
    /// D01 linking gap of the measured deposit's main mass [d̄].
    pub link_gap: f64,
    /// Width of the surface-profile bins [d̄].
    pub bin: f64,
}

impl Default for SchemeParams {
    fn default() -> Self {
        SchemeParams {
            link_gap: 0.5,
            bin: 1.0,
        }
    }
}

impl Validate for SchemeParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.check(
            self.link_gap >= 0.0 && self.link_gap.is_finite(),
            "link_gap",
            self.link_gap,
            "≥ 0 [d̄]",
        );
        c.positive("bin", self.bin);
        c.issues
    }
}

/// Shape ids of the scheme table (column `shape`; the plot filters on them).
pub mod shape {
    /// Initial column outline.
    pub const INITIAL: f64 = 0.0;
    /// The scheme's deposit outline (flat top to x_t, straight slope to L_f).
    pub const DEPOSIT: f64 = 1.0;
    /// Destabilised triangle.
    pub const DESTABILISED: f64 = 2.0;
    /// Deposited triangle.
    pub const DEPOSITED: f64 = 3.0;
    /// Centroid G of the destabilised mass before (one point).
    pub const G_BEFORE: f64 = 4.0;
    /// Centroid G of the deposited mass after (one point).
    pub const G_AFTER: f64 = 5.0;
    /// Measured free surface of the run's final deposit.
    pub const MEASURED: f64 = 6.0;
}

fn run_scheme(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: SchemeParams = decode(ctx)?;
    let inp = ctx.input("run")?;
    let sc = inp.scalars()?;
    let get = |k: &str| {
        sc.get(k)
            .copied()
            .ok_or_else(|| anyhow::anyhow!("input `{}` has no scalar `{k}`", inp.id))
    };
    let (l0, h0, lf) = (get("l0_m")?, get("h0_m")?, get("lf_m")?);
    let ep = series(inp, "table", "ep_j")?;
    let g = 9.81;
    let xt = 2.0 * l0 - lf;
    // Geometry of eqs 4.8–4.9 (docs/definitions.md fig4-12).
    let initial = [(0.0, 0.0), (l0, 0.0), (l0, h0), (0.0, h0)];
    let deposit = [(0.0, 0.0), (lf, 0.0), (xt, h0), (0.0, h0)];
    let dest = [(xt, h0), (l0, h0), (l0, 0.5 * h0)];
    let dep = [(l0, 0.0), (lf, 0.0), (l0, 0.5 * h0)];
    let (a_dest, g0) = polygon_area_centroid(&dest);
    let (a_dep, g1) = polygon_area_centroid(&dep);
    let (a_deposit, _) = polygon_area_centroid(&deposit);
    let dl = lf - l0;
    // Bulk density of the column (per m of thickness) from its own E_p(0) = ρ g L_0 H_0²/2.
    let rho = 2.0 * ep[0] / (g * l0 * h0 * h0);
    let de_scheme = rho * g * a_dest * (g0.1 - g1.1);
    let de_eq48 = rho * g * dl * h0 * h0 / 6.0;
    let mu_e = h0 / dl;
    let w_mu = mu_e * rho * g * a_dest * (g1.0 - g0.0);
    let de_run = ep[0] - ep[ep.len() - 1];
    // The run's deposit.
    let snap = snap_of(inp, None)?;
    let d = snap.d_mean();
    let main = snap.main(p.link_gap * d);
    let prof = surface_profile(&main.x, &main.y, &main.half, p.bin * d);
    let scheme_h = |x: f64| {
        if x <= xt {
            h0
        } else if x <= lf {
            h0 * (lf - x) / (lf - xt)
        } else {
            0.0
        }
    };
    let inside: Vec<&(f64, f64)> = prof.iter().filter(|q| q.0 <= lf).collect();
    let rms =
        (inside.iter().map(|q| (q.1 - scheme_h(q.0)).powi(2)).sum::<f64>() / inside.len().max(1) as f64).sqrt() / h0;
    // Table: polylines in mm, one shape id per outline.
    let (mut s, mut xs, mut ys) = (Vec::new(), Vec::new(), Vec::new());
    let mut poly = |id: f64, pts: &[(f64, f64)], close: bool| {
        for q in pts.iter().chain(if close { pts.first() } else { None }) {
            s.push(id);
            xs.push(q.0 * 1e3);
            ys.push(q.1 * 1e3);
        }
    };
    poly(shape::INITIAL, &initial, true);
    poly(shape::DEPOSIT, &deposit, true);
    poly(shape::DESTABILISED, &dest, true);
    poly(shape::DEPOSITED, &dep, true);
    poly(shape::G_BEFORE, &[g0], false);
    poly(shape::G_AFTER, &[g1], false);
    let meas: Vec<(f64, f64)> = prof.iter().map(|q| (q.0, q.1)).collect();
    poly(shape::MEASURED, &meas, false);
    let mut out = Output::default();
    out.table("table", frame(vec![("shape", s), ("x_mm", xs), ("y_mm", ys)])?);
    out.scalar("l0_mm", l0 * 1e3)
        .scalar("h0_mm", h0 * 1e3)
        .scalar("lf_mm", lf * 1e3)
        .scalar("x_t_mm", xt * 1e3)
        .scalar("runout_norm", dl / l0)
        .scalar("destabilised_area_over_l0h0", a_dest / (l0 * h0))
        .scalar("g_dx_over_runout", (g1.0 - g0.0) / dl)
        .scalar("g_dy_over_h0", (g0.1 - g1.1) / h0)
        .scalar("delta_e_scheme_j", de_eq48)
        .scalar("delta_e_run_j", de_run)
        .scalar("delta_e_scheme_over_run", de_eq48 / de_run)
        .scalar("mu_e_geometric", mu_e)
        .scalar("surface_rms_over_h0", rms)
        .scalar("deposit_t_over_tau_c", snap.t);
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs().max(1e-300);
    out.checks.push(Claim::at_most(
        "scheme-valid",
        "the scheme needs x_t = 2L_0 − L_f ≥ 0, i.e. ΔL ≤ 1 (docs/definitions.md fig4-12)",
        1.0,
        dl / l0,
    ));
    out.checks.push(Claim::at_most("destabilised-mass", "\"the amount of mass destabilised ¼(L_f − L_0)H_0\": shoelace area of the drawn triangle against ¼(L_f − L_0)H_0 (relative)", 1e-9, rel(a_dest, 0.25 * dl * h0)));
    out.checks.push(Claim::at_most(
        "deposited-equals-destabilised",
        "volume conservation: deposited triangle area = destabilised (relative)",
        1e-9,
        rel(a_dep, a_dest),
    ));
    out.checks.push(Claim::at_most(
        "deposit-area",
        "volume conservation: scheme deposit area = L_0 H_0 (relative)",
        1e-9,
        rel(a_deposit, l0 * h0),
    ));
    out.checks.push(Claim::at_most(
        "two-thirds-runout",
        "\"over two thirds of the run-out distance 2(L_f − L_0)/3\": horizontal shift of G (relative)",
        1e-9,
        rel(g1.0 - g0.0, 2.0 * dl / 3.0),
    ));
    out.checks.push(Claim::at_most(
        "g-drop",
        "G drops from 5H_0/6 to H_0/6, by 2H_0/3 (relative)",
        1e-9,
        rel(g0.1 - g1.1, 2.0 * h0 / 3.0),
    ));
    out.checks.push(Claim::at_most(
        "eq-4-8",
        "δE = ρ g ΔA Δy_G equals eq 4.8's (1/6) g ρ (L_f − L_0) H_0² (relative)",
        1e-9,
        rel(de_scheme, de_eq48),
    ));
    out.checks.push(Claim::at_most(
        "eq-4-9",
        "W_μ = μ_e ρ g ΔA Δx_G with μ_e = H_0/(L_f − L_0) equals δE (eqs 4.8–4.9: μ_e (L_f − L_0) = H_0; relative)",
        1e-9,
        rel(w_mu, de_eq48),
    ));
    out.note(format!(
        "Scheme from {}'s L_f = {:.2} mm (L_0 = {:.2} mm, H_0 = {:.2} mm, ΔL = {:.3}); measured surface: main mass (edges within {} d̄) of the run's last snapshot at t = {:.2} τ_c, bins of {} d̄. The scheme's δE (eq 4.8) is {:.2} × the run's E_p(0) − E_p(end); RMS distance between the scheme's and the measured surface over [0, L_f]: {:.3} H_0.",
        inp.id, lf * 1e3, l0 * 1e3, h0 * 1e3, dl / l0, p.link_gap, snap.t, p.bin, de_eq48 / de_run, rms
    ));
    Ok(out)
}

/// Kind `column-scheme`.
pub const SCHEME_KIND: Kind = Kind {
    name: "column-scheme",
    source: file!(),
    method: None,
    version: 1,
    about: "energy-balance scheme of eqs 4.8–4.9 from a run's L_f, with its identities as checks and the run's measured deposit surface",
    params: typed::<SchemeParams>,
    run: run_scheme,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[("run", crate::pipeline::context::Arity::One)]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "delta_e_run_j", "delta_e_scheme_j", "delta_e_scheme_over_run", "deposit_t_over_tau_c",
            "destabilised_area_over_l0h0", "g_dx_over_runout", "g_dy_over_h0", "h0_mm", "l0_mm", "lf_mm",
            "mu_e_geometric", "runout_norm", "surface_rms_over_h0", "x_t_mm",
        ],
        tables: &[crate::stages::kind::TableDecl {
            name: "table",
            columns: &["shape", "x_mm", "y_mm"],
        }],
        measurements: &[],
        texts: &[],
    },
    reads: None,
    cost: None,
    atlas: None,
};
