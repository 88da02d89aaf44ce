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
    for i in p.validate() {
        c.fail(&format!("dem.{}", i.key), i.value, &i.allowed);
    }
    c.in_open_closed("stiffness_factor", factor, 0.0, 1.0);
    if !c.issues.is_empty() {
        return;
    }
    let run = p.softened(factor);
    if let Err(e) = crate::dem::preflight(&run, PILE_SIZES, true, run.dt) {
        c.fail(
            "dem.dt",
            format!("{:.3e} s (with stiffness_factor {factor})", run.dt),
            &format!("a stable step for the pile grains — {e}"),
        );
        // Without the rolling dashpot the rolling spring is integrated explicitly and its
        // scale binds: the fix may equally be `rolling.cr` (set in another file than `dt`).
        if e.to_string().contains("rolling spring") && !(p.rolling.cr > 0.0) {
            c.fail(
                "dem.rolling.cr",
                p.rolling.cr,
                &format!(
                    "> 0 (the implicit rolling dashpot) at dem.dt = {:.3e} s, or a smaller dem.dt — {e}",
                    run.dt
                ),
            );
        }
    }
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
