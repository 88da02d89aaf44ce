//! Straight walls: infinite lines {p : (p − origin)·normal = 0}, grains on the side the
//! normal points to. A wall has a velocity (moving right wall, compression plate) and can
//! be switched off (the column gate). Contacts use the same law as grain pairs, with the
//! wall's own [`ContactParams`](crate::dem::params::ContactParams).

use crate::math::{Real, Vec2};

/// One straight wall (not serde: `Vec2` has no serde impl without nalgebra's feature).
#[derive(Debug, Clone, PartialEq)]
pub struct Wall {
    /// Name for reports ("floor", "left", "gate", …).
    pub name: String,
    /// A point of the wall line [m].
    pub origin: Vec2,
    /// Unit normal pointing into the granular domain.
    pub normal: Vec2,
    /// Wall velocity [m/s] (the origin moves with it).
    pub velocity: Vec2,
    /// Inactive walls exert no force (a removed gate).
    pub active: bool,
}

impl Wall {
    /// Wall through `origin` with inward `normal` (normalised here), at rest, active.
    pub fn new(name: &str, origin: Vec2, normal: Vec2) -> Self {
        Self { name: name.to_string(), origin, normal: normal.normalize(), velocity: Vec2::zeros(), active: true }
    }
    /// Floor y = y0.
    pub fn floor(y0: Real) -> Self { Self::new("floor", Vec2::new(0.0, y0), Vec2::new(0.0, 1.0)) }
    /// Left wall x = x0 (grains to its right).
    pub fn left(x0: Real) -> Self { Self::new("left", Vec2::new(x0, 0.0), Vec2::new(1.0, 0.0)) }
    /// Right wall x = x0 (grains to its left).
    pub fn right(name: &str, x0: Real) -> Self { Self::new(name, Vec2::new(x0, 0.0), Vec2::new(-1.0, 0.0)) }
    /// Ceiling y = y0 (grains below it).
    pub fn ceiling(name: &str, y0: Real) -> Self { Self::new(name, Vec2::new(0.0, y0), Vec2::new(0.0, -1.0)) }
    /// Signed distance of point p from the wall line (positive inside the domain).
    #[inline(always)]
    pub fn distance(&self, p: Vec2) -> Real { (p - self.origin).dot(&self.normal) }
}
