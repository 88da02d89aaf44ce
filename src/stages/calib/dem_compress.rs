//! Kind `dem-compress`: laterally confined uniaxial compression of a DEM column →
//! constrained and Young's modulus, which feed the MPM through the DAG.
//!
//! Every DEM kind takes `dem` (the solver's own parameter schema, `stages/dem-column.yaml`)
//! and `stiffness_factor`: the quick profile softens k_n, k_t, k_r by this factor (the
//! step grows by 1/√factor); what that costs in accuracy is measured by
//! `wp-dem-column` and printed on the figures.

use serde::{Deserialize, Serialize};

use crate::dem::DemParams;
use crate::dem::compress::{CompressionParams, compression_test};
use crate::pipeline::context::{Claim, Output, StageCtx, frame};
use crate::report::plot::{Chart, Series, Style, footer};
use crate::stages::column::dem_common::{check_dem, column_from, explain_dem};
use crate::stages::column::dem_prep::PrepParams;
use crate::stages::kind::{CostCtx, Work};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

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
    super::dem_calibration::apply_calibration(ctx, &mut p.dem)?;
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
        .scalar("rest_ke_over_ep", r.rest_ke_over_ep)
        .scalar("at_rest", if r.at_rest { 1.0 } else { 0.0 })
        .scalar("stiffness_factor", p.stiffness_factor);
    out.claims.push(Claim::rel("youngs-modulus", "E = 1.98e6 N/m², \"initial slope of the stress-strain plot of a uni-axial compression of a laterally confined granular column\" (I12: that slope is M; E = M(1+ν)(1−2ν)/(1−ν))", 1.98e6, r.young, 0.25));
    out.note(format!("Constrained modulus M = {:.3e} Pa (slope over the first {:.2} % strain), E = {:.3e} Pa with ν = {}; K_0 = {:.3}. Contact stiffness factor {} (the affine estimate of docs/definitions.md I12 scales with k_n). The sample {} before the plate moved (E_k/E_p = {:.1e}, limit {:.0e}); each point's stress is its strain interval's mean, and M is a least-squares slope with an intercept.", r.modulus, 100.0 * p.compression.fit_strain, r.young, p.compression.poisson, r.k0, p.stiffness_factor, if r.at_rest { "was at rest" } else { "was NOT at rest" }, r.rest_ke_over_ep, p.compression.rest_ratio));
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
                    (0.0, r.fit_intercept),
                    (
                        p.compression.fit_strain,
                        r.fit_intercept + r.modulus * p.compression.fit_strain,
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
    source: file!(),
    method: Some(crate::engines::Method::Dem),
    version: 3,
    about: "laterally confined uniaxial compression of a DEM column -> constrained and Young's modulus",
    params: typed::<CompressStageParams>,
    run: run_compress,
    explain: Some(explain_dem),
    roles: crate::stages::kind::Roles::Fixed(&[
        ("column", crate::pipeline::context::Arity::One),
        ("calibration", crate::pipeline::context::Arity::OptionalOne),
    ]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "at_rest", "constrained_modulus_pa", "height_m", "k0", "rest_ke_over_ep", "stiffness_factor",
            "youngs_modulus_pa",
        ],
        tables: &[crate::stages::kind::TableDecl {
            name: "table",
            columns: &["axial_strain", "axial_stress_pa", "lateral_stress_pa"],
        }],
        measurements: &["youngs-modulus"],
        texts: &[],
    },
    reads: None,
    cost: Some(cost),
    atlas: None,
};

/// Cost: grains ∝ the input column's area, steps per simulated second.
fn cost(c: &CostCtx) -> Option<Work> {
    let p: CompressStageParams = c.typed()?;
    let area = c.input::<PrepParams>("column")?.area_m2;
    Some((
        vec![("grains", area), ("steps", p.dem.steps_per_second(p.stiffness_factor))],
        false,
    ))
}
