//! Frictional boundaries as constraints on nodal velocities (chapter 3 alg. "friction
//! boundary", Bandara 2013; chapter 4: "constraints on the nodal accelerations on the left and
//! the bottom boundaries").
//!
//! For every node on or beyond a wall line, after the force update v* = v + Δt f/m:
//! - normal: if v*_n < 0 (moving into the wall; or always, if bilateral) set v_n = 0. The
//!   removed normal velocity is the normal impulse per unit mass, |Δv_n| = Δt |a_n|;
//! - tangential: Coulomb. If |v*_t| ≤ μ|Δv_n| the node sticks (v_t = 0: static friction),
//!   else v_t is reduced by μ|Δv_n| against its direction (kinetic friction).
//!   This is Bandara's acceleration algorithm written with velocities (a Δt = Δv).
//!
//! Work booked per node and step: the reaction impulse m Δv (Δv = constrained − unconstrained
//! velocity) times the mean nodal velocity over the step ½(v^n + v^{n+1}); its normal part is
//! impact/support work (zero for a node resting on the wall), its tangential part Coulomb
//! friction work (≈ μ N |v_slip| Δt while sliding).

use super::params::{Axis, Wall};
use crate::math::{Real, Vec2};

/// Kinetic energy removed by walls during one application [J/m].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WallWork {
    /// Coulomb friction work.
    pub friction: Real,
    /// Normal (impact) work.
    pub normal: Real,
}

impl WallWork {
    /// Sum.
    pub fn add(&mut self, o: WallWork) {
        self.friction += o.friction;
        self.normal += o.normal;
    }
}

/// Apply every wall to one node at position `x` with mass `m`, velocity at the start of the
/// step `v0` and unconstrained updated velocity `v` (modified in place). `tol` is the distance
/// tolerance for "on the line" [m]. A gate (a wall with the material on its minus side) does
/// not act on nodes below `open_below` [m]: −∞ for a closed gate, its lower edge while it is
/// lifted.
#[inline]
pub fn constrain(walls: &[Wall], x: Vec2, m: Real, v0: Vec2, v: &mut Vec2, tol: Real, open_below: Real) -> WallWork {
    let mut w = WallWork::default();
    for wall in walls {
        if !wall.material_on_plus_side && x.y < open_below {
            continue;
        }
        let (coord, vn_idx) = match wall.axis {
            Axis::X => (x.x, 0usize),
            Axis::Y => (x.y, 1usize),
        };
        let sign = if wall.material_on_plus_side { 1.0 } else { -1.0 };
        // Signed distance into the material side; ≤ tol means on or beyond the wall.
        if sign * (coord - wall.at) > tol {
            continue;
        }
        let vt_idx = 1 - vn_idx;
        let vn = sign * v[vn_idx];
        if vn >= 0.0 && !wall.bilateral {
            continue;
        }
        let dvn = vn.abs();
        let (vn_star, vt_star) = (v[vn_idx], v[vt_idx]);
        v[vn_idx] = 0.0;
        let cap = wall.friction * dvn;
        let vt_new = if vt_star.abs() <= cap {
            0.0
        } else {
            vt_star - cap * vt_star.signum()
        };
        v[vt_idx] = vt_new;
        // Dissipated = −(reaction impulse)·(mean velocity).
        w.normal -= m * (0.0 - vn_star) * 0.5 * (v0[vn_idx] + 0.0);
        w.friction -= m * (vt_new - vt_star) * 0.5 * (v0[vt_idx] + vt_new);
    }
    w
}

/// Kinematic projection only (MUSL re-map): same constraint, no work booked.
#[inline]
pub fn project(walls: &[Wall], x: Vec2, v: &mut Vec2, tol: Real, open_below: Real) {
    let v0 = *v;
    let _ = constrain(walls, x, 1.0, v0, v, tol, open_below);
}

/// The column walls: a left wall at x = 0 and a base at y = 0, both with friction `mu`,
/// unilateral.
pub fn column_walls(mu: Real) -> Vec<Wall> {
    vec![
        Wall {
            axis: Axis::X,
            at: 0.0,
            material_on_plus_side: true,
            friction: mu,
            bilateral: false,
        },
        Wall {
            axis: Axis::Y,
            at: 0.0,
            material_on_plus_side: true,
            friction: mu,
            bilateral: false,
        },
    ]
}

/// A frictionless roller gate at x = `at` (material on its left), used while the column is
/// loaded geostatically.
pub fn gate(at: Real) -> Wall {
    Wall {
        axis: Axis::X,
        at,
        material_on_plus_side: false,
        friction: 0.0,
        bilateral: false,
    }
}
