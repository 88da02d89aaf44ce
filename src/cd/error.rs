//! Errors of the CD library; each carries the numbers needed to act on it.

use crate::math::Real;

/// CD failure.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CdError {
    /// Invalid parameters (all issues listed).
    #[error("invalid CD parameters: {0}")]
    InvalidParams(String),
    /// A grain would move more than half the alert distance in one step: a contact could
    /// close without having been detected (pre-flight of every step).
    #[error(
        "step {step} (t = {t:.6e} s): grain {grain} moves {displacement:.3e} m in one step at {speed:.3e} m/s, more than half the alert distance {alert:.3e} m, so a contact could be missed; fix: dt ≤ {dt_limit:.3e} s, or alert_fraction ≥ {alert_fraction_needed:.3}"
    )]
    StepTooLarge {
        /// Step number.
        step: u64,
        /// Simulated time [s].
        t: Real,
        /// Fastest grain.
        grain: u32,
        /// Its speed (start of step, or over the step when checked after it) [m/s].
        speed: Real,
        /// h·speed [m].
        displacement: Real,
        /// Alert distance [m].
        alert: Real,
        /// Largest step that passes [s].
        dt_limit: Real,
        /// Smallest alert fraction of d_min that passes at this step.
        alert_fraction_needed: Real,
    },
    /// Non-finite velocity or position.
    #[error("non-finite state at step {step} (t = {t:.6e} s), grain {grain}")]
    NonFinite {
        /// Step number.
        step: u64,
        /// Simulated time [s].
        t: Real,
        /// Offending grain (body index).
        grain: u32,
    },
    /// Interpenetration beyond the watchdog limit.
    #[error(
        "interpenetration {fraction:.4} d between {i} and {j} at step {step} (t = {t:.6e} s) exceeds {limit} d; reduce dt (c.5: h ≤ 0.02 d_min/v_max) or tighten the tolerance"
    )]
    Penetration {
        /// Step number.
        step: u64,
        /// Simulated time [s].
        t: Real,
        /// First grain.
        i: u32,
        /// Second grain (u32::MAX − w for wall w).
        j: u32,
        /// Penetration / smaller diameter.
        fraction: Real,
        /// Limit.
        limit: Real,
    },
    /// Mechanical energy rose above the input without work to explain it.
    #[error(
        "energy rose to {energy:.6e} J/m > allowed {allowed:.6e} J/m at step {step} (t = {t:.6e} s); the contact solve is not converging (raise max_iterations, lower the tolerance or dt)"
    )]
    EnergyRise {
        /// Step number.
        step: u64,
        /// Simulated time [s].
        t: Real,
        /// E_k + E_p now.
        energy: Real,
        /// Allowed maximum.
        allowed: Real,
    },
    /// A scene or driver that cannot be set up as asked.
    #[error("CD set-up: {0}")]
    Setup(String),
}
