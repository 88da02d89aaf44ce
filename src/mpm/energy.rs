//! Energies of a state (docs/definitions.md D06, D07), summed in a fixed order
//! (deterministic).

use super::material::Elastic;
use super::particles::Point;
use super::state::State;
use crate::math::Real;
use rayon::prelude::*;

/// Energies per metre of thickness [J/m].
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Energies {
    /// E_p = Σ m g y (eq 4.10, y from the base).
    pub potential: Real,
    /// E_k = ½ Σ m |v|² (eq 4.11).
    pub kinetic: Real,
    /// ½ Σ m v_x².
    pub kinetic_x: Real,
    /// ½ Σ m v_y².
    pub kinetic_y: Real,
    /// ½ Σ m |Δx/Δt|²: kinetic energy of the velocity the points actually moved with in the
    /// last step (the grid velocity interpolated to them). Pure FLIP keeps point-velocity
    /// noise the grid cannot see (E_k − this, ≈ 1e-4–1e-3 E_p(0) in a deposit at rest); use
    /// this one to decide that the mass has stopped. Equals E_k before the first step.
    pub kinetic_grid: Real,
    /// Elastic strain energy ½ Σ V σ:C⁻¹:σ.
    pub elastic: Real,
    /// Cumulative plastic work Σ V σ:Δε^p.
    pub plastic_work: Real,
    /// Cumulative Coulomb friction work at walls.
    pub wall_friction: Real,
    /// Cumulative normal (impact) work at walls.
    pub wall_normal: Real,
    /// Cumulative geostatic damping work.
    pub damping: Real,
}

impl Energies {
    /// E_k + E_p + E_el + all dissipated work: constant up to numerical (grid-transfer)
    /// dissipation, which makes it decrease.
    pub fn total(&self) -> Real {
        self.potential
            + self.kinetic
            + self.elastic
            + self.plastic_work
            + self.wall_friction
            + self.wall_normal
            + self.damping
    }
}

/// Energies of `state` with gravity `g`.
pub fn energies(state: &State, el: &Elastic, g: Real) -> Energies {
    let inv_dt = if state.last_dt > 0.0 { 1.0 / state.last_dt } else { 0.0 };
    let parts: Vec<[Real; 6]> = state
        .points
        .par_chunks(4096)
        .map(|c| {
            let mut s = [0.0; 6];
            for p in c {
                s[0] += p.mass * g * p.x.y;
                s[1] += 0.5 * p.mass * p.v.x * p.v.x;
                s[2] += 0.5 * p.mass * p.v.y * p.v.y;
                s[3] += el.energy_density(&p.stress) * p.vol;
                s[4] += p.work_p;
                s[5] += 0.5 * p.mass * p.dx.norm_squared() * inv_dt * inv_dt;
            }
            s
        })
        .collect();
    let mut s = [0.0; 6];
    for q in parts {
        for k in 0..6 {
            s[k] += q[k];
        }
    }
    Energies {
        potential: s[0],
        kinetic: s[1] + s[2],
        kinetic_x: s[1],
        kinetic_y: s[2],
        kinetic_grid: if state.last_dt > 0.0 { s[5] } else { s[1] + s[2] },
        elastic: s[3],
        plastic_work: s[4],
        wall_friction: state.ledger.wall_friction,
        wall_normal: state.ledger.wall_normal,
        damping: state.ledger.damping,
    }
}

/// Total mass [kg/m].
pub fn total_mass(points: &[Point]) -> Real {
    points.iter().map(|p| p.mass).sum()
}
