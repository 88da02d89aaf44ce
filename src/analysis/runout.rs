//! Per-run quantities of a column collapse from its time series and end states
//! (docs/definitions.md D05, D10, D17; §4.2 phases), shared by DEM and MPM.

/// Index of the largest value (first on ties; None if empty) — t_KEmax of D05.
pub fn argmax(v: &[f64]) -> Option<usize> {
    let mut best: Option<usize> = None;
    for (k, &x) in v.iter().enumerate() {
        if best.is_none_or(|b| x > v[b]) {
            best = Some(k);
        }
    }
    best
}

/// Least-squares line through the samples with t in [t0, t1]: (slope, R², count).
pub fn line_fit(t: &[f64], y: &[f64], t0: f64, t1: f64) -> (f64, f64, usize) {
    let pts: Vec<(f64, f64)> = t
        .iter()
        .zip(y)
        .filter(|(a, _)| **a >= t0 && **a <= t1)
        .map(|(a, b)| (*a, *b))
        .collect();
    let n = pts.len() as f64;
    if pts.len() < 3 {
        return (f64::NAN, f64::NAN, pts.len());
    }
    let mt = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let stt = pts.iter().map(|p| (p.0 - mt).powi(2)).sum::<f64>();
    let sty = pts.iter().map(|p| (p.0 - mt) * (p.1 - my)).sum::<f64>();
    let syy = pts.iter().map(|p| (p.1 - my).powi(2)).sum::<f64>();
    let r2 = if syy > 0.0 && stt > 0.0 {
        sty * sty / (stt * syy)
    } else {
        f64::NAN
    };
    (sty / stt, r2, pts.len())
}

/// Largest backward move of a front between consecutive samples, in units of `l0`
/// (0 for a front that never moves back). A front that jumps back by a sizeable part of
/// L_0 has lost a part of the mass to its rule, not to the flow (issue 25: ≤ 0.5 L_0).
pub fn max_backward_jump(series: &[f64], l0: f64) -> f64 {
    series.windows(2).map(|w| (w[0] - w[1]) / l0).fold(0.0, f64::max)
}

/// Largest fall of a series below its running maximum (0 if it never falls): the largest
/// backward jump of L(t) counted from the farthest front reached so far [units of the series].
pub fn max_drawdown(series: &[f64]) -> f64 {
    let mut best = f64::NEG_INFINITY;
    let mut drop: f64 = 0.0;
    for &v in series {
        best = best.max(v);
        drop = drop.max(best - v);
    }
    drop
}

/// μ_e from the run-out (eqs 4.8–4.9, D17 first estimator): μ_e = H_0/(L_f − L_0).
pub fn mu_e_geometric(h0: f64, l0: f64, lf: f64) -> f64 {
    h0 / (lf - l0)
}

/// Staron & Hinch's W = g Σ m_p r_p with r_p = |x_end − x_0| the net horizontal
/// distance run by each body (D17 second estimator; the slope of δE against W over the
/// short columns is μ_e, the ratio δE/W is one run's value) [J/m].
pub fn staron_hinch_work(x0: &[f64], x1: &[f64], m: &[f64], g: f64) -> f64 {
    g * x0
        .iter()
        .zip(x1)
        .zip(m)
        .map(|((a, b), m)| m * (b - a).abs())
        .sum::<f64>()
}

/// Staron & Hinch's fitted law μ_e = 0.425 μ^0.2 (D17 third value; a formula of the
/// grain friction μ, not a measurement).
pub fn mu_e_staron_hinch_law(mu: f64) -> f64 {
    0.425 * mu.powf(0.2)
}

/// Free-surface profile of a deposit (docs/definitions.md fig4-20, fig4-12): bins of width
/// `bin` from x = 0 to the farthest edge; each bin's height is the highest top edge (y +
/// half) of the bodies whose centre falls in it (0 for an empty bin). Returns (bin centre,
/// h).
pub fn surface_profile(x: &[f64], y: &[f64], half: &[f64], bin: f64) -> Vec<(f64, f64)> {
    assert!(bin > 0.0, "surface_profile: bin must be positive");
    let x_end = x.iter().zip(half).map(|(a, h)| a + h).fold(0.0, f64::max);
    let nb = ((x_end / bin).ceil() as usize).clamp(1, 1 << 16);
    let mut h = vec![0.0f64; nb];
    for i in 0..x.len() {
        let k = ((x[i].max(0.0) / bin) as usize).min(nb - 1);
        h[k] = h[k].max(y[i] + half[i]);
    }
    h.into_iter()
        .enumerate()
        .map(|(k, v)| ((k as f64 + 0.5) * bin, v))
        .collect()
}

/// R² of the least-squares polynomial of degree 1 or 2 through (x, y) (NaN with too
/// few points or no spread). Centred and scaled x; 3×3 normal equations by Cramer.
pub fn poly_r2(x: &[f64], y: &[f64], degree: usize) -> f64 {
    assert!(degree == 1 || degree == 2, "poly_r2: degree 1 or 2");
    let n = x.len();
    if n < degree + 2 {
        return f64::NAN;
    }
    let mx = x.iter().sum::<f64>() / n as f64;
    let sx = (x.iter().map(|v| (v - mx).powi(2)).sum::<f64>() / n as f64).sqrt();
    let my = y.iter().sum::<f64>() / n as f64;
    let syy: f64 = y.iter().map(|v| (v - my).powi(2)).sum();
    if !(sx > 0.0) || !(syy > 0.0) {
        return f64::NAN;
    }
    let u: Vec<f64> = x.iter().map(|v| (v - mx) / sx).collect();
    let m = degree + 1;
    let mut a = [[0.0f64; 3]; 3];
    let mut b = [0.0f64; 3];
    for (ui, yi) in u.iter().zip(y) {
        let p = [1.0, *ui, ui * ui];
        for r in 0..m {
            b[r] += p[r] * yi;
            for c in 0..m {
                a[r][c] += p[r] * p[c];
            }
        }
    }
    let coef: Vec<f64> = if m == 2 {
        let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
        vec![
            (b[0] * a[1][1] - a[0][1] * b[1]) / det,
            (a[0][0] * b[1] - b[0] * a[1][0]) / det,
            0.0,
        ]
    } else {
        let det3 = |m: &[[f64; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let d = det3(&a);
        (0..3)
            .map(|k| {
                let mut mk = a;
                for r in 0..3 {
                    mk[r][k] = b[r];
                }
                det3(&mk) / d
            })
            .collect()
    };
    let sse: f64 = u
        .iter()
        .zip(y)
        .map(|(ui, yi)| (yi - (coef[0] + coef[1] * ui + coef[2] * ui * ui)).powi(2))
        .sum();
    1.0 - sse / syy
}

/// Area and centroid of a simple polygon (shoelace; vertices in order, not repeated).
pub fn polygon_area_centroid(p: &[(f64, f64)]) -> (f64, (f64, f64)) {
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for k in 0..p.len() {
        let (q, r) = (p[k], p[(k + 1) % p.len()]);
        let cr = q.0 * r.1 - r.0 * q.1;
        a += cr;
        cx += (q.0 + r.0) * cr;
        cy += (q.1 + r.1) * cr;
    }
    let a = 0.5 * a;
    (a.abs(), (cx / (6.0 * a), cy / (6.0 * a)))
}

#[cfg(test)]
mod deposit_tests {
    use super::*;

    #[test]
    fn profile_takes_the_top_edge_per_bin() {
        let p = surface_profile(&[0.5, 0.6, 1.5], &[0.5, 1.5, 0.5], &[0.5, 0.5, 0.5], 1.0);
        assert_eq!(p, vec![(0.5, 2.0), (1.5, 1.0)]);
    }

    #[test]
    fn straight_line_is_linear_and_parabola_is_not() {
        let x: Vec<f64> = (0..20).map(|i| i as f64).collect();
        let line: Vec<f64> = x.iter().map(|v| 3.0 - 0.1 * v).collect();
        let para: Vec<f64> = x.iter().map(|v| (20.0 - v).powi(2) * 0.01).collect();
        assert!((poly_r2(&x, &line, 1) - 1.0).abs() < 1e-12);
        assert!((poly_r2(&x, &para, 2) - 1.0).abs() < 1e-12);
        assert!(
            poly_r2(&x, &para, 1) < 0.97,
            "a parabola is not a line: {}",
            poly_r2(&x, &para, 1)
        );
    }

    #[test]
    fn backward_jump_is_between_consecutive_samples() {
        // A growing front (L_0 = 2) that loses a toe of 1.5 at the fourth sample, then
        // regrows, then creeps back by 0.1: the largest backward move is 1.5/2 = 0.75 L_0.
        let l = [2.0, 2.5, 3.4, 1.9, 2.6, 3.5, 3.4];
        assert!((max_backward_jump(&l, 2.0) - 0.75).abs() < 1e-12);
        assert!(max_backward_jump(&l, 2.0) > 0.5, "this series fails the 0.5 L_0 test");
        let ok = [2.0, 2.5, 3.4, 3.3, 3.6, 3.6];
        assert!((max_backward_jump(&ok, 2.0) - 0.05).abs() < 1e-12);
        assert_eq!(max_backward_jump(&[1.0, 2.0, 3.0], 1.0), 0.0);
        assert_eq!(max_backward_jump(&[], 1.0), 0.0);
        // From the running maximum, a creep back of 0.1 + 0.2 is one fall of 0.3.
        assert!((max_drawdown(&[1.0, 3.0, 2.9, 2.7, 3.5]) - 0.3).abs() < 1e-12);
    }

    #[test]
    fn triangle_area_and_centroid() {
        let (a, c) = polygon_area_centroid(&[(0.0, 0.0), (3.0, 0.0), (0.0, 3.0)]);
        assert!((a - 4.5).abs() < 1e-12 && (c.0 - 1.0).abs() < 1e-12 && (c.1 - 1.0).abs() < 1e-12);
    }
}
