//! Failure-surface angle from the velocity field (docs/definitions.md D18), for grains or
//! points.
//!
//! Bodies faster than `v_frac` · max|v| are moving, the others static. Inside the initial
//! footprint (x ≤ L_0) the bodies are binned in horizontal slices of height `bin`; in a
//! slice that holds both, the boundary x_b is the right edge of the static bodies (the
//! largest static x) provided some moving body lies to its right. A least-squares line
//! x_b = c + s·y through the slices with y ∈ [0.1, 0.9]·y_top (y_top the highest slice
//! with a boundary) gives the angle from the horizontal, θ = atan2(1, −s): 90° is a
//! vertical surface, < 90° a surface rising from the toe into the column.

use super::cloud::Cloud;

/// The fitted failure line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FailureLine {
    /// Angle from the horizontal [°].
    pub angle_deg: f64,
    /// dx_b/dy of the fit [-].
    pub slope: f64,
    /// x_b at y = 0 [m] (the toe the line starts from).
    pub x_at_base: f64,
    /// Slices in the fit.
    pub n_slices: usize,
    /// Highest slice centre with a boundary [m].
    pub y_top: f64,
    /// Coefficient of determination of the fit [-].
    pub r2: f64,
}

/// D18 at one instant. `l0` the initial column width [m]; `bin` the slice height [m];
/// `v_frac` the moving threshold as a fraction of max|v| (D18: 0.1). None when fewer than
/// three slices hold a boundary.
pub fn failure_line(c: &Cloud, l0: f64, bin: f64, v_frac: f64) -> Option<FailureLine> {
    let speed = c.speed();
    let vmax = speed.iter().cloned().fold(0.0, f64::max);
    if !(vmax > 0.0) || !(bin > 0.0) {
        return None;
    }
    let thr = v_frac * vmax;
    let ymax = c.y.iter().cloned().fold(0.0, f64::max);
    let nb = (ymax / bin).floor() as usize + 1;
    let mut static_right = vec![f64::NEG_INFINITY; nb];
    let mut moving_right = vec![f64::NEG_INFINITY; nb];
    for i in 0..c.len() {
        if c.x[i] > l0 || c.y[i] < 0.0 {
            continue;
        }
        let k = ((c.y[i] / bin) as usize).min(nb - 1);
        if speed[i] > thr {
            moving_right[k] = moving_right[k].max(c.x[i]);
        } else {
            static_right[k] = static_right[k].max(c.x[i]);
        }
    }
    let pts: Vec<(f64, f64)> = (0..nb)
        .filter(|&k| static_right[k].is_finite() && moving_right[k] > static_right[k])
        .map(|k| ((k as f64 + 0.5) * bin, static_right[k]))
        .collect();
    let y_top = pts.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    let sel: Vec<(f64, f64)> = pts
        .into_iter()
        .filter(|p| p.0 >= 0.1 * y_top && p.0 <= 0.9 * y_top)
        .collect();
    if sel.len() < 3 {
        return None;
    }
    let n = sel.len() as f64;
    let my = sel.iter().map(|p| p.0).sum::<f64>() / n;
    let mx = sel.iter().map(|p| p.1).sum::<f64>() / n;
    let syy = sel.iter().map(|p| (p.0 - my).powi(2)).sum::<f64>();
    let sxy = sel.iter().map(|p| (p.0 - my) * (p.1 - mx)).sum::<f64>();
    let sxx = sel.iter().map(|p| (p.1 - mx).powi(2)).sum::<f64>();
    if !(syy > 0.0) {
        return None;
    }
    let s = sxy / syy;
    let r2 = if sxx > 0.0 { sxy * sxy / (sxx * syy) } else { 1.0 };
    Some(FailureLine {
        angle_deg: 1.0f64.atan2(-s).to_degrees(),
        slope: s,
        x_at_base: mx - s * my,
        n_slices: sel.len(),
        y_top,
        r2,
    })
}

/// The Mohr–Coulomb (active Rankine) failure-plane angle 45° + φ/2 [°].
pub fn mohr_coulomb_angle_deg(phi_deg: f64) -> f64 {
    45.0 + 0.5 * phi_deg
}
