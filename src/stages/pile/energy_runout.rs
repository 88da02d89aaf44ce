//! Kind `energy-runout` (fig 4.45, chapter §4.4.6): the run-out of collapsing columns and of
//! excited piles against the kinetic energy available for the flow, per grain in m g d.
//!
//! Columns (docs/definitions.md D22): "the peak energy at τ_c is used as the energy
//! available for the flow" — x = max_t E_k / (M g d̄), d̄ = 1.15 mm, computed as (max
//! E_k / E_p0)·H_0/(2 d̄) since E_p0 = M g H_0/2 for a column of uniform packing (D22's own
//! identity). Piles: x = E_0 per grain (D21). y = ΔL = (L_f − L_0)/L_0 for both; for the
//! columns, the gathered length (D01), the one rule both methods publish, so the MPM/DEM
//! ratios compare like with like. Reads the column sweeps' members (roles `col_dem`,
//! `col_mpm`: scalars `a`, `h0_m`, `runout_gathered_norm`, table columns `ek_j`, `ep_j`) and the pile runs (roles `pile_dem`, `pile_mpm`: `e0_mgd`,
//! `dl`).

use polars::prelude::{Column, DataFrame};
use serde::{Deserialize, Serialize};

use crate::fit::power_law;
use crate::pipeline::context::{Claim, InputRef, Output, StageCtx, col_f64};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// The column grain diameter d̄ [m] (SC-PSD, PSD-COL).
pub const D_COLUMN: f64 = 1.15e-3;

/// Parameters of an `energy-runout` stage.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Params {
    /// The column regime boundary a = 2.7 (eq 4.6).
    pub a_split: f64,
    /// Column "similar run-out" below `a_split`: tolerance on the mean MPM/DEM ratio (UNSPEC).
    pub similar_tolerance: f64,
    /// Pile "good agreement": tolerance on the mean MPM/DEM ΔL ratio (UNSPEC).
    pub agreement_tolerance: f64,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            a_split: 2.7,
            similar_tolerance: 0.2,
            agreement_tolerance: 0.25,
        }
    }
}

impl Validate for Params {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.check(
            self.a_split.is_finite() && self.a_split > 0.0,
            "a_split",
            self.a_split,
            "a finite aspect ratio > 0",
        );
        c.check(
            self.similar_tolerance > 0.0 && self.similar_tolerance < 1.0,
            "similar_tolerance",
            self.similar_tolerance,
            "in (0, 1)",
        );
        c.check(
            self.agreement_tolerance > 0.0 && self.agreement_tolerance < 1.0,
            "agreement_tolerance",
            self.agreement_tolerance,
            "in (0, 1)",
        );
        c.issues
    }
}

/// The peak translational E_k of a column over M g d̄ (D22): (max E_k / E_p0) · H_0/(2 d̄).
pub fn column_energy(ek: &[f64], ep0: f64, h0: f64) -> f64 {
    let peak = ek.iter().copied().fold(0.0, f64::max);
    peak / ep0 * h0 / (2.0 * D_COLUMN)
}

/// (a, energy, ΔL) of every member of a column sweep role, sorted by a.
fn columns(ctx: &StageCtx, role: &str) -> anyhow::Result<Vec<(f64, f64, f64)>> {
    let mut v = Vec::new();
    for inp in ctx.inputs_of(role) {
        let t = inp.table("table")?;
        let ek = col_f64(&t, "ek_j")?;
        let ep0 = *col_f64(&t, "ep_j")?
            .first()
            .ok_or_else(|| anyhow::anyhow!("input `{}`: empty table", inp.id))?;
        v.push((
            inp.scalar("a")?,
            column_energy(&ek, ep0, inp.scalar("h0_m")?),
            inp.scalar("runout_gathered_norm")?,
        ));
    }
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(v)
}

fn pile(inp: &InputRef) -> anyhow::Result<Vec<(f64, f64)>> {
    let t = inp.table("table")?;
    Ok(col_f64(&t, "e0_mgd")?.into_iter().zip(col_f64(&t, "dl")?).collect())
}

fn run(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: Params = decode(ctx)?;
    let (cd, cm) = (columns(ctx, "col_dem")?, columns(ctx, "col_mpm")?);
    let (pd, pm) = (pile(ctx.input("pile_dem")?)?, pile(ctx.input("pile_mpm")?)?);
    let mut fam: Vec<String> = Vec::new();
    let (mut a, mut x, mut y) = (Vec::new(), Vec::new(), Vec::new());
    for (name, rows) in [("column DEM", &cd), ("column MPM", &cm)] {
        for r in rows.iter() {
            fam.push(name.into());
            a.push(r.0);
            x.push(r.1);
            y.push(r.2);
        }
    }
    for (name, rows) in [("pile DEM", &pd), ("pile MPM", &pm)] {
        for r in rows.iter() {
            fam.push(name.into());
            a.push(f64::NAN);
            x.push(r.0);
            y.push(r.1);
        }
    }
    let mut out = Output::default();
    out.table(
        "table",
        DataFrame::new_infer_height(vec![
            Column::new("family".into(), fam.clone()),
            Column::new("a".into(), a),
            Column::new("energy_mgd".into(), x.clone()),
            Column::new("dl".into(), y.clone()),
        ])?,
    );
    // Column MPM against DEM at the same a (the DEM's a is measured on the deposit: paired
    // within 5 %; the sweeps' values are ≥ 20 % apart), either side of a = 2.7.
    let pairs: Vec<(f64, f64)> = cd
        .iter()
        .filter_map(|d| {
            cm.iter()
                .find(|m| (m.0 - d.0).abs() <= 0.05 * d.0)
                .map(|m| (d.0, m.2 / d.2))
        })
        .collect();
    let mean = |v: Vec<f64>| {
        if v.is_empty() {
            f64::NAN
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    let tall = mean(pairs.iter().filter(|q| q.0 > p.a_split).map(|q| q.1).collect());
    let short = mean(pairs.iter().filter(|q| q.0 <= p.a_split).map(|q| q.1).collect());
    out.scalar("column_mpm_over_dem_tall", tall)
        .scalar("column_mpm_over_dem_short", short);
    out.claims.push(Claim::at_least("column-mpm-longer-tall", &format!("\"MPM predicts longer run-out for high energy regime (corresponding to a > 2.7)\": mean ΔL_MPM/ΔL_DEM over the columns with a > {} (≥ 1)", p.a_split), 1.0, tall));
    out.claims.push(Claim::rel("column-similar-short", &format!("\"MPM and DEM predict similar run-out behaviour for low energy regime (short columns)\": mean ΔL_MPM/ΔL_DEM over a ≤ {} (tolerance {} %, UNSPEC)", p.a_split, 100.0 * p.similar_tolerance), 1.0, short, p.similar_tolerance));
    // Piles: MPM against DEM at equal E_0.
    let ratios: Vec<(f64, f64)> = pd
        .iter()
        .filter_map(|d| {
            pm.iter()
                .find(|m| (m.0 - d.0).abs() < 1e-6 * d.0)
                .map(|m| (d.0, m.1 / d.1))
        })
        .collect();
    let agree = mean(ratios.iter().map(|q| q.1).collect());
    let lowest = ratios.first().map(|q| 1.0 / q.1).unwrap_or(f64::NAN);
    out.scalar("pile_mpm_over_dem_mean", agree)
        .scalar("pile_dem_over_mpm_lowest", lowest);
    out.claims.push(Claim::rel("pile-agreement", &format!("\"In the case of granular column subjected to horizontal velocity … MPM is able to predict the run-out response in good agreement with DEM simulations\": mean ΔL_MPM/ΔL_DEM over the common E_0 (per E_0: {}; tolerance {} %, UNSPEC)", ratios.iter().map(|q| format!("{:.2}", q.1)).collect::<Vec<_>>().join(", "), 100.0 * p.agreement_tolerance), 1.0, agree, p.agreement_tolerance));
    out.claims.push(Claim::at_least("pile-dem-longer-low", &format!("\"At very low energy, DEM simulations show longer run-out in the case of slope subjected to excitations\": ΔL_DEM/ΔL_MPM at the lowest common E_0 ({} mgd; ≥ 1)", ratios.first().map(|q| q.0).unwrap_or(f64::NAN)), 1.0, lowest));
    // "Both granular flows … show power-law relation with the energy": R² of a log–log fit.
    let mut worst = f64::INFINITY;
    for name in ["column DEM", "column MPM", "pile DEM", "pile MPM"] {
        let (xs, ys): (Vec<f64>, Vec<f64>) = (0..fam.len()).filter(|&k| fam[k] == name).map(|k| (x[k], y[k])).unzip();
        if let Ok(f) = power_law(&xs, &ys) {
            let key = name.replace(' ', "_").to_lowercase();
            out.scalar(&format!("{key}_exponent"), f.exponent)
                .scalar(&format!("{key}_exponent_se"), f.exponent_se)
                .scalar(&format!("{key}_r2"), f.r2);
            worst = worst.min(f.r2);
        }
    }
    out.claims.push(Claim::at_least("power-law-energy", "\"Both granular flows, column collapse and slope subjected to horizontal excitation … show power-law relation with the energy\": smallest R² of the single log–log fit of ΔL against the energy over the four families (≥ 0.9, UNSPEC)", 0.9, worst));
    out.note("Column energy (D22): max_t E_k / (M g d̄) with d̄ = 1.15 mm, from (max E_k / E_p0)·H_0/(2 d̄) — exact for a column of uniform packing (E_p0 = M g H_0/2). Pile energy: E_0 per grain (D21, d = 2.455 mm). Quick profile: the quick columns (6 aspect ratios) and the 250-grain quick pile.");
    Ok(out)
}

/// What it reads of its inputs, whatever its params: the table of every column and pile run (for the committed store's serving
/// rule and the load-time check of the inputs' declared outputs).
fn reads(_: &serde_json::Value) -> Vec<crate::stages::kind::Read> {
    crate::stages::reads::tables(&[
        ("col_dem", "table"),
        ("col_mpm", "table"),
        ("pile_dem", "table"),
        ("pile_mpm", "table"),
    ])
}

/// Kind `energy-runout`.
pub const KIND: Kind = Kind {
    name: "energy-runout",
    source: file!(),
    method: None,
    version: 1,
    about: "fig 4.45: column (peak E_k at τ_c, D22) and pile (E_0, D21) run-out against the kinetic energy per grain, with the §4.4.6 comparisons",
    params: typed::<Params>,
    run,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[
        ("col_dem", crate::pipeline::context::Arity::Many),
        ("col_mpm", crate::pipeline::context::Arity::Many),
        ("pile_dem", crate::pipeline::context::Arity::One),
        ("pile_mpm", crate::pipeline::context::Arity::One),
    ]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "column_dem_exponent", "column_dem_exponent_se", "column_dem_r2", "column_mpm_exponent",
            "column_mpm_exponent_se", "column_mpm_over_dem_short", "column_mpm_over_dem_tall", "column_mpm_r2",
            "pile_dem_exponent", "pile_dem_exponent_se", "pile_dem_over_mpm_lowest", "pile_dem_r2",
            "pile_mpm_exponent", "pile_mpm_exponent_se", "pile_mpm_over_dem_mean", "pile_mpm_r2",
        ],
        tables: &[crate::stages::kind::TableDecl {
            name: "table",
            columns: &["a", "dl", "energy_mgd", "family"],
        }],
        measurements: &[
            "column-mpm-longer-tall", "column-similar-short", "pile-agreement", "pile-dem-longer-low",
            "power-law-energy",
        ],
        texts: &[],
    },
    reads: Some(reads),
    cost: None,
    atlas: None,
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn column_energy_is_d22() {
        // E_k peaks at 10 % of E_p0 on a column 0.1 m high: 0.1 · 0.1/(2 · 1.15e-3) = 4.348
        let e = column_energy(&[0.0, 0.05, 0.1, 0.02], 1.0, 0.1);
        assert!((e - 4.3478).abs() < 1e-3, "{e}");
    }
}
