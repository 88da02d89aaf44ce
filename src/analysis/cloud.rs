//! A snapshot of round bodies with velocities, the common input of the per-run column
//! analyses: DEM grains (half-size = radius) or MPM material points (half-size = GIMP
//! half-width l_p). Every analysis in `crate::analysis` reads a [`Cloud`] and nothing
//! method-specific, so DEM and MPM are measured by the same code.

use super::front::Body;

/// Bodies at one instant (struct of arrays, all the same length).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Cloud {
    /// Time since release [s].
    pub t: f64,
    /// Centre x [m].
    pub x: Vec<f64>,
    /// Centre y [m].
    pub y: Vec<f64>,
    /// Half-size [m] (grain radius or GIMP half-width).
    pub half: Vec<f64>,
    /// Mass [kg per m of thickness].
    pub mass: Vec<f64>,
    /// Velocity x [m/s].
    pub vx: Vec<f64>,
    /// Velocity y [m/s].
    pub vy: Vec<f64>,
}

impl Cloud {
    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.x.len()
    }
    /// No bodies.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }
    /// Positions, sizes and masses as a front [`Body`].
    pub fn body(&self) -> Body<'_> {
        Body {
            x: &self.x,
            y: &self.y,
            half: &self.half,
            mass: &self.mass,
        }
    }
    /// Speed |v| of every body [m/s].
    pub fn speed(&self) -> Vec<f64> {
        self.vx.iter().zip(&self.vy).map(|(a, b)| a.hypot(*b)).collect()
    }
}
