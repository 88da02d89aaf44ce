//! One time scale of a scene against the step: a row of the pre-flight audit
//! ([`crate::dem::preflight`]) and what a refused step names ([`crate::dem::DemError`]).

use crate::math::Real;
use serde::{Deserialize, Serialize};

/// One time scale of the scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TimeScale {
    /// What it is, e.g. "collision grain–grain (d_min pair)".
    pub name: String,
    /// Its physical period or relaxation time [s].
    pub value: Real,
    /// Largest stable step for it [s] (∞ when unconditionally stable).
    pub limit: Real,
    /// Δt / limit (≥ 1 ⇒ unstable).
    pub ratio: Real,
    /// value / Δt (steps per period).
    pub steps: Real,
    /// How to fix a violation.
    pub fix: String,
    /// Remark (e.g. under-resolution warning).
    pub note: String,
}
