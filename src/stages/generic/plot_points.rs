//! A `plot` series: its declaration, and its points read from one input — the rows of a
//! table after the series' filter and normalisation (x optionally from another table of
//! the input, row for row), or one point from its scalars.

use anyhow::{Context, anyhow};
use polars::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

use crate::pipeline::context::{InputRef, col_f64};

/// Where a series' points come from.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Default)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// Rows of a table of each input of the role (concatenated).
    #[default]
    Table,
    /// One point per input of the role, from its scalars (a sweep over matrix members).
    Scalars,
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Default)]
#[serde(rename_all = "snake_case")]
pub enum Draw {
    /// Markers (measured points; the default).
    #[default]
    Points,
    /// Solid line (time series).
    Line,
    /// Markers joined by a thin line.
    LinePoints,
}

/// One data series.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SeriesSpec {
    /// Input role to read.
    pub from: String,
    /// Table or scalars.
    #[serde(default)]
    pub source: Source,
    /// Table name (source: table).
    #[serde(default = "main_table")]
    pub table: String,
    /// x column / scalar.
    pub x: String,
    /// y column / scalar.
    pub y: String,
    /// ± error column / scalar (drawn as bars).
    #[serde(default)]
    pub err: Option<String>,
    /// Keep rows (or members) whose column (scalar) equals the value.
    #[serde(default)]
    pub filter: BTreeMap<String, serde_json::Value>,
    /// Multiply x by this.
    #[serde(default = "one")]
    pub x_scale: f64,
    /// Multiply y (and its error) by this.
    #[serde(default = "one")]
    pub y_scale: f64,
    /// Divide y (and its error) by this column / scalar (a normalisation, e.g. `l0_m`).
    #[serde(default)]
    pub y_div: Option<String>,
    /// Divide y (and its error) by the first row of this column (table source): a
    /// normalisation by the initial value, e.g. `ep_j` for E/E_0.
    #[serde(default)]
    pub y_div_initial: Option<String>,
    /// Legend label.
    pub label: String,
    /// Drawing.
    #[serde(default)]
    pub draw: Draw,
    /// Palette index (default: the series' position).
    #[serde(default)]
    pub color: Option<usize>,
    /// One series per distinct value of this column (table source), in ascending order,
    /// labelled "`label` = value", colours from `color` on: one curve per run of a table
    /// holding several (e.g. `e0_mgd` of a pile-run `series`). Left out of the canonical
    /// params when absent (no existing plot's cache key moves).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
    /// Read x from this other table of the same input, row for row with `table` (table
    /// source): a stage keeps its wall times in a table of their own (`timing`) so that
    /// `table` stays bit-identical; a work-precision figure draws error against them.
    /// Left out of the canonical params when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x_table: Option<String>,
}

fn main_table() -> String {
    "table".into()
}
fn one() -> f64 {
    1.0
}

/// Does a value (f64 column cell or scalar) match a filter value?
fn matches_num(v: f64, want: &serde_json::Value) -> bool {
    match want {
        serde_json::Value::Number(n) => n.as_f64().is_some_and(|w| (v - w).abs() <= 1e-12 * w.abs().max(1.0)),
        serde_json::Value::Bool(b) => (v != 0.0) == *b,
        _ => false,
    }
}

/// Rows of a table as (x, y, err, group value) after filter and normalisation.
pub(super) fn table_points(inp: &InputRef, s: &SeriesSpec) -> anyhow::Result<Vec<(f64, f64, f64, f64)>> {
    let df = inp.table(&s.table)?;
    let n = df.height();
    let mut keep = vec![true; n];
    for (col, want) in &s.filter {
        let c = df
            .column(col)
            .map_err(|_| anyhow!("input `{}` table `{}` has no column `{col}` (filter)", inp.id, s.table))?;
        if let (DataType::String, Some(w)) = (c.dtype(), want.as_str()) {
            let ca = c.str()?;
            for (k, v) in ca.iter().enumerate() {
                keep[k] &= v == Some(w);
            }
        } else {
            let v = col_f64(&df, col)?;
            for (k, x) in v.iter().enumerate() {
                keep[k] &= matches_num(*x, want);
            }
        }
    }
    let ctx = |what: &str| format!("input `{}` table `{}`: {what}", inp.id, s.table);
    let x = match &s.x_table {
        Some(t) => {
            let dx = inp.table(t)?;
            anyhow::ensure!(
                dx.height() == n,
                "input `{}`: table `{t}` (x_table) has {} rows, table `{}` {n}: they are not row for row",
                inp.id,
                dx.height(),
                s.table
            );
            col_f64(&dx, &s.x).with_context(|| format!("input `{}` table `{t}`: x", inp.id))?
        }
        None => col_f64(&df, &s.x).with_context(|| ctx("x"))?,
    };
    let y = col_f64(&df, &s.y).with_context(|| ctx("y"))?;
    let e = match &s.err {
        Some(c) => col_f64(&df, c).with_context(|| ctx("err"))?,
        None => vec![f64::NAN; n],
    };
    let d = match &s.y_div {
        Some(c) => match col_f64(&df, c) {
            Ok(v) => v,
            Err(_) => vec![
                inp.scalar(c)
                    .with_context(|| ctx("y_div is neither a column nor a scalar"))?;
                n
            ],
        },
        None => vec![1.0; n],
    };
    let d0 = match &s.y_div_initial {
        Some(c) => *col_f64(&df, c)
            .with_context(|| ctx("y_div_initial"))?
            .first()
            .ok_or_else(|| anyhow!("{}", ctx("empty table")))?,
        None => 1.0,
    };
    let d: Vec<f64> = d.into_iter().map(|v| v * d0).collect();
    let g = match &s.group {
        Some(c) => col_f64(&df, c).with_context(|| ctx("group"))?,
        None => vec![0.0; n],
    };
    Ok((0..n)
        .filter(|&k| keep[k])
        .map(|k| (x[k] * s.x_scale, y[k] * s.y_scale / d[k], e[k] * s.y_scale / d[k], g[k]))
        .collect())
}

/// One point from an input's scalars (None when the filter drops it).
pub(super) fn scalar_point(inp: &InputRef, s: &SeriesSpec) -> anyhow::Result<Option<(f64, f64, f64, f64)>> {
    let sc = inp.scalars()?;
    for (k, want) in &s.filter {
        let v = *sc
            .get(k)
            .ok_or_else(|| anyhow!("input `{}` has no scalar `{k}` (filter)", inp.id))?;
        if !matches_num(v, want) {
            return Ok(None);
        }
    }
    let get = |k: &str| {
        sc.get(k)
            .copied()
            .ok_or_else(|| anyhow!("input `{}` has no scalar `{k}`", inp.id))
    };
    let d = match &s.y_div {
        Some(c) => get(c)?,
        None => 1.0,
    };
    let e = match &s.err {
        Some(c) => get(c)?,
        None => f64::NAN,
    };
    Ok(Some((
        get(&s.x)? * s.x_scale,
        get(&s.y)? * s.y_scale / d,
        e * s.y_scale / d,
        0.0,
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numeric_filter() {
        assert!(matches_num(0.4, &serde_json::json!(0.4)));
        assert!(!matches_num(0.4, &serde_json::json!(0.8)));
        assert!(matches_num(1.0, &serde_json::json!(true)));
    }
}
