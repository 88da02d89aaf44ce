//! The quantities `pile-series` derives from one pile run (chapter 4 §4.4.2, §4.4.4,
//! §4.4.5; docs/definitions.md D12–D16): the run's time series, its derived quantities, the
//! high-pass of E_ky, and the spreads and monotony counts the statements use.

use crate::analysis::pile::{first_crossing, interp};

/// One run (one energy of one input) with its derived quantities.
#[derive(Debug, Clone, Default)]
pub struct Run {
    /// Label values (as `SeriesParams::labels`).
    pub labels: Vec<f64>,
    /// E_0 [mgd].
    pub e0: f64,
    /// L_0 [d].
    pub l0: f64,
    /// ΔL (D02).
    pub dl: f64,
    /// t_f [√(d/g)] (D10).
    pub tf: f64,
    /// Sample times [√(d/g)].
    pub t: Vec<f64>,
    /// L(t) [d].
    pub l: Vec<f64>,
    /// H(t) [d].
    pub h: Vec<f64>,
    /// E_k/E_0, E_kx/E_0, E_ky/E_0, E_rot/E_0.
    pub ek: Vec<f64>,
    /// See `ek`.
    pub ekx: Vec<f64>,
    /// See `ek`.
    pub eky: Vec<f64>,
    /// See `ek`.
    pub erot: Vec<f64>,
}

/// Per-run results (D12–D16 and the diagnostics of the statements).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Derived {
    /// E'_kx0 = E_kx(t_1) [mgd] (D13).
    pub ekx0: f64,
    /// τ [√(d/g)] (D14).
    pub tau: f64,
    /// t'_f = t_f − t_1 (D15).
    pub tfp: f64,
    /// max E_ky/E_0.
    pub eky_peak: f64,
    /// Time of that peak.
    pub t_eky_peak: f64,
    /// Measured t_1: first time after the peak with E_ky below 1 % of it (D12 diagnostic).
    pub t1_measured: f64,
    /// Last time with E_k/E_0 ≥ zero_ratio.
    pub t_dissipated: f64,
    /// max E_rot/E_k over t ≤ t_f with E_k/E_0 ≥ zero_ratio.
    pub erot_over_ek_max: f64,
    /// ∫ E_rot dt / ∫ E_k dt over [0, t_f] (the rotational share of the motion).
    pub erot_share: f64,
    /// RMS over [t_1, t_f] of E_ky/E_0 minus its centred moving average.
    pub eky_hp_rms: f64,
    /// Free-fall time from the initial top, √(2 H_0/d) [√(d/g)].
    pub t_free_fall: f64,
}

/// E_ky/E_0 minus its centred moving average over `window` (same units as `t`).
pub fn highpass(t: &[f64], v: &[f64], window: f64) -> Vec<f64> {
    (0..t.len())
        .map(|i| {
            let (mut s, mut n) = (0.0, 0.0);
            for j in 0..t.len() {
                if (t[j] - t[i]).abs() <= 0.5 * window {
                    s += v[j];
                    n += 1.0;
                }
            }
            v[i] - s / n
        })
        .collect()
}

/// The derived quantities of one run.
pub fn derive(r: &Run, t1: f64, zero_ratio: f64, window: f64) -> Derived {
    let ekx_mgd: Vec<f64> = r.ekx.iter().map(|v| v * r.e0).collect();
    let ekx0 = interp(&r.t, &ekx_mgd, t1);
    let tau = first_crossing(&r.t, &ekx_mgd, t1, 0.5 * ekx0) - t1;
    let (k_peak, eky_peak) = r
        .eky
        .iter()
        .enumerate()
        .fold((0, 0.0), |a, (k, v)| if *v > a.1 { (k, *v) } else { a });
    let t_eky_peak = r.t.get(k_peak).copied().unwrap_or(f64::NAN);
    let t1_measured = if eky_peak > 0.0 {
        first_crossing(&r.t, &r.eky, t_eky_peak, 0.01 * eky_peak)
    } else {
        f64::NAN
    };
    let t_dissipated =
        r.t.iter()
            .zip(&r.ek)
            .filter(|(_, e)| **e >= zero_ratio)
            .map(|(t, _)| *t)
            .fold(0.0, f64::max);
    let erot_over_ek_max = (0..r.t.len())
        .filter(|&k| r.t[k] <= r.tf && r.ek[k] >= zero_ratio)
        .map(|k| r.erot[k] / r.ek[k])
        .fold(0.0, f64::max);
    let integral = |v: &[f64]| -> f64 {
        (1..r.t.len())
            .filter(|&k| r.t[k] <= r.tf)
            .map(|k| 0.5 * (v[k] + v[k - 1]) * (r.t[k] - r.t[k - 1]))
            .sum()
    };
    let erot_share = integral(&r.erot) / integral(&r.ek);
    let hp = highpass(&r.t, &r.eky, window);
    let win: Vec<f64> = (0..r.t.len())
        .filter(|&k| r.t[k] >= t1 && r.t[k] <= r.tf)
        .map(|k| hp[k] * hp[k])
        .collect();
    let eky_hp_rms = if win.is_empty() {
        f64::NAN
    } else {
        (win.iter().sum::<f64>() / win.len() as f64).sqrt()
    };
    let h0 = r.h.first().copied().unwrap_or(f64::NAN);
    Derived {
        ekx0,
        tau,
        tfp: r.tf - t1,
        eky_peak,
        t_eky_peak,
        t1_measured,
        t_dissipated,
        erot_over_ek_max,
        erot_share,
        eky_hp_rms,
        t_free_fall: (2.0 * h0).sqrt(),
    }
}

/// Largest spread (max − min, or relative to the mean when `relative`) across curves
/// (ts, vs) sampled at the grid points.
pub fn spread(curves: &[(Vec<f64>, Vec<f64>)], grid: &[f64], relative: bool) -> f64 {
    if curves.len() < 2 {
        return f64::NAN;
    }
    grid.iter()
        .map(|&x| {
            let v: Vec<f64> = curves.iter().map(|(t, y)| interp(t, y, x)).collect();
            let (lo, hi) = v
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |a, y| (a.0.min(*y), a.1.max(*y)));
            let mean = v.iter().sum::<f64>() / v.len() as f64;
            if relative {
                (hi - lo) / mean.abs().max(1e-300)
            } else {
                hi - lo
            }
        })
        .fold(0.0, f64::max)
}

/// Number of adjacent pairs (ordered by `x`) where `y` does not decrease.
pub fn increases(mut xy: Vec<(f64, f64)>) -> usize {
    xy.sort_by(|a, b| a.0.total_cmp(&b.0));
    xy.windows(2).filter(|w| w[1].1 >= w[0].1).count()
}

pub(crate) fn grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..=n).map(|k| lo + (hi - lo) * k as f64 / n as f64).collect()
}

/// One energy, one value: a run whose E_0 is within 1e-9 (relative) of an earlier run's
/// takes that run's value. E_0 is measured back from the grains' velocities (12.98 mgd
/// reads 12.980000000000002 in one PPC run of the paper study), and the statements group
/// runs by energy: without this, that run formed a group of its own and fell out of the
/// comparisons.
pub fn same_energies(runs: &mut [Run]) {
    let mut seen: Vec<f64> = Vec::new();
    for r in runs.iter_mut() {
        match seen.iter().find(|&&e| (e - r.e0).abs() <= 1e-9 * e.abs()) {
            Some(&e) => r.e0 = e,
            None => seen.push(r.e0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run_with(e0: f64, tau: f64, t1: f64) -> Run {
        // E_kx = E_0 up to t_1 then exp(−ln2 (t − t_1)/τ): τ is the half-life.
        let t: Vec<f64> = (0..800).map(|k| 0.25 * k as f64).collect();
        let ekx: Vec<f64> = t
            .iter()
            .map(|&x| {
                if x < t1 {
                    1.0
                } else {
                    (-(2f64.ln()) * (x - t1) / tau).exp()
                }
            })
            .collect();
        let eky: Vec<f64> = t.iter().map(|&x| 0.1 * (-(x - 3.0).powi(2)).exp()).collect();
        let ek: Vec<f64> = ekx.iter().zip(&eky).map(|(a, b)| a + b).collect();
        Run {
            labels: vec![],
            e0,
            l0: 10.0,
            dl: 1.0,
            tf: t1 + 5.0 * tau,
            h: vec![8.0; t.len()],
            l: vec![10.0; t.len()],
            erot: vec![0.0; t.len()],
            ekx,
            eky,
            ek,
            t,
        }
    }

    #[test]
    fn decay_time_and_measured_t1() {
        let d = derive(&run_with(100.0, 8.0, 7.5), 7.5, 1e-3, 5.0);
        assert!((d.tau - 8.0).abs() < 0.02, "τ = {}", d.tau);
        assert!((d.ekx0 - 100.0).abs() < 1e-9);
        assert!((d.tfp / d.tau - 5.0).abs() < 0.01);
        // E_ky = 0.1 exp(−(t − 3)²) falls below 1 % of its peak at t = 3 + √ln100 = 5.146
        assert!((d.t1_measured - 5.146).abs() < 0.05, "t_1 = {}", d.t1_measured);
        assert!((d.t_free_fall - 4.0).abs() < 1e-12);
    }

    #[test]
    fn collapse_against_t_over_tau_and_not_against_t() {
        let rs = [
            run_with(50.0, 5.0, 7.5),
            run_with(150.0, 10.0, 7.5),
            run_with(250.0, 15.0, 7.5),
        ];
        let ds: Vec<Derived> = rs.iter().map(|r| derive(r, 7.5, 1e-3, 5.0)).collect();
        let scaled: Vec<(Vec<f64>, Vec<f64>)> = rs
            .iter()
            .zip(&ds)
            .map(|(r, d)| (r.t.iter().map(|t| (t - 7.5) / d.tau).collect(), r.ekx.clone()))
            .collect();
        let raw: Vec<(Vec<f64>, Vec<f64>)> = rs
            .iter()
            .map(|r| (r.t.iter().map(|t| t - 7.5).collect(), r.ekx.clone()))
            .collect();
        assert!(spread(&scaled, &grid(0.0, 4.0, 80), false) < 0.01);
        assert!(spread(&raw, &grid(0.0, 40.0, 80), false) > 0.2);
    }

    #[test]
    fn highpass_removes_a_ramp_and_keeps_an_oscillation() {
        let t: Vec<f64> = (0..400).map(|k| 0.25 * k as f64).collect();
        let ramp: Vec<f64> = t.iter().map(|x| 0.01 * x).collect();
        let hp = highpass(&t, &ramp, 5.0);
        assert!(hp[200].abs() < 1e-12);
        let osc: Vec<f64> = t.iter().map(|x| (2.0 * std::f64::consts::PI * x).sin()).collect();
        let hp = highpass(&t, &osc, 5.0);
        assert!((hp[200] - osc[200]).abs() < 0.1);
    }

    #[test]
    fn increases_counts_non_decreasing_pairs() {
        assert_eq!(increases(vec![(3.0, 1.0), (1.0, 3.0), (2.0, 2.0)]), 0);
        assert_eq!(increases(vec![(1.0, 1.0), (2.0, 2.0), (3.0, 0.5)]), 1);
    }

    /// An energy measured back with a last-digit difference joins its group.
    #[test]
    fn an_energy_off_in_the_last_digit_is_the_same_energy() {
        let mut runs = vec![run_with(12.98, 5.0, 7.5), run_with(12.980000000000002, 5.0, 7.5), run_with(129.8, 5.0, 7.5)];
        same_energies(&mut runs);
        assert_eq!(runs[1].e0, 12.98);
        assert_eq!(runs[2].e0, 129.8);
    }
}
