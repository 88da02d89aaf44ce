//! Material points (array of structs: every phase touches most fields of a point).
//!
//! Stress convention: tension positive, plane strain, `Stress` holds σ_xx, σ_yy, σ_xy and the
//! out-of-plane σ_zz.

use crate::math::{Mat2, Real, Vec2};

/// Cauchy stress in plane strain [Pa], tension positive.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Stress {
    /// σ_xx.
    pub xx: Real,
    /// σ_yy.
    pub yy: Real,
    /// σ_xy.
    pub xy: Real,
    /// σ_zz (out of plane).
    pub zz: Real,
}

impl Stress {
    /// Mean stress p = −(σ_xx + σ_yy + σ_zz)/3 [Pa], compression positive.
    pub fn pressure(&self) -> Real {
        -(self.xx + self.yy + self.zz) / 3.0
    }
    /// In-plane part as a matrix.
    pub fn in_plane(&self) -> Mat2 {
        Mat2::new(self.xx, self.xy, self.xy, self.yy)
    }
}

/// Identifier of a material point, stable for the whole run (its index at creation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(transparent)]
pub struct PointId(pub u32);

/// One material point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    /// Position [m].
    pub x: Vec2,
    /// Velocity [m/s].
    pub v: Vec2,
    /// Mass [kg/m] = ρ V_0.
    pub mass: Real,
    /// Initial volume (area per m thickness) [m²].
    pub vol0: Real,
    /// Current volume V_0 J [m²].
    pub vol: Real,
    /// Jacobian J = det F, updated as J ← J det(I + Δt L) (F itself is not needed).
    pub j: Real,
    /// Stress.
    pub stress: Stress,
    /// Accumulated equivalent plastic shear strain √(2/3 ε^p_dev:ε^p_dev) [-].
    pub eps_p: Real,
    /// Current friction coefficient tan φ (μ(I) models; the fixed value otherwise) [-].
    pub mu: Real,
    /// Last inertial number I [-] (μ(I) models; 0 otherwise).
    pub inertial: Real,
    /// Cumulative plastic work of this point [J/m] (Σ V σ:Δε^p).
    pub work_p: Real,
    /// Scratch: velocity gradient of the current step [1/s].
    pub grad_v: Mat2,
    /// Scratch: displacement of the current step [m], applied in `relocate`.
    pub dx: Vec2,
    /// Scratch: first node (i0, j0) of the point's 3 × 3 stencil, set in `relocate`.
    pub base: [u32; 2],
    /// Stable id.
    pub id: PointId,
}

impl Point {
    /// A point at rest, stress free.
    pub fn new(id: u32, x: Vec2, vol0: Real, density: Real) -> Self {
        Self {
            x,
            v: Vec2::zeros(),
            mass: density * vol0,
            vol0,
            vol: vol0,
            j: 1.0,
            stress: Stress::default(),
            eps_p: 0.0,
            mu: 0.0,
            inertial: 0.0,
            work_p: 0.0,
            grad_v: Mat2::zeros(),
            dx: Vec2::zeros(),
            base: [0, 0],
            id: PointId(id),
        }
    }
}

/// Fill the rectangle [x0, x0 + nx·s] × [y0, y0 + ny·s] with nx × ny points on a regular
/// lattice of spacing `s` (cell-centred: first point at x0 + s/2), ids from `first_id`, in
/// column-major order (x outer, y inner).
pub fn rectangle(x0: Real, y0: Real, nx: usize, ny: usize, s: Real, density: Real, first_id: u32) -> Vec<Point> {
    let mut out = Vec::with_capacity(nx * ny);
    let vol = s * s;
    for i in 0..nx {
        for j in 0..ny {
            let id = first_id + (i * ny + j) as u32;
            let x = Vec2::new(x0 + (i as Real + 0.5) * s, y0 + (j as Real + 0.5) * s);
            out.push(Point::new(id, x, vol, density));
        }
    }
    out
}
