//! Kind `plot`: a figure declared in YAML. Analysis stages make tables and scalars; a
//! `plot` stage only draws them: panels of series (which input, which table or scalars,
//! which columns, a row filter, a normalisation), axes, fitted overlays read from
//! `power-law-fit` stages and the chapter's stated laws read from `reference-laws` —
//! both dashed and labelled as what they are, never as data.
//!
//! Input roles are free names: every `from:` (and `fits[].from`, `laws_from`,
//! `error.from`) names a role declared under the stage's `inputs:`, and every declared role
//! must be read (`src/pipeline/check.rs`). A role that names a matrix base id fans in all
//! its members: `source: scalars` then gives one point per member (a sweep), `source:
//! table` concatenates the members' tables.

use anyhow::anyhow;
use serde::{Deserialize, Serialize};

use crate::pipeline::context::{Output, StageCtx, col_f64};
use crate::report::plot::{Chart, Legend, Series, Style, footer, panels_to_svg};
use crate::stages::kind::{Item, Read};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

use super::plot_lines::line_series;
pub use super::plot_lines::{Coef, LineOverlay};
pub use super::plot_points::{Draw, SeriesSpec, Source};
use super::plot_points::{scalar_point, table_points};

/// One axis.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Axis {
    /// Label with unit (or "nondimensional").
    pub label: String,
    /// Logarithmic axis.
    #[serde(default)]
    pub log: bool,
    /// Fixed range [lo, hi] (else from the data).
    #[serde(default)]
    pub range: Option<[f64; 2]>,
}

/// Legend corner.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Default)]
#[serde(rename_all = "snake_case")]
pub enum Corner {
    /// Upper left.
    #[default]
    UpperLeft,
    /// Upper right.
    UpperRight,
    /// Lower left.
    LowerLeft,
    /// Lower right.
    LowerRight,
}

/// A fitted power law to overlay (dashed), from a `power-law-fit` stage.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FitOverlay {
    /// Input role naming the fit stage.
    pub from: String,
    /// What was fitted (legend: "fit <label>: c·x^(n ± se)").
    pub label: String,
    /// Palette index.
    #[serde(default)]
    pub color: Option<usize>,
}

/// One panel.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Panel {
    /// Panel title (default: the stage caption).
    #[serde(default)]
    pub title: Option<String>,
    /// x axis.
    pub x: Axis,
    /// y axis.
    pub y: Axis,
    /// Legend corner.
    #[serde(default)]
    pub legend: Corner,
    /// Data series.
    #[serde(default)]
    pub series: Vec<SeriesSpec>,
    /// Fitted overlays.
    #[serde(default)]
    pub fits: Vec<FitOverlay>,
    /// Stated laws (names of `reference-laws`) to overlay from the role `laws_from`.
    #[serde(default)]
    pub laws: Vec<String>,
    /// Straight lines (a fitted line from scalars, a stated level). Left out of the
    /// canonical params when empty (no existing plot's cache key moves).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lines: Vec<LineOverlay>,
}

/// A figure's own measured error, read from a work-precision stage through the DAG: the
/// scalar `profile_error` and a note saying what it measures (the footer line with the
/// method's error is stamped on every published figure, `report::measured`).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ErrorNote {
    /// Input role naming the work-precision stage.
    pub from: String,
    /// Its scalar holding this profile's error.
    pub scalar: String,
    /// What the number is ("run-out error of the quick column vs the finest setting").
    pub label: String,
}

/// Parameters of a `plot` stage.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PlotParams {
    /// Panels, row-major.
    pub panels: Vec<Panel>,
    /// Panels per row (default: up to 2).
    #[serde(default)]
    pub columns: Option<usize>,
    /// Role naming the `reference-laws` stage (needed when a panel lists `laws`).
    #[serde(default)]
    pub laws_from: Option<String>,
    /// This figure's own measured error (scalar `profile_error` and a note).
    #[serde(default)]
    pub error: Option<ErrorNote>,
}

impl PlotParams {
    /// Every input role the declaration reads.
    pub fn roles(&self) -> Vec<String> {
        let mut r: Vec<String> = Vec::new();
        let mut add = |s: &str| {
            if !r.iter().any(|x| x == s) {
                r.push(s.to_string());
            }
        };
        for p in &self.panels {
            p.series.iter().for_each(|s| add(&s.from));
            p.fits.iter().for_each(|f| add(&f.from));
            p.lines.iter().filter_map(|l| l.from.as_deref()).for_each(&mut add);
        }
        if let Some(l) = &self.laws_from {
            add(l);
        }
        if let Some(e) = &self.error {
            add(&e.from);
        }
        r
    }
}

impl Validate for PlotParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.check(
            !self.panels.is_empty() && self.panels.len() <= 12,
            "panels",
            self.panels.len(),
            "1 to 12 panels",
        );
        if let Some(n) = self.columns {
            c.check((1..=4).contains(&n), "columns", n, "1 to 4 panels per row");
        }
        for (i, p) in self.panels.iter().enumerate() {
            for (ax, a) in [("x", &p.x), ("y", &p.y)] {
                if let Some([lo, hi]) = a.range {
                    let key = format!("panels[{i}].{ax}.range");
                    c.check(
                        lo.is_finite() && hi.is_finite() && hi > lo && (!a.log || lo > 0.0),
                        &key,
                        format!("[{lo}, {hi}]"),
                        "[lo, hi] with lo < hi (lo > 0 on a log axis)",
                    );
                }
            }
            c.check(
                !p.series.is_empty() || !p.fits.is_empty() || !p.laws.is_empty() || !p.lines.is_empty(),
                &format!("panels[{i}]"),
                "empty",
                "at least one series, fit, law or line",
            );
            for (j, l) in p.lines.iter().enumerate() {
                let key = format!("panels[{i}].lines[{j}]");
                c.check(
                    l.from.is_some() || l.scalars().next().is_none(),
                    &format!("{key}.from"),
                    "missing",
                    "the role whose scalars `intercept` / `slope` name (or write both as numbers)",
                );
                if let Some([lo, hi]) = l.x_range {
                    c.check(
                        lo.is_finite() && hi.is_finite() && hi > lo && (!p.x.log || lo > 0.0),
                        &format!("{key}.x_range"),
                        format!("[{lo}, {hi}]"),
                        "[lo, hi] with lo < hi (lo > 0 on a log axis)",
                    );
                }
                for (f, v) in [("intercept", &l.intercept), ("slope", &l.slope)] {
                    if let Coef::Value(x) = v {
                        c.check(
                            x.is_finite(),
                            &format!("{key}.{f}"),
                            x,
                            "a finite number or a scalar's name",
                        );
                    }
                }
            }
            for (j, s) in p.series.iter().enumerate() {
                let key = format!("panels[{i}].series[{j}]");
                c.check(
                    s.x_scale.is_finite() && s.x_scale != 0.0,
                    &format!("{key}.x_scale"),
                    s.x_scale,
                    "a finite non-zero factor",
                );
                c.check(
                    s.y_scale.is_finite() && s.y_scale != 0.0,
                    &format!("{key}.y_scale"),
                    s.y_scale,
                    "a finite non-zero factor",
                );
                c.check(
                    !(s.source == Source::Scalars && s.y_div_initial.is_some()),
                    &format!("{key}.y_div_initial"),
                    "with source: scalars",
                    "a table source (scalars have no first row)",
                );
                c.check(
                    !(s.source == Source::Scalars && s.group.is_some()),
                    &format!("{key}.group"),
                    "with source: scalars",
                    "a table source (one series per distinct value of a column)",
                );
                c.check(
                    !(s.source == Source::Scalars && s.x_table.is_some()),
                    &format!("{key}.x_table"),
                    "with source: scalars",
                    "a table source (x read row for row from another table)",
                );
                for (k, v) in &s.filter {
                    c.check(
                        v.is_number() || v.is_string() || v.is_boolean(),
                        &format!("{key}.filter.{k}"),
                        v,
                        "a number, string or boolean",
                    );
                }
            }
            for l in &p.laws {
                c.check(
                    super::laws::eval(l, 1.0).is_some(),
                    &format!("panels[{i}].laws"),
                    l,
                    &format!(
                        "one of {}",
                        super::laws::LAWS.iter().map(|l| l.0).collect::<Vec<_>>().join(", ")
                    ),
                );
            }
            if !p.laws.is_empty() && self.laws_from.is_none() {
                c.fail(
                    "laws_from",
                    "missing",
                    "the role of the `reference-laws` stage, e.g. `laws_from: laws` with `inputs: { laws: laws }`",
                );
            }
        }
        c.issues
    }
}

/// The series of one declaration: one, or one per distinct value of `group`.
fn series_of(ctx: &StageCtx, s: &SeriesSpec, color: usize) -> anyhow::Result<Vec<Series>> {
    let inputs = ctx.inputs_of(&s.from);
    anyhow::ensure!(
        !inputs.is_empty(),
        "stage `{}`: series `{}` reads role `{}`, which names no input",
        ctx.id,
        s.label,
        s.from
    );
    let mut pts: Vec<(f64, f64, f64, f64)> = Vec::new();
    for inp in inputs {
        match s.source {
            Source::Table => pts.extend(table_points(inp, s)?),
            Source::Scalars => pts.extend(scalar_point(inp, s)?),
        }
    }
    if s.source == Source::Scalars {
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    let style = match s.draw {
        Draw::Points => Style::Points,
        Draw::Line => Style::Line,
        Draw::LinePoints => Style::LinePoints,
    };
    let mut groups: Vec<f64> = pts.iter().map(|p| p.3).collect();
    groups.sort_by(|a, b| a.total_cmp(b));
    groups.dedup();
    let base = s.color.unwrap_or(color);
    Ok(groups
        .iter()
        .enumerate()
        .map(|(k, g)| {
            let sel: Vec<&(f64, f64, f64, f64)> = pts.iter().filter(|p| p.3 == *g).collect();
            let label = match &s.group {
                Some(_) => format!("{} = {}", s.label, crate::report::plot::tick(*g)),
                None => s.label.clone(),
            };
            let mut out = Series::new(label, style, sel.iter().map(|p| (p.0, p.1)).collect(), base + k);
            if s.err.is_some() {
                out = out.with_errors(sel.iter().map(|p| p.2).collect());
            }
            out
        })
        .collect())
}

/// The dashed curves of a `power-law-fit` stage: one per regime, over its fitted range.
fn fit_series(ctx: &StageCtx, f: &FitOverlay, color: usize) -> anyhow::Result<Vec<Series>> {
    let inp = ctx.inputs_of(&f.from).first().ok_or_else(|| {
        anyhow!(
            "stage `{}`: fit `{}` reads role `{}`, which names no input",
            ctx.id,
            f.label,
            f.from
        )
    })?;
    let t = inp.table("table")?;
    let (lo, hi) = (col_f64(&t, "x_min")?, col_f64(&t, "x_max")?);
    let (n, se, c) = (
        col_f64(&t, "exponent")?,
        col_f64(&t, "exponent_se")?,
        col_f64(&t, "prefactor")?,
    );
    Ok((0..t.height())
        .map(|k| {
            let pts = (0..40).map(|i| {
                let x = lo[k] * (hi[k] / lo[k]).powf(i as f64 / 39.0);
                (x, c[k] * x.powf(n[k]))
            });
            let regime = if t.height() > 1 {
                if k == 0 { " (low)" } else { " (high)" }
            } else {
                ""
            };
            Series::new(
                format!("fit {}{regime}: {:.3}·x^({:.3} ± {:.3})", f.label, c[k], n[k], se[k]),
                Style::Dashed,
                pts.collect(),
                f.color.unwrap_or(color),
            )
        })
        .collect())
}

fn run(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: PlotParams = decode(ctx)?;
    let caption = ctx.caption.clone().unwrap_or_else(|| ctx.id.clone());
    let mut charts = Vec::new();
    let mut out = Output::default();
    for panel in &p.panels {
        let mut series = Vec::new();
        for (j, s) in panel.series.iter().enumerate() {
            series.extend(series_of(ctx, s, j)?);
        }
        let n_data = series.len();
        for (j, f) in panel.fits.iter().enumerate() {
            series.extend(fit_series(ctx, f, panel.series.len() + j)?);
        }
        if !panel.laws.is_empty() {
            let role = p.laws_from.as_deref().unwrap_or("laws");
            let laws = ctx
                .inputs_of(role)
                .first()
                .ok_or_else(|| {
                    anyhow!(
                        "stage `{}`: laws need the `reference-laws` stage under role `{role}`",
                        ctx.id
                    )
                })?
                .table("table")?;
            let a = col_f64(&laws, "a")?;
            for (k, l) in panel.laws.iter().enumerate() {
                let v = col_f64(&laws, l)?;
                let label = super::laws::LAWS.iter().find(|x| x.0 == l).map(|x| x.1).unwrap_or(l);
                series.push(Series::new(
                    label,
                    Style::Dashed,
                    a.iter().copied().zip(v).collect(),
                    5 + k,
                ));
            }
        }
        let first = panel.series.len() + panel.fits.len();
        let lines = line_series(
            ctx,
            &panel.lines,
            (panel.x.log, panel.x.range),
            &series[..n_data],
            first,
        )?;
        series.extend(lines);
        // Points drawn are what the figure shows: count them (a golden number that moves
        // when a filter or an upstream sweep silently changes).
        out.scalar(
            &format!("panel{}_points", charts.len()),
            series[..n_data].iter().map(|s| s.points.len() as f64).sum(),
        );
        charts.push(Chart {
            title: panel.title.clone().unwrap_or_else(|| caption.clone()),
            footer: String::new(),
            x_label: panel.x.label.clone(),
            y_label: panel.y.label.clone(),
            x_log: panel.x.log,
            y_log: panel.y.log,
            x_range: panel.x.range.map(|[a, b]| (a, b)),
            y_range: panel.y.range.map(|[a, b]| (a, b)),
            series,
            legend: match panel.legend {
                Corner::UpperLeft => Legend::UpperLeft,
                Corner::UpperRight => Legend::UpperRight,
                Corner::LowerLeft => Legend::LowerLeft,
                Corner::LowerRight => Legend::LowerRight,
            },
        });
    }
    // The figure's footer line with the measured error is stamped at publish for every
    // stage alike (report::measured); the declared error is the figure's own scalar and
    // note (what exactly was measured), not a second footer line.
    if let Some(e) = &p.error {
        let inp = ctx.inputs_of(&e.from).first().ok_or_else(|| {
            anyhow!(
                "stage `{}`: error note reads role `{}`, which names no input",
                ctx.id,
                e.from
            )
        })?;
        let v = inp.scalar(&e.scalar)?;
        out.scalar("profile_error", v);
        out.note(format!(
            "Measured error ({}): {:.3} (`{}` of `{}`).",
            e.label, v, e.scalar, inp.id
        ));
    }
    let cols = p.columns.unwrap_or(charts.len().min(2));
    out.figure("figure", panels_to_svg(&charts, cols, &footer(&ctx.profile, ""))?);
    Ok(out)
}

/// Kind `plot`.
pub const KIND: Kind = Kind {
    name: "plot",
    source: file!(),
    method: None,
    // 3: the shared renderer places legends off the data, tables fitted coefficients,
    // shares the figure width between panels and draws each method's marker (issue 26)
    version: 3,
    about: "a figure declared in YAML: panels of series from upstream tables or sweep scalars, fits and stated laws dashed",
    params: typed::<PlotParams>,
    run,
    explain: None,
    roles: crate::stages::kind::Roles::Named(named_roles),
    outputs: crate::stages::kind::Outputs {
        scalars: &["panel*_points", "profile_error"],
        tables: &[],
        measurements: &[],
        texts: &[],
    },
    reads: Some(reads),
    cost: None,
    atlas: None,
};

/// What the figure names of its inputs (checked at load against their kinds' outputs).
pub fn reads(v: &serde_json::Value) -> Vec<Read> {
    let Ok(p) = serde_json::from_value::<PlotParams>(v.clone()) else {
        return vec![];
    };
    let mut out = Vec::new();
    for (i, panel) in p.panels.iter().enumerate() {
        for (j, s) in panel.series.iter().enumerate() {
            let key = |f: &str| format!("panels[{i}].series[{j}].{f}");
            let mut add = |f: &str, item: Item| {
                out.push(Read {
                    role: s.from.clone(),
                    key: key(f),
                    item,
                })
            };
            match s.source {
                Source::Scalars => {
                    add("x", Item::Scalar(s.x.clone()));
                    add("y", Item::Scalar(s.y.clone()));
                    if let Some(e) = &s.err {
                        add("err", Item::Scalar(e.clone()));
                    }
                    for k in s.filter.keys() {
                        add(&format!("filter.{k}"), Item::Scalar(k.clone()));
                    }
                    if let Some(d) = &s.y_div {
                        add("y_div", Item::Scalar(d.clone()));
                    }
                }
                Source::Table => {
                    let col = |c: &String| Item::Column(s.table.clone(), c.clone());
                    add("table", Item::Table(s.table.clone()));
                    match &s.x_table {
                        Some(t) => {
                            add("x_table", Item::Table(t.clone()));
                            add("x", Item::Column(t.clone(), s.x.clone()));
                        }
                        None => add("x", col(&s.x)),
                    }
                    add("y", col(&s.y));
                    if let Some(e) = &s.err {
                        add("err", col(e));
                    }
                    for k in s.filter.keys() {
                        add(&format!("filter.{k}"), col(k));
                    }
                    if let Some(d) = &s.y_div {
                        add("y_div", Item::ColumnOrScalar(s.table.clone(), d.clone()));
                    }
                    if let Some(d) = &s.y_div_initial {
                        add("y_div_initial", col(d));
                    }
                    if let Some(g) = &s.group {
                        add("group", col(g));
                    }
                }
            }
        }
    }
    for (i, panel) in p.panels.iter().enumerate() {
        for (j, l) in panel.lines.iter().enumerate() {
            let Some(role) = &l.from else { continue };
            for (c, f) in [(&l.intercept, "intercept"), (&l.slope, "slope")] {
                if let Coef::Scalar(s) = c {
                    out.push(Read {
                        role: role.clone(),
                        key: format!("panels[{i}].lines[{j}].{f}"),
                        item: Item::Scalar(s.clone()),
                    });
                }
            }
        }
    }
    if let Some(e) = &p.error {
        out.push(Read {
            role: e.from.clone(),
            key: "error.scalar".into(),
            item: Item::Scalar(e.scalar.clone()),
        });
    }
    out
}

/// Roles: those the params read.
fn named_roles(v: &serde_json::Value) -> Option<Vec<String>> {
    serde_json::from_value::<PlotParams>(v.clone()).ok().map(|p| p.roles())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roles_are_the_declared_sources() {
        let p: PlotParams = serde_json::from_value(serde_json::json!({
            "panels": [{ "x": {"label": "a", "log": true}, "y": {"label": "r"},
                "series": [{ "from": "dem", "source": "scalars", "x": "a", "y": "runout_norm", "label": "DEM" },
                           { "from": "mpm", "x": "a", "y": "r", "label": "MPM" }],
                "fits": [{ "from": "fit_dem", "label": "DEM" }], "laws": ["eq4_6_runout"] }],
            "laws_from": "laws"
        }))
        .unwrap();
        assert_eq!(p.roles(), vec!["dem", "mpm", "fit_dem", "laws"]);
        assert!(p.validate().is_empty());
    }

    #[test]
    fn laws_need_their_role_and_known_names() {
        let p: PlotParams = serde_json::from_value(serde_json::json!({
            "panels": [{ "x": {"label": "a"}, "y": {"label": "r"}, "laws": ["eq9_9"] }]
        }))
        .unwrap();
        let keys: Vec<String> = p.validate().into_iter().map(|i| i.key).collect();
        assert!(
            keys.contains(&"panels[0].laws".to_string()) && keys.contains(&"laws_from".to_string()),
            "{keys:?}"
        );
    }
}
