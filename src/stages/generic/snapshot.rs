//! Kind `snapshot`: particle or material-point fields drawn to scale, declared in YAML —
//! panels of one upstream table's rows (a filter picks the instant), coloured by a column
//! with ONE colour range shared by every panel (figs 4.7–4.10: DEM random, DEM hexagonal
//! and MPM side by side at τ_c and 3τ_c). The collapse stages write the rows
//! (`snapshots` table, one block per instant: [`dem_rows`], [`mpm_rows`]); this kind only
//! draws, so DEM grains and MPM points go through the same code.

use std::collections::BTreeMap;

use anyhow::anyhow;
use polars::prelude::DataFrame;
use serde::{Deserialize, Serialize};

use crate::pipeline::context::{Output, StageCtx, col_f64, frame};
use crate::report::plot::footer;
use crate::report::snapshot::{Field, Segment, Shape, Snapshot};
use crate::stages::kind::{Item, Read};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// The `snapshots` table of a DEM collapse: one block of rows per instant.
pub fn dem_rows(snaps: &[crate::dem::column::Snapshot], tau_c: f64) -> anyhow::Result<DataFrame> {
    let mut c: BTreeMap<&str, Vec<f64>> = BTreeMap::new();
    for (k, s) in snaps.iter().enumerate() {
        let st = &s.state;
        for i in 0..st.x.len() {
            push(&mut c, k, s.t / tau_c, st.x[i], st.y[i], st.r[i], st.vx[i], st.vy[i]);
        }
    }
    table(c)
}

/// The `snapshots` table of an MPM collapse; `half` is a point's domain half-width.
pub fn mpm_rows(snaps: &[crate::mpm::column::Snapshot], tau_c: f64, half: f64) -> anyhow::Result<DataFrame> {
    let mut c: BTreeMap<&str, Vec<f64>> = BTreeMap::new();
    for (k, s) in snaps.iter().enumerate() {
        for i in 0..s.x.len() {
            push(&mut c, k, s.t / tau_c, s.x[i], s.y[i], half, s.vx[i], s.vy[i]);
        }
    }
    table(c)
}

/// The `snapshots` table of any run from frames (pile runs: DEM and CD grains, MPM points),
/// with the time column `time_col` (t / `t_unit`) and, when the frames carry it, σ_yy.
pub fn frame_rows(
    frames: &[crate::analysis::pile::Frame],
    time_col: &'static str,
    t_unit: f64,
) -> anyhow::Result<DataFrame> {
    let mut cols: Vec<(&str, Vec<f64>)> = ["k", time_col, "x_m", "y_m", "half_m", "vx_m_s", "vy_m_s", "speed_m_s"]
        .iter()
        .map(|n| (*n, Vec::new()))
        .collect();
    let stress = !frames.is_empty() && frames.iter().all(|f| f.sigma_yy.len() == f.x.len());
    if stress {
        cols.push(("sigma_yy_pa", Vec::new()));
    }
    for (k, f) in frames.iter().enumerate() {
        for i in 0..f.x.len() {
            let row = [
                k as f64,
                f.t / t_unit,
                f.x[i],
                f.y[i],
                f.half[i],
                f.vx[i],
                f.vy[i],
                f.vx[i].hypot(f.vy[i]),
            ];
            for (c, v) in cols.iter_mut().zip(row) {
                c.1.push(v);
            }
            if stress {
                cols[8].1.push(f.sigma_yy[i]);
            }
        }
    }
    frame(cols)
}

#[allow(clippy::too_many_arguments)]
fn push(c: &mut BTreeMap<&str, Vec<f64>>, k: usize, t: f64, x: f64, y: f64, half: f64, vx: f64, vy: f64) {
    for (name, v) in [
        ("k", k as f64),
        ("t_over_tau_c", t),
        ("x_m", x),
        ("y_m", y),
        ("half_m", half),
        ("vx_m_s", vx),
        ("vy_m_s", vy),
        ("speed_m_s", vx.hypot(vy)),
    ] {
        c.entry(name).or_default().push(v);
    }
}

fn table(c: BTreeMap<&str, Vec<f64>>) -> anyhow::Result<DataFrame> {
    let order = [
        "k", "t_over_tau_c", "x_m", "y_m", "half_m", "vx_m_s", "vy_m_s", "speed_m_s",
    ];
    frame(
        order
            .iter()
            .map(|n| (*n, c.get(n).cloned().unwrap_or_default()))
            .collect(),
    )
}

/// Body shape.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Default)]
#[serde(rename_all = "snake_case")]
pub enum Body {
    /// DEM grain (half_m = radius).
    #[default]
    Disk,
    /// MPM point domain (half_m = half-width).
    Square,
}

/// One panel: rows of a role's table at one instant.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SnapPanel {
    /// Input role.
    pub from: String,
    /// Table (default `snapshots`).
    #[serde(default = "snap_table")]
    pub table: String,
    /// Snapshot index (column `k`).
    pub k: usize,
    /// Panel title.
    pub title: String,
    /// Body shape.
    #[serde(default)]
    pub shape: Body,
    /// Column colouring this panel (default: the stage's `colour`; `none`: uniform fill).
    /// Panels coloured by the same column share one range.
    #[serde(default)]
    pub colour: Option<String>,
    /// Colour-bar label of this panel's column (default: the stage's `colour_label`).
    #[serde(default)]
    pub colour_label: Option<String>,
    /// View window of this panel [x0, x1, y0, y1] m (a zoom; default: the stage's view).
    #[serde(default)]
    pub view: Option<[f64; 4]>,
    /// Draw background-grid lines every `grid_m` metres (MPM cells, fig4-24a).
    #[serde(default)]
    pub grid_m: Option<f64>,
    /// One panel per input of the role (a matrix: figs 4.27/4.28, one per PPC), in input
    /// order, each titled `title` followed by the value of this parameter path of its
    /// stage (e.g. `mpm.ppc`). Absent: the role's first input.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub each: Option<String>,
}

/// The time column of the upstream `snapshots` tables and its unit in titles.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TimeAxis {
    /// Column name.
    pub column: String,
    /// Unit shown in panel titles.
    pub unit: String,
}

impl Default for TimeAxis {
    fn default() -> Self {
        TimeAxis {
            column: "t_over_tau_c".into(),
            unit: "τ_c".into(),
        }
    }
}

/// Parameters of a `snapshot` stage.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SnapParams {
    /// Panels, row-major.
    pub panels: Vec<SnapPanel>,
    /// Panels per row.
    #[serde(default = "three")]
    pub columns: usize,
    /// Column that colours the bodies.
    #[serde(default = "speed")]
    pub colour: String,
    /// Colour-bar label.
    #[serde(default = "speed_label")]
    pub colour_label: String,
    /// Shared colour range [lo, hi]; default: 0 to the largest value over all panels.
    #[serde(default)]
    pub range: Option<[f64; 2]>,
    /// One view window for every panel [x0, x1, y0, y1] in metres; default: the union of
    /// the panels' extents (same scale everywhere).
    #[serde(default)]
    pub view: Option<[f64; 4]>,
    /// Time column and unit (columns: t/τ_c; piles: `t_over_sqrt_d_g`, √(d/g)).
    #[serde(default)]
    pub time: TimeAxis,
}

fn snap_table() -> String {
    "snapshots".into()
}
fn three() -> usize {
    3
}
fn speed() -> String {
    "speed_m_s".into()
}
fn speed_label() -> String {
    "|v| [m/s]".into()
}

impl SnapParams {
    /// Input roles read.
    pub fn roles(&self) -> Vec<String> {
        let mut r: Vec<String> = Vec::new();
        for p in &self.panels {
            if !r.contains(&p.from) {
                r.push(p.from.clone());
            }
        }
        r
    }
}

impl Validate for SnapParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.check(
            !self.panels.is_empty() && self.panels.len() <= 12,
            "panels",
            self.panels.len(),
            "1 to 12 panels",
        );
        c.check(
            (1..=4).contains(&self.columns),
            "columns",
            self.columns,
            "1 to 4 panels per row",
        );
        if let Some([lo, hi]) = self.range {
            c.check(
                lo.is_finite() && hi.is_finite() && hi > lo,
                "range",
                format!("[{lo}, {hi}]"),
                "[lo, hi] with lo < hi",
            );
        }
        let view_ok = |v: [f64; 4]| v.iter().all(|x| x.is_finite()) && v[1] > v[0] && v[3] > v[2];
        if let Some(v) = self.view {
            c.check(
                view_ok(v),
                "view",
                format!("{v:?}"),
                "[x0, x1, y0, y1] in metres with x0 < x1, y0 < y1",
            );
        }
        for (i, p) in self.panels.iter().enumerate() {
            if let Some(v) = p.view {
                c.check(
                    view_ok(v),
                    &format!("panels[{i}].view"),
                    format!("{v:?}"),
                    "[x0, x1, y0, y1] in metres with x0 < x1, y0 < y1",
                );
            }
            if let Some(g) = p.grid_m {
                c.check(
                    g.is_finite() && g > 0.0,
                    &format!("panels[{i}].grid_m"),
                    g,
                    "a grid spacing > 0 [m]",
                );
            }
        }
        c.check(
            !self.time.column.is_empty(),
            "time.column",
            "\"\"",
            "the name of the upstream tables' time column",
        );
        c.issues
    }
}

struct Rows {
    x: Vec<f64>,
    y: Vec<f64>,
    half: Vec<f64>,
    v: Vec<f64>,
    t: f64,
}

impl SnapParams {
    /// The column colouring `panel` (None: uniform fill).
    fn colour_of<'a>(&'a self, panel: &'a SnapPanel) -> Option<&'a str> {
        let c = panel.colour.as_deref().unwrap_or(&self.colour);
        (c != "none").then_some(c)
    }
}

/// The declared panels with `each` expanded: (panel, index of its input in the role).
fn expand(ctx: &StageCtx, p: &SnapParams) -> anyhow::Result<Vec<(SnapPanel, usize)>> {
    let mut out = Vec::new();
    for panel in &p.panels {
        let Some(path) = &panel.each else {
            out.push((panel.clone(), 0));
            continue;
        };
        let inputs = ctx.inputs_of(&panel.from);
        anyhow::ensure!(
            !inputs.is_empty(),
            "stage `{}`: panel `{}` reads role `{}`, which names no input",
            ctx.id,
            panel.title,
            panel.from
        );
        for (i, inp) in inputs.iter().enumerate() {
            let v = path.split('.').try_fold(&inp.params, |v, k| v.get(k)).ok_or_else(|| {
                anyhow!(
                    "stage `{}`: panels `each: {path}`: input `{}` has no parameter `{path}`",
                    ctx.id,
                    inp.id
                )
            })?;
            let shown = v.as_f64().map(|x| format!("{x}")).unwrap_or_else(|| v.to_string());
            out.push((
                SnapPanel {
                    title: format!("{} {shown}", panel.title),
                    each: None,
                    ..panel.clone()
                },
                i,
            ));
        }
    }
    anyhow::ensure!(
        out.len() <= 12,
        "stage `{}`: {} panels after expanding `each` (at most 12)",
        ctx.id,
        out.len()
    );
    Ok(out)
}

fn rows(ctx: &StageCtx, p: &SnapParams, panel: &SnapPanel, input: usize) -> anyhow::Result<Rows> {
    let inp = ctx.inputs_of(&panel.from).get(input).ok_or_else(|| {
        anyhow!(
            "stage `{}`: panel `{}` reads role `{}`, which names no input",
            ctx.id,
            panel.title,
            panel.from
        )
    })?;
    let df = inp.table(&panel.table)?;
    let k = col_f64(&df, "k")?;
    let keep: Vec<usize> = (0..k.len()).filter(|&i| k[i] == panel.k as f64).collect();
    anyhow::ensure!(
        !keep.is_empty(),
        "input `{}` table `{}` has no snapshot k = {} (its run stopped before that instant?)",
        inp.id,
        panel.table,
        panel.k
    );
    let pick = |name: &str| -> anyhow::Result<Vec<f64>> {
        let c = col_f64(&df, name).map_err(|e| anyhow!("input `{}` table `{}`: {e}", inp.id, panel.table))?;
        Ok(keep.iter().map(|&i| c[i]).collect())
    };
    let v = match p.colour_of(panel) {
        Some(c) => pick(c)?,
        None => Vec::new(),
    };
    Ok(Rows {
        x: pick("x_m")?,
        y: pick("y_m")?,
        half: pick("half_m")?,
        v,
        t: pick(&p.time.column)?[0],
    })
}

/// Place standalone SVG documents side by side (row-major) in one document.
fn tile(svgs: &[String], cols: usize, foot: &str) -> String {
    let dims: Vec<(f64, f64)> = svgs
        .iter()
        .map(|s| {
            let attr = |a: &str| -> f64 {
                s.split(&format!(" {a}=\""))
                    .nth(1)
                    .and_then(|r| r.split('"').next())
                    .and_then(|v| v.parse().ok())
                    .unwrap_or(400.0)
            };
            (attr("width"), attr("height"))
        })
        .collect();
    let rows = svgs.len().div_ceil(cols);
    let col_w: Vec<f64> = (0..cols)
        .map(|c| {
            (0..rows)
                .filter_map(|r| dims.get(r * cols + c))
                .map(|d| d.0)
                .fold(0.0, f64::max)
        })
        .collect();
    let row_h: Vec<f64> = (0..rows)
        .map(|r| {
            (0..cols)
                .filter_map(|c| dims.get(r * cols + c))
                .map(|d| d.1)
                .fold(0.0, f64::max)
        })
        .collect();
    let (w, h) = (col_w.iter().sum::<f64>(), row_h.iter().sum::<f64>() + 28.0);
    let mut out = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w:.0}\" height=\"{h:.0}\" viewBox=\"0 0 {w:.1} {h:.1}\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    for (i, s) in svgs.iter().enumerate() {
        let (r, c) = (i / cols, i % cols);
        let (x, y) = (
            col_w[..c].iter().fold(0.0, |a, b| a + b),
            row_h[..r].iter().fold(0.0, |a, b| a + b),
        );
        out.push_str(&s.replacen("<svg ", &format!("<svg x=\"{x:.1}\" y=\"{y:.1}\" "), 1));
        out.push('\n');
    }
    out.push_str(&format!(
        "<text x=\"8\" y=\"{:.1}\" font-family=\"sans-serif\" font-size=\"12\" fill=\"#5a5a5a\">{}</text>\n</svg>\n",
        h - 9.0,
        foot.replace('&', "&amp;").replace('<', "&lt;")
    ));
    out
}

fn run(ctx: &StageCtx) -> anyhow::Result<Output> {
    let mut p: SnapParams = decode(ctx)?;
    let expanded = expand(ctx, &p)?;
    let data: Vec<Rows> = expanded
        .iter()
        .map(|(panel, i)| rows(ctx, &p, panel, *i))
        .collect::<anyhow::Result<_>>()?;
    p.panels = expanded.into_iter().map(|(panel, _)| panel).collect();
    // One colour range per colouring column, shared by the panels it colours.
    let range_of = |col: &str| -> (f64, f64) {
        if col == p.colour
            && let Some([a, b]) = p.range
        {
            return (a, b);
        }
        let vals = p
            .panels
            .iter()
            .zip(&data)
            .filter(|(q, _)| p.colour_of(q) == Some(col))
            .flat_map(|(_, r)| r.v.iter().copied())
            .filter(|v| v.is_finite());
        let (lo, hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        // Non-negative fields (speeds) start at 0, as before; signed ones (σ_yy, v_x) span their values.
        let lo = if lo >= 0.0 { 0.0 } else { lo };
        (lo, if hi > lo { hi } else { lo + 1e-12 })
    };
    let view = p.view.map(|[a, b, c, d]| (a, b, c, d)).unwrap_or_else(|| {
        let mut v = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for r in &data {
            for i in 0..r.x.len() {
                v.1 = v.1.max(r.x[i] + r.half[i]);
                v.3 = v.3.max(r.y[i] + r.half[i]);
                v.0 = v.0.min(r.x[i] - r.half[i]);
            }
        }
        let pad = 0.03 * (v.1 - v.0).max(v.3 - v.2);
        (v.0 - pad, v.1 + pad, -pad, v.3 + pad)
    });
    let mut out = Output::default();
    let mut svgs = Vec::new();
    let mut ranges: Vec<(String, String, (f64, f64))> = Vec::new();
    for (k, (panel, r)) in p.panels.iter().zip(&data).enumerate() {
        let col = p.colour_of(panel);
        let view = panel.view.map(|[a, b, c, d]| (a, b, c, d)).unwrap_or(view);
        out.scalar(&format!("panel{k}_bodies"), r.x.len() as f64)
            .scalar(&format!("panel{k}_{}", p.time.column), r.t);
        let field = col.map(|c| {
            let range = range_of(c);
            let label = panel.colour_label.clone().unwrap_or_else(|| {
                if c == p.colour {
                    p.colour_label.clone()
                } else {
                    c.to_string()
                }
            });
            out.scalar(
                &format!("panel{k}_max_{c}"),
                r.v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            );
            if !ranges.iter().any(|x| x.0 == c) {
                ranges.push((c.to_string(), label.clone(), range));
            }
            Field {
                values: &r.v,
                label,
                range,
            }
        });
        let mut segments = vec![Segment {
            a: (view.0, 0.0),
            b: (view.1, 0.0),
            color: "black",
            width: 2.0,
            dashed: false,
        }];
        if let Some(g) = panel.grid_m {
            let (i0, i1) = ((view.0 / g).ceil() as i64, (view.1 / g).floor() as i64);
            for i in i0..=i1 {
                segments.push(Segment {
                    a: (i as f64 * g, view.2),
                    b: (i as f64 * g, view.3),
                    color: "#888",
                    width: 0.6,
                    dashed: false,
                });
            }
            let (j0, j1) = ((view.2 / g).ceil() as i64, (view.3 / g).floor() as i64);
            for j in j0..=j1 {
                segments.push(Segment {
                    a: (view.0, j as f64 * g),
                    b: (view.1, j as f64 * g),
                    color: "#888",
                    width: 0.6,
                    dashed: false,
                });
            }
        }
        let snap = Snapshot {
            title: format!("{} (t = {:.2} {})", panel.title, r.t, p.time.unit),
            footer: String::new(),
            x: &r.x,
            y: &r.y,
            half: &r.half,
            shape: match panel.shape {
                Body::Disk => Shape::Disk,
                Body::Square => Shape::Square,
            },
            field,
            black: None,
            fill: None,
            segments,
            view: Some(view),
            width_px: 420.0,
        };
        svgs.push(snap.to_svg());
    }
    let range = ranges
        .iter()
        .find(|x| x.0 == p.colour)
        .map(|x| x.2)
        .or(ranges.first().map(|x| x.2))
        .unwrap_or((0.0, 0.0));
    out.scalar("colour_max", range.1);
    if ranges.len() > 1 {
        for (c, _, r) in &ranges {
            out.scalar(&format!("range_{c}_lo"), r.0)
                .scalar(&format!("range_{c}_hi"), r.1);
        }
    }
    let shared: Vec<String> = ranges
        .iter()
        .map(|(_, l, r)| format!("{l} from {:.3} to {:.3}", r.0, r.1))
        .collect();
    let foot = if ranges.len() == 1 {
        footer(
            &ctx.profile,
            &format!(
                "one colour range for every panel: {} from {:.3} to {:.3}",
                ranges[0].1, range.0, range.1
            ),
        )
    } else {
        footer(
            &ctx.profile,
            &format!(
                "one colour range per field, shared by its panels: {}",
                shared.join("; ")
            ),
        )
    };
    out.figure("figure", tile(&svgs, p.columns, &foot));
    Ok(out)
}

/// Kind `snapshot`.
pub const KIND: Kind = Kind {
    name: "snapshot",
    source: file!(),
    method: None,
    version: 2,
    about: "particle / material-point snapshots declared in YAML: panels of upstream snapshot rows, one shared colour range",
    params: typed::<SnapParams>,
    run,
    explain: None,
    roles: crate::stages::kind::Roles::Named(named_roles),
    outputs: crate::stages::kind::Outputs {
        scalars: &["colour_max", "panel*", "range_*_hi", "range_*_lo"],
        tables: &[],
        measurements: &[],
        texts: &[],
    },
    reads: Some(reads),
    cost: None,
    atlas: None,
};

/// What the panels name of their inputs (checked at load).
pub fn reads(v: &serde_json::Value) -> Vec<Read> {
    let Ok(p) = serde_json::from_value::<SnapParams>(v.clone()) else {
        return vec![];
    };
    let mut out = Vec::new();
    for (i, panel) in p.panels.iter().enumerate() {
        let mut add = |f: &str, item: Item| {
            out.push(Read {
                role: panel.from.clone(),
                key: format!("panels[{i}].{f}"),
                item,
            })
        };
        add("table", Item::Table(panel.table.clone()));
        add("time.column", Item::Column(panel.table.clone(), p.time.column.clone()));
        let colour = panel.colour.as_ref().unwrap_or(&p.colour);
        if colour != "none" {
            add("colour", Item::Column(panel.table.clone(), colour.clone()));
        }
    }
    out
}

/// Roles: those the panels read.
fn named_roles(v: &serde_json::Value) -> Option<Vec<String>> {
    serde_json::from_value::<SnapParams>(v.clone()).ok().map(|p| p.roles())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_keep_every_panel() {
        let a = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"100\" height=\"50\" viewBox=\"0 0 100 50\"><circle/></svg>".to_string();
        let s = tile(&[a.clone(), a.clone(), a], 2, "f");
        assert_eq!(s.matches("<circle/>").count(), 3);
        assert!(
            s.contains("<svg x=\"100.0\" y=\"0.0\"") && s.contains("<svg x=\"0.0\" y=\"50.0\""),
            "{s}"
        );
        assert!(s.contains("width=\"200\" height=\"128\""), "{s}");
    }
}
