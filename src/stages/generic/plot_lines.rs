//! Straight-line overlays of a `plot` panel (`lines:`): a line fitted upstream, its
//! coefficients read from an input's scalars, or a stated value written as numbers. Drawn
//! dashed, labelled with the coefficients drawn, never counted as data.

use anyhow::anyhow;
use serde::{Deserialize, Serialize};

use crate::pipeline::context::StageCtx;
use crate::report::plot::{Series, Style};

/// A coefficient of a straight-line overlay: a number written in the declaration, or the
/// name of a scalar of the line's input.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum Coef {
    /// A number (a stated value).
    Value(f64),
    /// A scalar of the input named by `from` (a fitted value).
    Scalar(String),
}

/// A straight line y = intercept + slope·x (dashed) across the panel's data: a line fitted
/// upstream, its coefficients read from an input's scalars (`from`), or a stated value
/// written as numbers (`slope` 0: a level). The legend prints the coefficients drawn.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LineOverlay {
    /// Input role whose scalars the coefficients name (needed when one is a name).
    #[serde(default)]
    pub from: Option<String>,
    /// y at x = 0.
    pub intercept: Coef,
    /// dy/dx (default 0: a level).
    #[serde(default = "zero_coef")]
    pub slope: Coef,
    /// The x range drawn (a fit's own domain); default: the panel's (below).
    #[serde(default)]
    pub x_range: Option<[f64; 2]>,
    /// What the line is ("fit μ = μ_min + b I", "stated μ* = 0.22").
    pub label: String,
    /// Palette index.
    #[serde(default)]
    pub color: Option<usize>,
}

fn zero_coef() -> Coef {
    Coef::Value(0.0)
}

impl LineOverlay {
    /// The scalar names its coefficients read.
    pub(super) fn scalars(&self) -> impl Iterator<Item = &String> {
        [&self.intercept, &self.slope].into_iter().filter_map(|c| match c {
            Coef::Scalar(s) => Some(s),
            Coef::Value(_) => None,
        })
    }
}

/// A panel's straight lines, each across its own `x_range`, or the x axis' fixed `range`,
/// or else the x range of the panel's data series (widened by 1.5× on a log axis, 5 % of the span on a linear
/// one), 40 points spaced as the axis is; colours from `first_color` on.
pub(super) fn line_series(
    ctx: &StageCtx,
    lines: &[LineOverlay],
    (x_log, x_range): (bool, Option<[f64; 2]>),
    data: &[Series],
    first_color: usize,
) -> anyhow::Result<Vec<Series>> {
    let xs = || {
        data.iter()
            .flat_map(|s| s.points.iter().map(|p| p.0))
            .filter(|x| x.is_finite())
    };
    let (lo, hi) = xs().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
    let (lo, hi) = match x_range {
        Some([a, b]) => (a, b),
        None if !lo.is_finite() => return Ok(vec![]),
        None if x_log => (lo / 1.5, hi * 1.5),
        None => (lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo)),
    };
    let mut out = Vec::new();
    for (k, l) in lines.iter().enumerate() {
        let coef = |c: &Coef| -> anyhow::Result<f64> {
            match c {
                Coef::Value(v) => Ok(*v),
                Coef::Scalar(name) => {
                    let role = l.from.as_deref().unwrap_or_default();
                    let inp = ctx.inputs_of(role).first().ok_or_else(|| {
                        anyhow!(
                            "stage `{}`: line `{}` reads role `{role}`, which names no input",
                            ctx.id,
                            l.label
                        )
                    })?;
                    inp.scalar(name)
                }
            }
        };
        let (a, b) = (coef(&l.intercept)?, coef(&l.slope)?);
        let (lo, hi) = l.x_range.map_or((lo, hi), |[a, b]| (a, b));
        let at = |i: usize| {
            let t = i as f64 / 39.0;
            if x_log {
                lo * (hi / lo).powf(t)
            } else {
                lo + t * (hi - lo)
            }
        };
        let label = if b == 0.0 {
            format!("{} = {a:.3}", l.label)
        } else {
            format!("{}: {a:.3} + {b:.3}·x", l.label)
        };
        let color = l.color.unwrap_or(first_color + k);
        out.push(Series::new(
            label,
            Style::Dashed,
            (0..40).map(|i| (at(i), a + b * at(i))).collect(),
            color,
        ));
    }
    Ok(out)
}
