//! Scalar and vector types used everywhere. granrepro is 2D-only (plane strain, disks of
//! unit thickness): nothing outside this file names a dimension-specific type.

/// Floating-point type of every physical quantity (SI units).
pub type Real = f64;
/// 2D vector (x horizontal, positive to the right; y vertical, positive up).
pub type Vec2 = nalgebra::Vector2<Real>;
/// 2×2 matrix (stresses, strain rates, deformation gradients in plane strain).
pub type Mat2 = nalgebra::Matrix2<Real>;

/// Standard gravity [m/s²]. The chapter never states g (figures.md: UNSPEC, standard value).
pub const G: Real = 9.81;
/// π, re-exported so physics code reads like the thesis.
pub const PI: Real = std::f64::consts::PI;
