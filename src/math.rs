//! Scalar and vector types used everywhere. granrepro is 2D-only (plane strain, disks of
//! unit thickness): nothing outside this file names a dimension-specific type.

/// Floating-point type of every physical quantity (SI units).
pub type Real = f64;
/// 2D vector (x horizontal, positive to the right; y vertical, positive up).
pub type Vec2 = nalgebra::Vector2<Real>;
/// 2×2 matrix (stresses, strain rates, deformation gradients in plane strain).
pub type Mat2 = nalgebra::Matrix2<Real>;

/// Standard gravity [m/s²]. The chapter never states g (docs/definitions.md, Conventions:
/// the standard value).
pub const G: Real = 9.81;
/// π, re-exported so physics code reads like the thesis.
pub const PI: Real = std::f64::consts::PI;

/// `if c { a } else { b }` for floats, as a select (no branch): through the bit patterns,
/// which LLVM keeps a blend, where a float select whose operand is a division may become a
/// branch again. The branch-free kernels (the DEM's batched contact law, the MPM's
/// Mohr–Coulomb return) choose between candidates with it, so they vectorise.
#[inline(always)]
pub fn select(c: bool, a: Real, b: Real) -> Real {
    let m = (c as u64).wrapping_neg();
    Real::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
}
