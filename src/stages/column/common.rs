//! What the column study's analysis kinds share: readers of a collapse stage's artifacts
//! (the bodies of one instant of its `snapshots` table, a column of one of its tables).

use crate::analysis::front::{Body, Link, main_mass};
use crate::pipeline::context::{InputRef, col_f64};

/// Bodies of the last (or `k`-th) instant of a collapse's `snapshots` table:
/// (t/τ_c, x, y, half) with masses ∝ half² (one density).
pub(crate) struct Snap {
    pub(crate) t: f64,
    pub(crate) x: Vec<f64>,
    pub(crate) y: Vec<f64>,
    pub(crate) half: Vec<f64>,
}

pub(crate) fn snap_of(inp: &InputRef, k: Option<f64>) -> anyhow::Result<Snap> {
    let df = inp.table("snapshots")?;
    let kk = col_f64(&df, "k")?;
    let want = match k {
        Some(v) => v,
        None => kk.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
    };
    let (t, x, y, h) = (
        col_f64(&df, "t_over_tau_c")?,
        col_f64(&df, "x_m")?,
        col_f64(&df, "y_m")?,
        col_f64(&df, "half_m")?,
    );
    let idx: Vec<usize> = (0..kk.len()).filter(|&i| kk[i] == want).collect();
    anyhow::ensure!(
        !idx.is_empty(),
        "input `{}`: its `snapshots` table has no instant k = {want}",
        inp.id
    );
    Ok(Snap {
        t: t[idx[0]],
        x: idx.iter().map(|&i| x[i]).collect(),
        y: idx.iter().map(|&i| y[i]).collect(),
        half: idx.iter().map(|&i| h[i]).collect(),
    })
}

impl Snap {
    /// Volume-mean diameter Σ d³ / Σ d² (docs/definitions.md SC-PSD: d̄).
    pub(crate) fn d_mean(&self) -> f64 {
        let s3: f64 = self.half.iter().map(|h| (2.0 * h).powi(3)).sum();
        let s2: f64 = self.half.iter().map(|h| (2.0 * h).powi(2)).sum();
        s3 / s2
    }
    /// The main mass (D01, edges within `gap` [m]) only.
    pub(crate) fn main(&self, gap: f64) -> Snap {
        let m: Vec<f64> = self.half.iter().map(|h| h * h).collect();
        let idx = main_mass(
            &Body {
                x: &self.x,
                y: &self.y,
                half: &self.half,
                mass: &m,
            },
            Link::Contact { gap },
        );
        Snap {
            t: self.t,
            x: idx.iter().map(|&i| self.x[i]).collect(),
            y: idx.iter().map(|&i| self.y[i]).collect(),
            half: idx.iter().map(|&i| self.half[i]).collect(),
        }
    }
}

pub(crate) fn series(inp: &InputRef, table: &str, col: &str) -> anyhow::Result<Vec<f64>> {
    col_f64(&inp.table(table)?, col).map_err(|e| anyhow::anyhow!("input `{}` table `{table}`: {e}", inp.id))
}
