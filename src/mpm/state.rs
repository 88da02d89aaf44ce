//! What an MPM run evolves: the material points, the clock and the energy booked at the
//! walls and by damping. The solver ([`crate::mpm::solver`]) advances it; the energy and
//! watchdog modules read it.

use super::particles::Point;
use crate::math::Real;

/// Cumulative dissipated/removed energies [J/m].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Ledger {
    /// Coulomb friction work at the walls.
    pub wall_friction: Real,
    /// Normal (impact/support) work at the walls.
    pub wall_normal: Real,
    /// Work removed by geostatic damping.
    pub damping: Real,
}

/// The solver's evolving state.
#[derive(Debug, Clone)]
pub struct State {
    /// Material points.
    pub points: Vec<Point>,
    /// Time [s].
    pub t: Real,
    /// Steps taken.
    pub step: u64,
    /// Boundary and damping work.
    pub ledger: Ledger,
    /// Size of the last step [s] (0 before the first).
    pub last_dt: Real,
}

impl State {
    /// A state at t = 0.
    pub fn new(points: Vec<Point>) -> Self {
        Self {
            points,
            t: 0.0,
            step: 0,
            ledger: Ledger::default(),
            last_dt: 0.0,
        }
    }
}
