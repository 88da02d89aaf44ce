//! Kind `cd-shear-figure` (fig4-25b): macroscopic friction μ* against inertial number
//! with the μ(I) fit and the chapter's 0.22 claim.

use serde::{Deserialize, Serialize};

use crate::pipeline::context::{Claim, Output, StageCtx, col_f64, frame};
use crate::report::plot::{Chart, Legend, Series, Style, footer};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Parameters of a `cd-shear-figure` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShearFigureParams {
    /// The chapter's macroscopic friction coefficient.
    pub paper_mu: f64,
    /// Allowed |μ_min − 0.22|. 0.03: about twice the standard error of μ_min in the quick
    /// cell, and the spread of quasi-static μ* reported for 2D disks at μ_p = 0.4.
    pub tolerance: f64,
}

impl Default for ShearFigureParams {
    fn default() -> Self {
        ShearFigureParams {
            paper_mu: 0.22,
            tolerance: 0.03,
        }
    }
}

impl Validate for ShearFigureParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.positive("paper_mu", self.paper_mu);
        c.positive("tolerance", self.tolerance);
        c.issues
    }
}

fn run_shear_figure(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: ShearFigureParams = decode(ctx)?;
    let input = ctx.input("shear")?;
    let df = input.table("table")?;
    let (i, mu, se) = (
        col_f64(&df, "inertial_number")?,
        col_f64(&df, "mu")?,
        col_f64(&df, "mu_se")?,
    );
    let (mu_min, b) = (input.scalar("mu_min")?, input.scalar("b")?);
    let mu_min_se = input.scalar("mu_min_se").unwrap_or(f64::NAN);
    let i_fit = input
        .params
        .pointer("/shear/fit_max_inertial_number")
        .and_then(|v| v.as_f64())
        .unwrap_or(f64::NAN);
    let mut out = Output::default();
    out.table(
        "table",
        frame(vec![
            ("inertial_number", i.clone()),
            ("mu", mu.clone()),
            ("mu_se", se.clone()),
        ])?,
    );
    out.scalar("mu_min", mu_min)
        .scalar("b", b)
        .scalar("mu_min_se", mu_min_se);
    out.claims.push(Claim::abs("macro-friction", "\"Periodic shear tests using CD (figure 4.25a), reveals a macroscopic friction coefficient of 0.22\" — μ*(I → 0) = μ_min of the fit μ = μ_min + b I", p.paper_mu, mu_min, p.tolerance));
    out.note(format!(
        "μ* points from `{}`; fit μ_min = {:.3} ± {:.3}, b = {:.3}.",
        input.id, mu_min, mu_min_se, b
    ));
    let (lo, hi) = i
        .iter()
        .filter(|v| *v > &0.0)
        .fold((f64::INFINITY, 0.0f64), |(a, z), &v| (a.min(v), z.max(v)));
    let grid: Vec<f64> = (0..=40)
        .map(|k| (lo / 1.5) * ((hi * 1.5) / (lo / 1.5)).powf(k as f64 / 40.0))
        .collect();
    let mut err_lo = Vec::new();
    let mut err_hi = Vec::new();
    for k in 0..i.len() {
        err_lo.push((i[k], mu[k] - se[k]));
        err_hi.push((i[k], mu[k] + se[k]));
    }
    let chart = Chart {
        title: ctx.caption.clone().unwrap_or_else(|| "Figure 4.25b".into()),
        footer: footer(
            &ctx.profile,
            &format!("μ_min = {mu_min:.3} ± {mu_min_se:.3}, b = {b:.3}"),
        ),
        x_label: "inertial number I [-]".into(),
        y_label: "macroscopic friction μ* = τ/σ_n [-]".into(),
        x_log: true,
        y_range: Some((0.0, (mu.iter().cloned().fold(0.0, f64::max) * 1.25).max(0.5))),
        legend: Legend::UpperLeft,
        series: vec![
            Series::new(
                "CD, time-averaged steady shear",
                Style::Points,
                i.iter().cloned().zip(mu.iter().cloned()).collect(),
                0,
            ),
            Series::new(
                "± standard error (8 blocks)",
                Style::Points,
                err_lo.into_iter().chain(err_hi).collect(),
                5,
            ),
            Series::new(
                format!("fit (I ≤ {i_fit}): μ = {mu_min:.3} + {b:.2} I"),
                Style::Dashed,
                grid.iter().map(|&x| (x, mu_min + b * x)).collect(),
                1,
            ),
            Series::new(
                format!("stated: μ* = {}", p.paper_mu),
                Style::Dashed,
                vec![(grid[0], p.paper_mu), (grid[40], p.paper_mu)],
                7,
            ),
        ],
        ..Default::default()
    };
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `cd-shear-figure`.
pub const SHEAR_FIGURE_KIND: Kind = Kind {
    name: "cd-shear-figure",
    source: file!(),
    method: Some(crate::engines::Method::Cd),
    version: 1,
    about: "fig4-25b: macroscopic friction mu* against inertial number (log x) with the fit and the 0.22 claim",
    params: typed::<ShearFigureParams>,
    run: run_shear_figure,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[("shear", crate::pipeline::context::Arity::One)]),
    outputs: crate::stages::kind::Outputs {
        scalars: &["b", "mu_min", "mu_min_se"],
        tables: &[crate::stages::kind::TableDecl {
            name: "table",
            columns: &["inertial_number", "mu", "mu_se"],
        }],
        measurements: &["macro-friction"],
        texts: &[],
    },
    reads: None,
    cost: None,
    atlas: None,
};
