//! The registry: every stage kind this build knows. Adding a kind adds its line here.

use std::collections::BTreeMap;

use super::kind::Kind;
use super::{calib, column, generic, pile, work_precision};

/// Every stage kind this build knows, by name.
pub fn registry() -> BTreeMap<&'static str, Kind> {
    let kinds = [
        generic::psd::KIND,
        generic::psd::FIGURE_KIND,
        generic::tables::KIND,
        generic::fit_stage::KIND,
        generic::laws::KIND,
        column::dem_prep::PREP_KIND,
        column::dem_snapshot::SNAPSHOT_KIND,
        column::collapse::KIND,
        calib::dem_shear::SHEAR_KIND,
        calib::dem_compress::COMPRESS_KIND,
        pile::prep::PREP_KIND,
        pile::run::RUN_KIND,
        pile::runout::RUNOUT_KIND,
        pile::series::KIND,
        pile::energy_runout::KIND,
        pile::packing::KIND,
        pile::compare::KIND,
        calib::dem_calibration::POINT_KIND,
        calib::dem_calibration::CALIB_KIND,
        calib::cd_shear::SHEAR_KIND,
        calib::cd_shear_figure::SHEAR_FIGURE_KIND,
        column::mpm_geostatic::GEOSTATIC_KIND,
        work_precision::study::KIND,
        work_precision::wp_summary::KIND,
        generic::plot::KIND,
        generic::compare::KIND,
        generic::snapshot::KIND,
        column::scheme::SCHEME_KIND,
        column::inertial::INERTIAL_KIND,
        column::packing::PACKING_KIND,
        column::density_pair::PAIR_KIND,
    ];
    kinds.into_iter().map(|k| (k.name, k)).collect()
}
