//! The tall-column resolution check of `wp-mpm-column` (issue 25): does the a = 6 column's
//! start — E_p/E_0 at 0.5, 1 and 2 τ_c and the measured critical time t_KEmax/τ_c
//! (docs/definitions.md D05, D06; chapter §4.2.3–4.2.4, figs 4.11b, 4.13b) — move with the
//! resolution? One knob at a time from a base setting: the number of cells across L_0 at the
//! first PPC, then the PPC at the first number of cells. The column keeps the work-precision
//! stage's area, so L_0 and H_0 are the DEM columns' of the profile; the cell size is
//! L_0/cells, so L_0 is not snapped. Each run stops at `until_tau` τ_c (the start is what is
//! checked, not the deposit; the a = 0.4 sweep of the same stage covers the run-out).

use serde::{Deserialize, Serialize};

use crate::mpm::column::{CollapseOptions, ColumnSpec, collapse};
use crate::mpm::{MpmParams, StepRule};
use crate::validate::Checker;

/// The check's settings.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct TallCheck {
    /// Aspect ratio of the column. 6 (figs 4.9–4.11b, 4.13b).
    pub a: f64,
    /// Cells across L_0, swept at `ppc[0]`; the first is the base setting.
    pub cells_across: Vec<u32>,
    /// Points per cell, swept at `cells_across[0]`; the first is the base setting.
    pub ppc: Vec<u32>,
    /// Courant number of the CFL step.
    pub courant: f64,
    /// End of each run [τ_c].
    pub until_tau: f64,
}

impl Default for TallCheck {
    fn default() -> Self {
        TallCheck {
            a: 6.0,
            cells_across: vec![12, 24, 48],
            ppc: vec![4, 16],
            courant: 0.5,
            until_tau: 2.0,
        }
    }
}

impl TallCheck {
    /// Every invalid value, into `c`.
    pub fn check(&self, c: &mut Checker) {
        c.in_closed("tall.a", self.a, 0.05, 20.0);
        c.check(
            !self.cells_across.is_empty(),
            "tall.cells_across",
            "[]",
            "at least one value",
        );
        for &n in &self.cells_across {
            c.check((1..=400).contains(&n), "tall.cells_across", n, "an integer in [1, 400]");
        }
        c.check(!self.ppc.is_empty(), "tall.ppc", "[]", "at least one value");
        for &p in &self.ppc {
            let r = (p as f64).sqrt().round() as u32;
            c.check(
                p >= 1 && r * r == p,
                "tall.ppc",
                p,
                "perfect squares (1, 4, 9, 16, 25, …)",
            );
        }
        c.in_open_closed("tall.courant", self.courant, 0.0, 1.0);
        c.in_closed("tall.until_tau", self.until_tau, 1.0, 12.0);
    }

    /// (cells across, PPC) of every run: the base, the other cell counts at the base PPC,
    /// then the other PPC at the base cell count.
    pub fn settings(&self) -> Vec<(u32, u32)> {
        let (Some(&n0), Some(&p0)) = (self.cells_across.first(), self.ppc.first()) else {
            return Vec::new();
        };
        let mut s: Vec<(u32, u32)> = self.cells_across.iter().map(|&n| (n, p0)).collect();
        s.extend(self.ppc.iter().skip(1).map(|&p| (n0, p)));
        s.dedup();
        s
    }
}

/// One run of the check.
#[derive(Debug, Clone, PartialEq)]
pub struct TallRow {
    /// Cells across L_0.
    pub cells: u32,
    /// Cell size [m].
    pub cell_size: f64,
    /// Points per cell.
    pub ppc: u32,
    /// Material points.
    pub points: usize,
    /// Steps of the collapse stage.
    pub steps: u64,
    /// E_p/E_0 at 0.5, 1 and 2 τ_c [-] (linear between samples; NaN past the run's end).
    pub ep: [f64; 3],
    /// t_KEmax/τ_c over the run [-].
    pub t_kemax: f64,
    /// ΔL = (L − L_0)/L_0 at the run's end [-] (the stage's linking rule).
    pub runout_end: f64,
    /// Wall time of the collapse stage [s].
    pub wall_s: f64,
}

/// Value of `y` at `t` by linear interpolation between samples (NaN outside).
pub fn interp(t: &[f64], y: &[f64], at: f64) -> f64 {
    for i in 1..t.len() {
        if t[i] >= at && t[i - 1] <= at {
            let w = if t[i] > t[i - 1] {
                (at - t[i - 1]) / (t[i] - t[i - 1])
            } else {
                0.0
            };
            return y[i - 1] * (1.0 - w) + y[i] * w;
        }
    }
    f64::NAN
}

/// Run every setting of the check (one after another; each run is itself parallel).
pub fn run(base: &MpmParams, run: &CollapseOptions, area_m2: f64, t: &TallCheck) -> anyhow::Result<Vec<TallRow>> {
    let spec = ColumnSpec::from_area(t.a, area_m2);
    let opts = CollapseOptions {
        min_time_tau: t.until_tau,
        max_time_tau: t.until_tau,
        stop_ke_ratio: 0.0,
        stop: None,
        snapshot_tau: Vec::new(),
        link_gap_sensitivity: Vec::new(),
        ..run.clone()
    };
    let tau = spec.tau_c(base.gravity);
    let mut rows = Vec::new();
    for (cells, ppc) in t.settings() {
        let h = spec.l0 / cells as f64;
        let mp = MpmParams {
            ppc,
            cell_size: h,
            step: StepRule::Cfl {
                courant: t.courant,
                dt_max: 1e-3,
            },
            ..base.clone()
        };
        let r = collapse(&mp, spec, &opts)?;
        let ts: Vec<f64> = r.series.iter().map(|s| s.t / tau).collect();
        let e0 = r.series.first().map_or(f64::NAN, |s| s.e.potential);
        let ep: Vec<f64> = r.series.iter().map(|s| s.e.potential / e0).collect();
        let kmax = r
            .series
            .iter()
            .max_by(|a, b| a.e.kinetic.total_cmp(&b.e.kinetic))
            .map_or(f64::NAN, |s| s.t / tau);
        rows.push(TallRow {
            cells,
            cell_size: h,
            ppc,
            points: r.points,
            steps: r.steps,
            ep: [interp(&ts, &ep, 0.5), interp(&ts, &ep, 1.0), interp(&ts, &ep, 2.0)],
            t_kemax: kmax,
            runout_end: r.runout,
            wall_s: r.wall_s,
        });
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_one_knob_at_a_time() {
        let t = TallCheck::default();
        assert_eq!(t.settings(), vec![(12, 4), (24, 4), (48, 4), (12, 16)]);
        let one = TallCheck {
            cells_across: vec![12],
            ppc: vec![4],
            ..t
        };
        assert_eq!(one.settings(), vec![(12, 4)]);
    }

    #[test]
    fn interp_between_samples_and_nan_outside() {
        let t = [0.0, 1.0, 2.0];
        let y = [1.0, 0.5, 0.25];
        assert_eq!(interp(&t, &y, 0.5), 0.75);
        assert_eq!(interp(&t, &y, 2.0), 0.25);
        assert!(interp(&t, &y, 2.5).is_nan());
    }

    #[test]
    fn invalid_settings_are_named() {
        let mut c = Checker::new("");
        TallCheck {
            ppc: vec![5],
            cells_across: vec![],
            ..TallCheck::default()
        }
        .check(&mut c);
        let keys: Vec<String> = c.issues.iter().map(|i| i.key.clone()).collect();
        assert!(keys.iter().any(|k| k.contains("tall.ppc")), "{keys:?}");
        assert!(keys.iter().any(|k| k.contains("tall.cells_across")), "{keys:?}");
    }
}
