//! The geometry of a column before it is discretised: its width L_0 and height H_0, from
//! an aspect ratio and an area (the DEM columns' area by default).

use crate::math::Real;

/// Column area of the DEM columns (docs/definitions.md SC-COL: ≈3000 grains, φ ≈ 0.8) [m²].
pub const DEM_COLUMN_AREA: Real = 3.9e-3;

/// Column geometry.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ColumnSpec {
    /// Initial width L_0 [m].
    pub l0: Real,
    /// Initial height H_0 [m].
    pub h0: Real,
}

impl ColumnSpec {
    /// The SC-COL column of aspect ratio `a` with the DEM area.
    pub fn from_aspect(a: Real) -> Self {
        Self::from_area(a, DEM_COLUMN_AREA)
    }
    /// A column of aspect ratio `a` and area `area` [m²].
    pub fn from_area(a: Real, area: Real) -> Self {
        let l0 = (area / a).sqrt();
        Self { l0, h0: a * l0 }
    }
    /// Aspect ratio a = H_0/L_0.
    pub fn aspect(&self) -> Real {
        self.h0 / self.l0
    }
    /// τ_c = √(H_0/g) [s] (docs/definitions.md I14).
    pub fn tau_c(&self, g: Real) -> Real {
        (self.h0 / g).sqrt()
    }
    /// Run-out estimate of eq 4.6, used only to size the grid.
    pub fn runout_estimate(&self) -> Real {
        let a = self.aspect();
        if a <= 2.7 { 1.67 * a } else { 2.7 * a.powf(2.0 / 3.0) }
    }
}
