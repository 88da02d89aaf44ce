//! Per-run quantities of a column collapse from its time series and end states
//! (figures.md D05, D10, D17; §4.2 phases), shared by DEM and MPM.

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
    let pts: Vec<(f64, f64)> = t.iter().zip(y).filter(|(a, _)| **a >= t0 && **a <= t1).map(|(a, b)| (*a, *b)).collect();
    let n = pts.len() as f64;
    if pts.len() < 3 {
        return (f64::NAN, f64::NAN, pts.len());
    }
    let mt = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let stt = pts.iter().map(|p| (p.0 - mt).powi(2)).sum::<f64>();
    let sty = pts.iter().map(|p| (p.0 - mt) * (p.1 - my)).sum::<f64>();
    let syy = pts.iter().map(|p| (p.1 - my).powi(2)).sum::<f64>();
    let r2 = if syy > 0.0 && stt > 0.0 { sty * sty / (stt * syy) } else { f64::NAN };
    (sty / stt, r2, pts.len())
}

/// μ_e from the run-out (eqs 4.8–4.9, D17 first estimator): μ_e = H_0/(L_f − L_0).
pub fn mu_e_geometric(h0: f64, l0: f64, lf: f64) -> f64 {
    h0 / (lf - l0)
}

/// Staron & Hinch's W = g Σ m_p r_p with r_p = |x_end − x_0| the net horizontal
/// distance run by each body (D17 second estimator; the slope of δE against W over the
/// short columns is μ_e, the ratio δE/W is one run's value) [J/m].
pub fn staron_hinch_work(x0: &[f64], x1: &[f64], m: &[f64], g: f64) -> f64 {
    g * x0.iter().zip(x1).zip(m).map(|((a, b), m)| m * (b - a).abs()).sum::<f64>()
}

/// Staron & Hinch's fitted law μ_e = 0.425 μ^0.2 (D17 third value; a formula of the
/// grain friction μ, not a measurement).
pub fn mu_e_staron_hinch_law(mu: f64) -> f64 {
    0.425 * mu.powf(0.2)
}
