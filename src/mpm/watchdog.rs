//! Watchdog: fixed chokepoints that stop a run with an error naming step, time and point.
//!
//! - every step (`relocate`): non-finite position/velocity/stress, det F ≤ 0, a point whose
//!   stencil leaves the grid;
//! - on every recorded sample ([`EnergyWatch`]): total energy E_k + E_p + E_el + dissipated
//!   work rising above its initial value by more than `tol × E_p(0)` (no work is done on the
//!   column by anything but gravity, which is inside E_p).

use super::energy::Energies;
use super::error::MpmError;
use super::grid::Grid;
use super::particles::{Point, PointId};
use crate::math::Real;
use rayon::prelude::*;

/// Per-step point checks. Reports the lowest-index offending point (deterministic).
pub fn check_points(points: &[Point], grid: &Grid, lp: Real, step: u64, t: Real) -> Result<(), MpmError> {
    let bad = |p: &Point| {
        let finite = p.x.iter().all(|v| v.is_finite())
            && p.v.iter().all(|v| v.is_finite())
            && p.stress.xx.is_finite()
            && p.stress.yy.is_finite()
            && p.stress.xy.is_finite()
            && p.stress.zz.is_finite();
        !finite || p.vol.is_nan() || p.vol <= 0.0 || !grid.contains(p.x, lp)
    };
    if let Some(i) = points.par_iter().position_first(bad) {
        let p = &points[i];
        let finite = p.x.iter().chain(p.v.iter()).all(|v| v.is_finite())
            && [p.stress.xx, p.stress.yy, p.stress.xy, p.stress.zz]
                .iter()
                .all(|v| v.is_finite());
        if !finite {
            return Err(MpmError::NonFinite { step, t, point: p.id });
        }
        if p.vol.is_nan() || p.vol <= 0.0 {
            return Err(MpmError::JacobianNonPositive {
                step,
                t,
                point: p.id,
                j: p.j,
            });
        }
        return Err(MpmError::LeftGrid {
            step,
            t,
            point: p.id,
            x: p.x.x,
            y: p.x.y,
        });
    }
    Ok(())
}

/// Energy-rise check against the first sample.
#[derive(Debug, Clone, Copy)]
pub struct EnergyWatch {
    /// E_total at the start [J/m].
    pub e0: Real,
    /// Allowed rise [J/m].
    pub tol: Real,
}

impl EnergyWatch {
    /// Start watching from `e`; allowed rise = `frac` × E_p(0) (E_p measured from the base).
    pub fn new(e: &Energies, frac: Real) -> Self {
        Self {
            e0: e.total(),
            tol: frac * e.potential.abs().max(1e-300),
        }
    }
    /// Check a later sample.
    pub fn check(&self, e: &Energies, points: &[Point], step: u64, t: Real) -> Result<(), MpmError> {
        let excess = e.total() - self.e0;
        if excess > self.tol {
            let mut best = (0.0, PointId(0));
            for p in points {
                let s = p.v.norm_squared();
                if s > best.0 {
                    best = (s, p.id);
                }
            }
            return Err(MpmError::EnergyRise {
                step,
                t,
                excess,
                tolerance: self.tol,
                point: best.1,
            });
        }
        Ok(())
    }
}
