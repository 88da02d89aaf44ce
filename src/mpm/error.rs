//! Errors of the MPM engine: each names what went wrong with the numbers needed to act on it.

use super::particles::PointId;
use crate::math::Real;

/// An MPM failure.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MpmError {
    /// Invalid parameters (all issues listed).
    #[error("invalid MPM parameters: {}", .0.iter().map(|i| format!("{} = {} (allowed: {})", i.key, i.value, i.allowed)).collect::<Vec<_>>().join("; "))]
    InvalidParams(Vec<crate::validate::Issue>),
    /// The requested time step exceeds the stable limit.
    #[error(
        "time step {dt:.3e} s exceeds the stable limit {limit:.3e} s ({reason}); use dt <= {limit:.3e} s or a CFL step"
    )]
    StepTooLarge {
        /// Requested step [s].
        dt: Real,
        /// Stable limit [s].
        limit: Real,
        /// Which time scale limits it.
        reason: String,
    },
    /// NaN or infinity in a point's state.
    #[error("non-finite state at step {step} (t = {t:.6e} s), point {}", point.0)]
    NonFinite {
        /// Step number.
        step: u64,
        /// Time [s].
        t: Real,
        /// Offending point.
        point: PointId,
    },
    /// det F ≤ 0.
    #[error("Jacobian det F = {j:.3e} <= 0 at step {step} (t = {t:.6e} s), point {}", point.0)]
    JacobianNonPositive {
        /// Step number.
        step: u64,
        /// Time [s].
        t: Real,
        /// Offending point.
        point: PointId,
        /// det F.
        j: Real,
    },
    /// A point left the background grid.
    #[error("point {} left the grid at step {step} (t = {t:.6e} s), position ({x:.4}, {y:.4}) m", point.0)]
    LeftGrid {
        /// Step number.
        step: u64,
        /// Time [s].
        t: Real,
        /// Offending point.
        point: PointId,
        /// x [m].
        x: Real,
        /// y [m].
        y: Real,
    },
    /// Total energy rose without work input.
    #[error("energy rose by {excess:.3e} J/m (> {tolerance:.3e}) at step {step} (t = {t:.6e} s) without work input; the point with the largest speed is {}", point.0)]
    EnergyRise {
        /// Step number.
        step: u64,
        /// Time [s].
        t: Real,
        /// Rise [J/m].
        excess: Real,
        /// Allowed rise [J/m].
        tolerance: Real,
        /// Fastest point (likely culprit).
        point: PointId,
    },
    /// The geostatic stage did not become stationary.
    #[error("geostatic stage not stationary after {t:.3} s: E_k/(M g H) = {ratio:.3e} > {tol:.1e}")]
    GeostaticNotStationary {
        /// Time reached [s].
        t: Real,
        /// Kinetic energy ratio reached.
        ratio: Real,
        /// Target.
        tol: Real,
    },
}
