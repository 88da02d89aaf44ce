//! When a collapse run has stopped flowing (docs/definitions.md D10), one rule for DEM and
//! MPM: after `t_min`, the kinetic energy is below `ke_ratio` · E_p(0) AND neither the
//! front L nor the height H moved by more than `front_speed` · `window` (in d̄ and τ_c
//! units) over the last `window`; the run ends at `t_max` whatever happens. DEM kinetic
//! energy is translational + rotational; the MPM's is the grid kinetic energy (the point
//! energy carries the FLIP velocity noise of a deposit at rest).

use serde::{Deserialize, Serialize};

/// The stated stop rule. Times in τ_c = √(H_0/g), speeds in d̄/τ_c.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StopRule {
    /// Kinetic energy threshold as a fraction of E_p(0) [-].
    pub ke_ratio: f64,
    /// Largest front (and height) speed still counted as stopped [d̄/τ_c].
    pub front_speed: f64,
    /// Window over which the front speed is measured [τ_c].
    pub window: f64,
    /// Never stop before this time [τ_c].
    pub t_min: f64,
    /// Upper bound on the run [τ_c].
    pub t_max: f64,
}

impl Default for StopRule {
    fn default() -> Self {
        Self {
            ke_ratio: 1e-4,
            front_speed: 0.5,
            window: 1.0,
            t_min: 1.0,
            t_max: 12.0,
        }
    }
}

/// Outcome of the rule at one sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Keep running.
    Running,
    /// Kinetic energy and front speed below their thresholds.
    AtRest,
    /// `t_max` reached.
    TimeLimit,
}

impl StopRule {
    /// Problems with the values, as (key, value, allowed).
    pub fn issues(&self) -> Vec<(&'static str, f64, &'static str)> {
        let mut v = Vec::new();
        if !(self.ke_ratio > 0.0 && self.ke_ratio < 1.0) {
            v.push(("ke_ratio", self.ke_ratio, "in (0, 1)"));
        }
        if !(self.front_speed > 0.0) {
            v.push(("front_speed", self.front_speed, "> 0 [d̄/τ_c]"));
        }
        if !(self.window > 0.0 && self.window.is_finite()) {
            v.push(("window", self.window, "> 0 [τ_c]"));
        }
        if !(self.t_min >= 0.0 && self.t_max > self.t_min && self.t_max.is_finite()) {
            v.push(("t_max", self.t_max, "> t_min ≥ 0 [τ_c]"));
        }
        v
    }

    /// Verdict after the latest sample. `t`, `l`, `h`: the sampled times [s], fronts and
    /// heights [m] so far (time order); `ke_over_e0` the latest kinetic energy / E_p(0);
    /// `tau` = τ_c [s]; `d` = d̄ [m].
    pub fn verdict(&self, t: &[f64], l: &[f64], h: &[f64], ke_over_e0: f64, tau: f64, d: f64) -> Verdict {
        let Some(&now) = t.last() else { return Verdict::Running };
        if now >= self.t_min * tau && ke_over_e0 < self.ke_ratio {
            // An infinite front speed is the energy-only rule (calibration runs).
            if self.front_speed == f64::INFINITY {
                return Verdict::AtRest;
            }
            if now < self.window * tau {
                return if now >= self.t_max * tau {
                    Verdict::TimeLimit
                } else {
                    Verdict::Running
                };
            }
            let t0 = now - self.window * tau;
            let tol = self.front_speed * self.window * d;
            let (ln, hn) = (l[l.len() - 1], h[h.len() - 1]);
            let still = (0..t.len())
                .rev()
                .take_while(|&k| t[k] >= t0)
                .all(|k| (l[k] - ln).abs() <= tol && (h[k] - hn).abs() <= tol);
            if still {
                return Verdict::AtRest;
            }
        }
        if now >= self.t_max * tau {
            Verdict::TimeLimit
        } else {
            Verdict::Running
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn needs_both_energy_and_front() {
        let r = StopRule {
            ke_ratio: 1e-3,
            front_speed: 0.5,
            window: 1.0,
            t_min: 1.0,
            t_max: 5.0,
        };
        let t: Vec<f64> = (0..=30).map(|k| k as f64 * 0.1).collect();
        let l_moving: Vec<f64> = t.iter().map(|t| t * 1e-3).collect();
        let flat = vec![1.0; t.len()];
        // Low energy but a front moving at 1 d̄/τ_c (d̄ = 1e-3, τ = 1): running.
        assert_eq!(r.verdict(&t, &l_moving, &flat, 1e-4, 1.0, 1e-3), Verdict::Running);
        // Still front but energetic: running.
        assert_eq!(r.verdict(&t, &flat, &flat, 1e-2, 1.0, 1e-3), Verdict::Running);
        // Both: at rest.
        assert_eq!(r.verdict(&t, &flat, &flat, 1e-4, 1.0, 1e-3), Verdict::AtRest);
        // Upper bound.
        let t2: Vec<f64> = (0..=60).map(|k| k as f64 * 0.1).collect();
        let l2: Vec<f64> = t2.iter().map(|t| t * 1e-3).collect();
        assert_eq!(
            r.verdict(&t2, &l2, &vec![1.0; t2.len()], 1e-2, 1.0, 1e-3),
            Verdict::TimeLimit
        );
    }
}
