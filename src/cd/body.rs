//! Rigid bodies as the solver sees them: one hot record per body (velocity and inverse
//! mass side by side, one cache line), plus cold per-body data (masses, applied force).
//!
//! Bodies `0..n` are the grains' own; bodies after them are walls (all inverse masses 0,
//! velocity imposed) and clumps (rough layers of glued grains moving as one body, e.g. the
//! shear cell's top plate: x velocity imposed, y free under an applied force, no spin).
//! A grain's contacts act on `body[g]`, which is `g` unless the grain belongs to a clump.

use crate::math::Real;

/// Hot per-body record: velocity (v_x, v_y, ω) and inverse masses (1/m_x, 1/m_y, 1/I).
/// A zero inverse mass means that component is imposed (infinite mass).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C, align(64))]
pub struct Body {
    /// Velocity v_x [m/s], v_y [m/s], ω [rad/s] (counter-clockwise).
    pub v: [Real; 3],
    /// 1/m [1/kg] along x and y (per metre), 1/I [1/(kg·m)]; 0 = imposed component.
    pub inv: [Real; 3],
}

/// Cold per-body data.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BodyInfo {
    /// Mass along x, y and moment of inertia (for energies; those of imposed components
    /// are not counted).
    pub mass: [Real; 3],
    /// Applied force (F_x, F_y, torque) other than grain gravity, constant over a step [N/m].
    pub force: [Real; 3],
    /// Whether gravity acts on this body (grains: yes; walls and clumps: no, their applied
    /// force says what acts).
    pub gravity: bool,
}

/// What an extra body is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Extra {
    /// A wall (index into the world's walls).
    Wall(usize),
    /// A clump of grains.
    Clump,
}
