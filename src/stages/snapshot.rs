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

use super::{Kind, Validate, decode, typed};
use crate::pipeline::context::{Output, StageCtx, col_f64, frame};
use crate::report::plot::footer;
use crate::report::snapshot::{Field, Segment, Shape, Snapshot};
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

#[allow(clippy::too_many_arguments)]
fn push(c: &mut BTreeMap<&str, Vec<f64>>, k: usize, t: f64, x: f64, y: f64, half: f64, vx: f64, vy: f64) {
    for (name, v) in [("k", k as f64), ("t_over_tau_c", t), ("x_m", x), ("y_m", y), ("half_m", half), ("vx_m_s", vx), ("vy_m_s", vy), ("speed_m_s", vx.hypot(vy))] {
        c.entry(name).or_default().push(v);
    }
}

fn table(c: BTreeMap<&str, Vec<f64>>) -> anyhow::Result<DataFrame> {
    let order = ["k", "t_over_tau_c", "x_m", "y_m", "half_m", "vx_m_s", "vy_m_s", "speed_m_s"];
    frame(order.iter().map(|n| (*n, c.get(n).cloned().unwrap_or_default())).collect())
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
        c.check(!self.panels.is_empty() && self.panels.len() <= 12, "panels", self.panels.len(), "1 to 12 panels");
        c.check((1..=4).contains(&self.columns), "columns", self.columns, "1 to 4 panels per row");
        if let Some([lo, hi]) = self.range {
            c.check(lo.is_finite() && hi.is_finite() && hi > lo, "range", format!("[{lo}, {hi}]"), "[lo, hi] with lo < hi");
        }
        if let Some([x0, x1, y0, y1]) = self.view {
            c.check([x0, x1, y0, y1].iter().all(|v| v.is_finite()) && x1 > x0 && y1 > y0, "view", format!("[{x0}, {x1}, {y0}, {y1}]"), "[x0, x1, y0, y1] in metres with x0 < x1, y0 < y1");
        }
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

fn rows(ctx: &StageCtx, p: &SnapParams, panel: &SnapPanel) -> anyhow::Result<Rows> {
    let inp = ctx.inputs_of(&panel.from).first().ok_or_else(|| anyhow!("stage `{}`: panel `{}` reads role `{}`, which names no input", ctx.id, panel.title, panel.from))?;
    let df = inp.table(&panel.table)?;
    let k = col_f64(&df, "k")?;
    let keep: Vec<usize> = (0..k.len()).filter(|&i| k[i] == panel.k as f64).collect();
    anyhow::ensure!(!keep.is_empty(), "input `{}` table `{}` has no snapshot k = {} (its run stopped before that instant?)", inp.id, panel.table, panel.k);
    let pick = |name: &str| -> anyhow::Result<Vec<f64>> {
        let c = col_f64(&df, name).map_err(|e| anyhow!("input `{}` table `{}`: {e}", inp.id, panel.table))?;
        Ok(keep.iter().map(|&i| c[i]).collect())
    };
    Ok(Rows { x: pick("x_m")?, y: pick("y_m")?, half: pick("half_m")?, v: pick(&p.colour)?, t: pick("t_over_tau_c")?[0] })
}

/// Place standalone SVG documents side by side (row-major) in one document.
fn tile(svgs: &[String], cols: usize, foot: &str) -> String {
    let dims: Vec<(f64, f64)> = svgs
        .iter()
        .map(|s| {
            let attr = |a: &str| -> f64 { s.split(&format!(" {a}=\"")).nth(1).and_then(|r| r.split('"').next()).and_then(|v| v.parse().ok()).unwrap_or(400.0) };
            (attr("width"), attr("height"))
        })
        .collect();
    let rows = svgs.len().div_ceil(cols);
    let col_w: Vec<f64> = (0..cols).map(|c| (0..rows).filter_map(|r| dims.get(r * cols + c)).map(|d| d.0).fold(0.0, f64::max)).collect();
    let row_h: Vec<f64> = (0..rows).map(|r| (0..cols).filter_map(|c| dims.get(r * cols + c)).map(|d| d.1).fold(0.0, f64::max)).collect();
    let (w, h) = (col_w.iter().sum::<f64>(), row_h.iter().sum::<f64>() + 28.0);
    let mut out = format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w:.0}\" height=\"{h:.0}\" viewBox=\"0 0 {w:.1} {h:.1}\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n");
    for (i, s) in svgs.iter().enumerate() {
        let (r, c) = (i / cols, i % cols);
        let (x, y) = (col_w[..c].iter().fold(0.0, |a, b| a + b), row_h[..r].iter().fold(0.0, |a, b| a + b));
        out.push_str(&s.replacen("<svg ", &format!("<svg x=\"{x:.1}\" y=\"{y:.1}\" "), 1));
        out.push('\n');
    }
    out.push_str(&format!("<text x=\"8\" y=\"{:.1}\" font-family=\"sans-serif\" font-size=\"12\" fill=\"#5a5a5a\">{}</text>\n</svg>\n", h - 9.0, foot.replace('&', "&amp;").replace('<', "&lt;")));
    out
}

fn run(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: SnapParams = decode(ctx)?;
    let data: Vec<Rows> = p.panels.iter().map(|panel| rows(ctx, &p, panel)).collect::<anyhow::Result<_>>()?;
    let vmax = data.iter().flat_map(|r| r.v.iter().copied()).filter(|v| v.is_finite()).fold(0.0, f64::max);
    let range = p.range.map(|[a, b]| (a, b)).unwrap_or((0.0, vmax.max(1e-12)));
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
    for (k, (panel, r)) in p.panels.iter().zip(&data).enumerate() {
        out.scalar(&format!("panel{k}_bodies"), r.x.len() as f64).scalar(&format!("panel{k}_t_over_tau_c"), r.t).scalar(&format!("panel{k}_max_{}", p.colour), r.v.iter().copied().fold(f64::NEG_INFINITY, f64::max));
        let snap = Snapshot {
            title: format!("{} (t = {:.2} τ_c)", panel.title, r.t),
            footer: String::new(),
            x: &r.x,
            y: &r.y,
            half: &r.half,
            shape: match panel.shape { Body::Disk => Shape::Disk, Body::Square => Shape::Square },
            field: Some(Field { values: &r.v, label: p.colour_label.clone(), range }),
            black: None,
            fill: None,
            segments: vec![Segment { a: (view.0, 0.0), b: (view.1, 0.0), color: "black", width: 2.0, dashed: false }],
            view: Some(view),
            width_px: 420.0,
        };
        svgs.push(snap.to_svg());
    }
    out.scalar("colour_max", range.1);
    let foot = footer(&ctx.profile, &format!("one colour range for every panel: {} from {:.3} to {:.3}", p.colour_label, range.0, range.1));
    out.figure("figure", tile(&svgs, p.columns, &foot));
    Ok(out)
}

/// Kind `snapshot`.
pub const KIND: Kind = Kind {
    name: "snapshot",
    version: 1,
    about: "particle / material-point snapshots declared in YAML: panels of upstream snapshot rows, one shared colour range",
    params: typed::<SnapParams>,
    run,
    explain: None,
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_keep_every_panel() {
        let a = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"100\" height=\"50\" viewBox=\"0 0 100 50\"><circle/></svg>".to_string();
        let s = tile(&[a.clone(), a.clone(), a], 2, "f");
        assert_eq!(s.matches("<circle/>").count(), 3);
        assert!(s.contains("<svg x=\"100.0\" y=\"0.0\"") && s.contains("<svg x=\"0.0\" y=\"50.0\""), "{s}");
        assert!(s.contains("width=\"200\" height=\"128\""), "{s}");
    }
}
