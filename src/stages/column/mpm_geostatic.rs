//! Kind `mpm-geostatic` (fig4-04): the MPM a = 1 column, its material points in the mesh
//! and the geostatic vertical stress.

use serde::{Deserialize, Serialize};

use super::mpm_common::{calibrate, check_mpm, explain_mpm};
use super::mpm_common::{cfl, points};
use crate::mpm::MpmParams;
use crate::mpm::column::fig4_04;
use crate::pipeline::context::{Claim, Output, StageCtx, frame};
use crate::report::plot::footer;
use crate::report::snapshot::{Field, Segment, Shape, Snapshot};
use crate::stages::kind::{CostCtx, Work};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

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
    source: file!(),
    method: Some(crate::engines::Method::Mpm),
    version: 2,
    about: "fig4-04: MPM a = 1 column, material points in the mesh and geostatic vertical stress",
    params: typed::<GeostaticParams>,
    run: run_geostatic,
    explain: Some(explain_mpm),
    roles: crate::stages::kind::Roles::Fixed(&[
        ("shear", crate::pipeline::context::Arity::OptionalOne),
        ("compression", crate::pipeline::context::Arity::OptionalOne),
    ]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "base_relative_error", "base_sigma_yy_analytic_pa", "base_sigma_yy_pa", "friction_angle_deg",
            "geostatic_steps", "h0_m", "l0_m", "points", "rho_g_h0_pa", "youngs_modulus_pa",
        ],
        tables: &[
            crate::stages::kind::TableDecl {
                name: "profile",
                columns: &["sigma_yy_analytic_pa", "sigma_yy_pa", "y_m"],
            },
            crate::stages::kind::TableDecl {
                name: "table",
                columns: &["sigma_xx_pa", "sigma_yy_pa", "x_m", "y_m"],
            },
        ],
        measurements: &[],
        texts: &[],
    },
    reads: None,
    cost: Some(geostatic_cost),
    atlas: None,
};

/// Cost (geostatic): the column's points, CFL steps of the geostatic stage.
fn geostatic_cost(c: &CostCtx) -> Option<Work> {
    let p: GeostaticParams = c.typed()?;
    let (m, h) = (&p.mpm, p.mpm.cell_size);
    Some((
        vec![
            ("points", points(1.0, m.ppc as f64, h)),
            ("steps", cfl(m, m.geostatic.courant, h)),
        ],
        false,
    ))
}
