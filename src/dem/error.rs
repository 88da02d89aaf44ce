//! Errors of the DEM library; each carries the numbers needed to act on it.

use crate::dem::time_scale::TimeScale;
use crate::math::Real;

/// DEM failure.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DemError {
    /// The step exceeds the explicit stability limit of a time scale (pre-flight).
    #[error("time step {dt:.3e} s exceeds the stable limit {limit:.3e} s of \"{}\" (time scale {:.3e} s); fix: {}", scale.name, scale.value, scale.fix)]
    StepTooLarge {
        /// Requested step [s].
        dt: Real,
        /// Largest stable step of the binding time scale [s].
        limit: Real,
        /// The binding time scale.
        scale: TimeScale,
    },
    /// Invalid parameters (all issues listed).
    #[error("invalid DEM parameters: {0}")]
    InvalidParams(String),
    /// Non-finite position or velocity.
    #[error("non-finite state at step {step} (t = {t:.6e} s), grain {grain}")]
    NonFinite {
        /// Step number.
        step: u64,
        /// Simulated time [s].
        t: Real,
        /// Offending grain.
        grain: u32,
    },
    /// Overlap beyond the watchdog limit.
    #[error(
        "overlap {fraction:.3} d between grains {i} and {j} at step {step} (t = {t:.6e} s) exceeds {limit} d; reduce dt or raise k_n"
    )]
    Overlap {
        /// Step number.
        step: u64,
        /// Simulated time [s].
        t: Real,
        /// First grain.
        i: u32,
        /// Second grain (u32::MAX for a wall).
        j: u32,
        /// Overlap / smaller diameter.
        fraction: Real,
        /// Limit.
        limit: Real,
    },
    /// Mechanical energy rose above the input without work to explain it.
    #[error(
        "energy rose to {energy:.4e} J/m > allowed {allowed:.4e} J/m at step {step} (t = {t:.6e} s); fastest grain {grain}; the step is probably unstable"
    )]
    EnergyRise {
        /// Step number.
        step: u64,
        /// Simulated time [s].
        t: Real,
        /// Grain with the largest kinetic energy.
        grain: u32,
        /// E_k + E_p + E_rot now.
        energy: Real,
        /// Allowed maximum.
        allowed: Real,
    },
    /// A scene or driver that cannot be set up as asked.
    #[error("DEM set-up: {0}")]
    Setup(String),
}
