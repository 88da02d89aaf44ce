//! Inertial number from coarse-grained fields (docs/definitions.md D08), the same for
//! grains and points: the bodies are binned on a square grid of side `cell`; per cell the
//! mass-weighted velocity, the strain rate by central differences between the four
//! neighbours (cells whose four neighbours all hold mass; free-surface and edge cells have
//! no two-sided gradient and are left out), γ̇ = √(2 D':D') with the 2D deviator
//! (= |dv_x/dy| in simple shear), and the lithostatic pressure p = g·(mass above in the
//! cell column + half the cell's own)/cell — the weight of the overburden, which neither
//! method's contact or stress noise enters. I = γ̇ d̄ / √(p/ρ_s).
//! Statistics are over *flowing* cells (γ̇ > 1e-3 √(g/d̄)), weighted by cell mass.

use super::cloud::Cloud;

/// Default coarse-graining cell [d̄] (3 d̄).
pub const DEFAULT_CELL_D: f64 = 3.0;

/// Whether a cell setting is the default (parameter files omit it; keeps cache keys of
/// stages written before the setting existed).
pub fn is_default_cell(v: &f64) -> bool {
    *v == DEFAULT_CELL_D
}

/// Settings: cell side [m], d̄ [m], grain density ρ_s [kg/m³], gravity [m/s²].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grain {
    /// Coarse-graining cell side [m].
    pub cell: f64,
    /// Mean grain diameter d̄ [m].
    pub d: f64,
    /// Grain density ρ_s [kg/m³].
    pub rho_s: f64,
    /// Gravity [m/s²].
    pub g: f64,
}

/// I statistics at one instant (zeros when nothing flows).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Stats {
    /// Mass-weighted mean of I over flowing cells [-].
    pub mean: f64,
    /// Mass-weighted median [-].
    pub median: f64,
    /// 95th percentile (by mass) [-].
    pub p95: f64,
    /// Largest I of a flowing cell [-].
    pub max: f64,
    /// Mass fraction in flowing cells [-].
    pub flowing_fraction: f64,
}

/// Mass-weighted mean, median, 95th percentile and max of (value, weight) pairs, with
/// the flowing fraction `frac` passed through.
pub fn weighted_stats(mut v: Vec<(f64, f64)>, frac: f64) -> Stats {
    if v.is_empty() {
        return Stats {
            flowing_fraction: frac,
            ..Default::default()
        };
    }
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    let w: f64 = v.iter().map(|p| p.1).sum();
    let mean = v.iter().map(|p| p.0 * p.1).sum::<f64>() / w;
    let q = |f: f64| {
        let mut acc = 0.0;
        for p in &v {
            acc += p.1;
            if acc >= f * w {
                return p.0;
            }
        }
        v[v.len() - 1].0
    };
    Stats {
        mean,
        median: q(0.5),
        p95: q(0.95),
        max: v[v.len() - 1].0,
        flowing_fraction: frac,
    }
}

/// Coarse-grained I statistics of `c` (see the module docs).
pub fn coarse_grained(c: &Cloud, gr: Grain) -> Stats {
    if c.is_empty() || !(gr.cell > 0.0) {
        return Stats::default();
    }
    let h = gr.cell;
    let x0 = c.x.iter().cloned().fold(f64::INFINITY, f64::min);
    let y0 = c.y.iter().cloned().fold(f64::INFINITY, f64::min).min(0.0);
    let nx = (((c.x.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - x0) / h).floor() as usize + 1).min(1 << 14);
    let ny = (((c.y.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - y0) / h).floor() as usize + 1).min(1 << 14);
    let mut m = vec![0.0f64; nx * ny];
    let mut px = vec![0.0f64; nx * ny];
    let mut py = vec![0.0f64; nx * ny];
    for i in 0..c.len() {
        let cx = (((c.x[i] - x0) / h) as usize).min(nx - 1);
        let cy = (((c.y[i] - y0) / h) as usize).min(ny - 1);
        let k = cy * nx + cx;
        m[k] += c.mass[i];
        px[k] += c.mass[i] * c.vx[i];
        py[k] += c.mass[i] * c.vy[i];
    }
    let vel = |k: usize| (px[k] / m[k], py[k] / m[k]);
    let total: f64 = m.iter().sum();
    let thr = 1e-3 * (gr.g / gr.d).sqrt();
    let mut vals = Vec::new();
    let mut mflow = 0.0;
    for ix in 1..nx.saturating_sub(1) {
        let mut above = 0.0;
        for iy in (0..ny).rev() {
            let k = iy * nx + ix;
            let own = m[k];
            let p = gr.g * (above + 0.5 * own) / h;
            above += own;
            if iy == 0 || iy + 1 >= ny || own <= 0.0 {
                continue;
            }
            let (e, w, n, s) = (k + 1, k - 1, k + nx, k - nx);
            if m[e] <= 0.0 || m[w] <= 0.0 || m[n] <= 0.0 || m[s] <= 0.0 {
                continue;
            }
            let (vxe, vye) = vel(e);
            let (vxw, vyw) = vel(w);
            let (vxn, vyn) = vel(n);
            let (vxs, vys) = vel(s);
            let dxx = (vxe - vxw) / (2.0 * h);
            let dyy = (vyn - vys) / (2.0 * h);
            let dxy = 0.5 * ((vxn - vxs) / (2.0 * h) + (vye - vyw) / (2.0 * h));
            let gd = ((dxx - dyy).powi(2) + 4.0 * dxy * dxy).sqrt();
            if gd > thr && p > 0.0 {
                vals.push((gd * gr.d / (p / gr.rho_s).sqrt(), own));
                mflow += own;
            }
        }
    }
    weighted_stats(vals, if total > 0.0 { mflow / total } else { 0.0 })
}
