//! Particle size distributions: the cumulative β (CB) grading curve of thesis chapter 3
//! (§"Cumulative beta distribution", after Voivret et al. 2007) and its sampling into a
//! finite set of disks.
//!
//! The grading curve h(d) = I_{d_r}(a, b) is the *volume* (2D: area) fraction finer than d,
//! with the reduced diameter d_r = (d − d_min)/(d_max − d_min) and I the regularised
//! incomplete beta function. β(1, 1) is the chapter's "uniform distribution of diameters
//! by volume fractions" (docs/definitions.md I15); the thesis's generator used a = b = 4.
//!
//! Sampling: grains are drawn by *number*, whose density is n(d) ∝ h'(d)/d² for disks
//! (area ∝ d²). The number CDF is tabulated on a fine grid from exact increments of h
//! (so a, b < 1 with their integrable end singularities are handled) and inverted by
//! interpolation. Quantiles are stratified — U_i = (i + u_i)/N — then shuffled, both from
//! a seeded ChaCha8 stream: the same seed gives the same grains on every machine.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A cumulative-β grading curve on [d_min, d_max].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BetaGrading {
    /// Smallest diameter [m].
    pub d_min: f64,
    /// Largest diameter [m].
    pub d_max: f64,
    /// Shape parameter a > 0.
    pub a: f64,
    /// Shape parameter b > 0.
    pub b: f64,
}

fn ln_gamma(x: f64) -> f64 {
    // Lanczos approximation (g = 7, n = 9), |rel err| < 1e-15 for x > 0.
    const C: [f64; 9] = [
        0.999_999_999_999_809_9, 676.520_368_121_885_1, -1_259.139_216_722_402_8, 771.323_428_777_653_1,
        -176.615_029_162_140_6, 12.507_343_278_686_905, -0.138_571_095_265_720_12, 9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        return (std::f64::consts::PI / (std::f64::consts::PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut s = C[0];
    for (i, c) in C.iter().enumerate().skip(1) {
        s += c / (x + i as f64);
    }
    let t = x + 7.5;
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + s.ln()
}

/// Continued fraction of the incomplete beta function (modified Lentz).
fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    let tiny = 1e-300;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < tiny {
        d = tiny;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..=500 {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 + aa * d;
        if d.abs() < tiny {
            d = tiny;
        }
        c = 1.0 + aa / c;
        if c.abs() < tiny {
            c = tiny;
        }
        d = 1.0 / d;
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 + aa * d;
        if d.abs() < tiny {
            d = tiny;
        }
        c = 1.0 + aa / c;
        if c.abs() < tiny {
            c = tiny;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// Regularised incomplete beta function I_x(a, b).
pub fn inc_beta(x: f64, a: f64, b: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln();
    let front = ln_front.exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        front * beta_cf(a, b, x) / a
    } else {
        1.0 - front * beta_cf(b, a, 1.0 - x) / b
    }
}

const GRID: usize = 8192;

impl BetaGrading {
    /// Volume (area) fraction finer than `d`, h(d) in [0, 1].
    pub fn volume_cdf(&self, d: f64) -> f64 {
        inc_beta((d - self.d_min) / (self.d_max - self.d_min), self.a, self.b)
    }

    /// Number CDF tabulated on a uniform diameter grid (GRID + 1 nodes).
    fn number_cdf_table(&self) -> (Vec<f64>, Vec<f64>) {
        let dd = (self.d_max - self.d_min) / GRID as f64;
        let ds: Vec<f64> = (0..=GRID).map(|i| self.d_min + dd * i as f64).collect();
        let hs: Vec<f64> = ds.iter().map(|&d| self.volume_cdf(d)).collect();
        let mut n = vec![0.0; GRID + 1];
        for i in 0..GRID {
            let mid = 0.5 * (ds[i] + ds[i + 1]);
            n[i + 1] = n[i] + (hs[i + 1] - hs[i]) / (mid * mid);
        }
        let tot = n[GRID];
        for v in n.iter_mut() {
            *v /= tot;
        }
        (ds, n)
    }

    /// Draw `n` diameters [m] (stratified, shuffled; deterministic for a seed).
    pub fn sample(&self, n: usize, seed: u64) -> Vec<f64> {
        let (ds, cdf) = self.number_cdf_table();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut out: Vec<f64> = (0..n)
            .map(|i| {
                let u = (i as f64 + rng.random::<f64>()) / n as f64;
                // Binary search for the grid cell holding u, then interpolate.
                let k = cdf.partition_point(|&c| c < u).clamp(1, GRID);
                let (c0, c1) = (cdf[k - 1], cdf[k]);
                let t = if c1 > c0 { (u - c0) / (c1 - c0) } else { 0.5 };
                ds[k - 1] + t * (ds[k] - ds[k - 1])
            })
            .collect();
        // Fisher–Yates shuffle so grain order carries no size trend.
        for i in (1..n).rev() {
            let j = (rng.random::<u64>() % (i as u64 + 1)) as usize;
            out.swap(i, j);
        }
        out
    }
}

/// Summary statistics of a sample of disk diameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PsdStats {
    /// Number of grains.
    pub n: usize,
    /// d10 by area [m].
    pub d10: f64,
    /// d50 by area [m].
    pub d50: f64,
    /// d60 by area [m].
    pub d60: f64,
    /// Coefficient of uniformity d60/d10.
    pub cu: f64,
    /// Area-weighted mean diameter Σd³/Σd² [m].
    pub d_mean_volume: f64,
    /// Number mean diameter [m].
    pub d_mean_number: f64,
    /// Smallest and largest sampled diameter [m].
    pub d_min: f64,
    /// Largest sampled diameter [m].
    pub d_max: f64,
}

/// Sorted diameters with their cumulative area fraction (fraction finer *including* each grain).
pub fn volume_cdf_of_sample(d: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut s = d.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    let tot: f64 = s.iter().map(|x| x * x).sum();
    let mut acc = 0.0;
    let f = s
        .iter()
        .map(|x| {
            acc += x * x;
            acc / tot
        })
        .collect();
    (s, f)
}

fn quantile(sorted: &[f64], cdf: &[f64], p: f64) -> f64 {
    let k = cdf.partition_point(|&c| c < p);
    if k == 0 {
        return sorted[0];
    }
    if k >= sorted.len() {
        return *sorted.last().unwrap();
    }
    let (c0, c1) = (cdf[k - 1], cdf[k]);
    let t = if c1 > c0 { (p - c0) / (c1 - c0) } else { 0.0 };
    sorted[k - 1] + t * (sorted[k] - sorted[k - 1])
}

/// Statistics of a sample (quantiles by area fraction, linear interpolation).
pub fn stats(d: &[f64]) -> PsdStats {
    let (s, f) = volume_cdf_of_sample(d);
    let d10 = quantile(&s, &f, 0.10);
    let d50 = quantile(&s, &f, 0.50);
    let d60 = quantile(&s, &f, 0.60);
    let a2: f64 = s.iter().map(|x| x * x).sum();
    let a3: f64 = s.iter().map(|x| x * x * x).sum();
    PsdStats {
        n: s.len(),
        d10,
        d50,
        d60,
        cu: d60 / d10,
        d_mean_volume: a3 / a2,
        d_mean_number: s.iter().sum::<f64>() / s.len() as f64,
        d_min: s[0],
        d_max: *s.last().unwrap(),
    }
}

/// Kolmogorov distance between the sample's area CDF and the grading curve.
pub fn ks_distance(d: &[f64], g: &BetaGrading) -> f64 {
    let (s, f) = volume_cdf_of_sample(d);
    let mut prev = 0.0;
    let mut worst: f64 = 0.0;
    for (x, fx) in s.iter().zip(&f) {
        let h = g.volume_cdf(*x);
        worst = worst.max((h - prev).abs()).max((h - fx).abs());
        prev = *fx;
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn incomplete_beta_known_values() {
        assert!((inc_beta(0.3, 1.0, 1.0) - 0.3).abs() < 1e-14);
        // I_x(2, 2) = 3x² − 2x³.
        let x: f64 = 0.37;
        assert!((inc_beta(x, 2.0, 2.0) - (3.0 * x * x - 2.0 * x * x * x)).abs() < 1e-13);
        // Symmetry I_x(a, b) = 1 − I_{1−x}(b, a).
        assert!((inc_beta(0.2, 4.0, 1.5) - (1.0 - inc_beta(0.8, 1.5, 4.0))).abs() < 1e-13);
        assert!((inc_beta(0.5, 4.0, 4.0) - 0.5).abs() < 1e-13);
    }

    #[test]
    fn uniform_by_volume_matches_closed_form_number_density() {
        // β(1,1): number CDF N(d) = (1/d_min − 1/d)/(1/d_min − 1/d_max)
        // (docs/definitions.md SC-PSD).
        let g = BetaGrading {
            d_min: 0.92e-3,
            d_max: 1.38e-3,
            a: 1.0,
            b: 1.0,
        };
        let d = g.sample(20000, 7);
        let s = stats(&d);
        assert!((s.d_mean_volume - 1.15e-3).abs() < 0.003e-3, "{}", s.d_mean_volume);
        // Number mean of n ∝ d⁻²: ln(r)/(1/dmin − 1/dmax).
        let expect = (1.38f64 / 0.92).ln() / (1.0 / 0.92e-3 - 1.0 / 1.38e-3);
        assert!(
            (s.d_mean_number - expect).abs() < 0.002e-3,
            "{} vs {expect}",
            s.d_mean_number
        );
        assert!(ks_distance(&d, &g) < 0.01);
    }

    #[test]
    fn sampling_is_deterministic_for_a_seed() {
        let g = BetaGrading {
            d_min: 1.0,
            d_max: 2.0,
            a: 4.0,
            b: 4.0,
        };
        let a = g.sample(500, 42);
        let b = g.sample(500, 42);
        let c = g.sample(500, 43);
        assert_eq!(
            a.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            b.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
        assert_ne!(a, c);
        assert!(a.iter().all(|&x| (1.0..=2.0).contains(&x)));
    }
}
