//! The registry: every stage kind this build knows. Adding a kind adds its line here.

use std::collections::BTreeMap;

use super::generic::{compare, fit_stage, laws, plot, psd, snapshot, tables};
use super::kind::Kind;
use super::{calib, cd_stages, column, dem_stages, mpm_stages, pile, wp_summary};

/// Every stage kind this build knows, by name.
pub fn registry() -> BTreeMap<&'static str, Kind> {
    let kinds = [
        psd::KIND,
        psd::FIGURE_KIND,
        tables::KIND,
        fit_stage::KIND,
        laws::KIND,
        column::dem_prep::PREP_KIND,
        column::dem_snapshot::SNAPSHOT_KIND,
        column::dem_collapse::COLLAPSE_KIND,
        dem_stages::SHEAR_KIND,
        dem_stages::COMPRESS_KIND,
        dem_stages::WP_KIND,
        pile::prep::PREP_KIND,
        pile::run::RUN_KIND,
        pile::runout::RUNOUT_KIND,
        pile::series::KIND,
        pile::energy_runout::KIND,
        pile::packing::KIND,
        pile::compare::KIND,
        calib::POINT_KIND,
        calib::CALIB_KIND,
        cd_stages::SHEAR_KIND,
        cd_stages::SHEAR_FIGURE_KIND,
        cd_stages::WP_KIND,
        column::mpm_geostatic::GEOSTATIC_KIND,
        column::mpm_collapse::COLLAPSE_KIND,
        mpm_stages::WP_KIND,
        wp_summary::KIND,
        plot::KIND,
        compare::KIND,
        snapshot::KIND,
        column::scheme::SCHEME_KIND,
        column::inertial::INERTIAL_KIND,
        column::packing::PACKING_KIND,
        column::density_pair::PAIR_KIND,
    ];
    kinds.into_iter().map(|k| (k.name, k)).collect()
}
