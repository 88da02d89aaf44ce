//! What the DEM kinds of the pile study share: the pre-flight's size classes of PSD-PILE,
//! the parameter check and the `--explain` table.

use crate::dem::{DemParams, SizeClasses};
use crate::validate::Checker;

/// Size classes of PSD-PILE (d ∈ [1.964, 2.946] mm) for the DEM pre-flight.
pub const PILE_SIZES: SizeClasses = SizeClasses {
    r_min: 0.982e-3,
    r_mean: 1.2275e-3,
    r_max: 1.473e-3,
};

pub(crate) fn check_dem_pile(p: &DemParams, factor: f64, c: &mut Checker) {
    crate::stages::column::dem_common::check_dem_at(p, factor, PILE_SIZES, "a stable step for the pile grains", "", c);
}

/// `--explain`: the pre-flight table of a DEM pile stage's parameters (PSD-PILE sizes).
pub(crate) fn explain_pile(v: &serde_json::Value) -> String {
    let dem: DemParams = v
        .get("dem")
        .cloned()
        .and_then(|d| serde_json::from_value(d).ok())
        .unwrap_or_default();
    let f = v.get("stiffness_factor").and_then(|x| x.as_f64()).unwrap_or(1.0);
    crate::stages::column::dem_common::preflight_dem(&dem, f, PILE_SIZES)
}
