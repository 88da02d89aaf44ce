//! Kind `column-packing` (figs 4.17, 4.21b): packing-fraction evolution of a loose/dense
//! column pair.

use serde::{Deserialize, Serialize};

use super::common::series;
use crate::pipeline::context::{Claim, Output, StageCtx};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Parameters of a `column-packing` stage (roles loose, dense).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct PackingParams {
    /// Column of the `packing` tables.
    pub column: String,
    /// "Initial stage of collapse": the window (0, t] τ_c where dilation is looked for.
    pub initial_window: f64,
    /// Bound on |φ_dense(end) − φ_loose(end)|.
    pub end_tolerance: f64,
}

impl Default for PackingParams {
    fn default() -> Self {
        PackingParams {
            column: "phi_voronoi".into(),
            initial_window: 1.0,
            end_tolerance: 0.01,
        }
    }
}

impl Validate for PackingParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.positive("initial_window", self.initial_window);
        c.positive("end_tolerance", self.end_tolerance);
        c.issues
    }
}

fn run_packing(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: PackingParams = decode(ctx)?;
    let mut out = Output::default();
    let mut ends = [0.0; 2];
    for (k, role) in ["loose", "dense"].iter().enumerate() {
        let inp = ctx.input(role)?;
        let t = series(inp, "packing", "t_over_tau_c")?;
        let phi = series(inp, "packing", &p.column)?;
        anyhow::ensure!(
            phi.len() >= 2,
            "input `{}`: its packing table has {} rows (need the start and later instants)",
            inp.id,
            phi.len()
        );
        let early = t
            .iter()
            .zip(&phi)
            .filter(|(a, _)| **a > 0.0 && **a <= p.initial_window + 1e-9)
            .map(|(_, b)| *b)
            .fold(f64::INFINITY, f64::min);
        let (phi0, phi_end) = (phi[0], phi[phi.len() - 1]);
        let min_all = phi.iter().cloned().fold(f64::INFINITY, f64::min);
        ends[k] = phi_end;
        out.scalar(&format!("{role}_phi_initial"), phi0)
            .scalar(&format!("{role}_phi_end"), phi_end)
            .scalar(&format!("{role}_dilation_initial"), phi0 - early)
            .scalar(&format!("{role}_recompaction"), phi_end - min_all);
        out.claims.push(Claim::at_least(
            &format!("{role}-dilates-initially"),
            &format!("fig 4.17: \"Both dense and loose granular columns dilate during the initial stage of collapse\" — {role}: φ(0) − min φ over (0, {}] τ_c (> 0)", p.initial_window),
            1e-9, phi0 - early,
        ));
        if *role == "loose" {
            out.claims.push(Claim::at_least(
                "loose-densifies",
                "fig 4.17: \"the loose sample densifies as the flow evolves\" — φ_loose(end) − φ_loose(0) (> 0)",
                1e-9,
                phi_end - phi0,
            ));
        }
    }
    out.claims.push(Claim::at_most("same-end-packing", &format!("fig 4.17: \"the granular mass attains similar packing density at the end of the flow\" — |φ_dense(end) − φ_loose(end)| < {}", p.end_tolerance), p.end_tolerance, (ends[1] - ends[0]).abs()));
    out.note(format!("Local packing fraction = Σ π r² / Σ Voronoi cell area over interior cells of all grains (analysis::voronoi, column `{}` of the collapse stages' packing tables; sampled at the snapshot instants).", p.column));
    Ok(out)
}

/// What it reads of its inputs, whatever its params: the packing table of the loose and the dense column (for the committed store's serving
/// rule and the load-time check of the inputs' declared outputs).
fn reads(_: &serde_json::Value) -> Vec<crate::stages::kind::Read> {
    crate::stages::reads::tables(&[("loose", "packing"), ("dense", "packing")])
}

/// Kind `column-packing`.
pub const PACKING_KIND: Kind = Kind {
    name: "column-packing",
    source: file!(),
    method: None,
    version: 1,
    about: "packing-fraction evolution of a loose/dense column pair against fig 4.17's three statements",
    params: typed::<PackingParams>,
    run: run_packing,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[
        ("loose", crate::pipeline::context::Arity::One),
        ("dense", crate::pipeline::context::Arity::One),
    ]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "dense_dilation_initial", "dense_phi_end", "dense_phi_initial", "dense_recompaction",
            "loose_dilation_initial", "loose_phi_end", "loose_phi_initial", "loose_recompaction",
        ],
        tables: &[],
        measurements: &[
            "dense-dilates-initially", "loose-densifies", "loose-dilates-initially", "same-end-packing",
        ],
        texts: &[],
    },
    reads: Some(reads),
    cost: None,
    atlas: None,
};
