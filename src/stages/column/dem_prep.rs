//! Kind `dem-column-prep`: a DEM column sample, by ballistic deposition of the PSD (trimmed
//! to L0 × H0) or on a hexagonal lattice, settled to rest; its grains, contact histories
//! and snapshot figure.
//!
//! Every DEM kind takes `dem` (the solver's own parameter schema, `stages/dem-column.yaml`)
//! and `stiffness_factor`: the quick profile softens k_n, k_t, k_r by this factor (the
//! step grows by 1/√factor); what that costs in accuracy is measured by
//! `wp-dem-column` and printed on the figures.

use serde::{Deserialize, Serialize};

use super::dem_common::{check_dem, explain_dem, grains_table, histories_table};
use super::dem_snapshot::column_snapshot;
use crate::dem::DemParams;
use crate::dem::prep::{DepositionParams, deposited_column, hex_column};
use crate::math::PI;
use crate::pipeline::context::{Claim, Output, StageCtx, col_f64};
use crate::report::plot::footer;
use crate::stages::kind::{CostCtx, Work};
use crate::stages::{Kind, Validate, decode, typed};
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
    source: file!(),
    method: Some(crate::engines::Method::Dem),
    version: 4,
    about: "DEM column sample: ballistic deposition of the PSD (trimmed to L0 x H0) or hexagonal lattice",
    params: typed::<PrepParams>,
    run: run_prep,
    explain: Some(explain_dem),
    roles: crate::stages::kind::Roles::ByParams(roles),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "a", "h0_m", "l0_m", "n", "packing_fraction", "packing_fraction_core", "seed", "settle_ke_over_ep",
            "settle_time_s", "stiffness_factor",
        ],
        tables: &[
            crate::stages::kind::TableDecl {
                name: "contacts",
                columns: &["a", "b", "ft_n", "mr_nm", "rolling_rad", "tangential_m", "wall"],
            },
            crate::stages::kind::TableDecl {
                name: "table",
                columns: &["r_m", "x_m", "y_m"],
            },
        ],
        measurements: &["packing-fraction"],
        texts: &[],
    },
    reads: None,
    cost: Some(cost),
    atlas: None,
};

/// Cost: grains ∝ the column's area, steps per simulated second of the run stiffness.
fn cost(c: &CostCtx) -> Option<Work> {
    let p: PrepParams = c.typed()?;
    Some((
        vec![
            ("grains", p.area_m2),
            ("steps", p.dem.steps_per_second(p.stiffness_factor)),
        ],
        false,
    ))
}

/// Roles: a hexagonal lattice is monodisperse, so its PSD input is optional.
fn roles(v: &serde_json::Value) -> Vec<(&'static str, crate::pipeline::context::Arity)> {
    use crate::pipeline::context::Arity::*;
    let hex = v.get("packing").and_then(|p| p.as_str()) == Some("hex");
    vec![("psd", if hex { OptionalOne } else { One })]
}
