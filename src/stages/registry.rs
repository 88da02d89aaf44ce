//! The registry: every stage kind this build knows. Adding a kind adds its line here.

use std::collections::BTreeMap;

use super::kind::Kind;
use super::{
    calib, cd_stages, column_analysis, compare, dem_stages, energy_runout, fit_stage, laws, mpm_stages, pile_compare,
    pile_packing, pile_series, pile_stages, plot, psd, snapshot, tables, wp_summary,
};

/// Every stage kind this build knows, by name.
pub fn registry() -> BTreeMap<&'static str, Kind> {
    let kinds = [
        psd::KIND,
        psd::FIGURE_KIND,
        tables::KIND,
        fit_stage::KIND,
        laws::KIND,
        dem_stages::PREP_KIND,
        dem_stages::SNAPSHOT_KIND,
        dem_stages::COLLAPSE_KIND,
        dem_stages::SHEAR_KIND,
        dem_stages::COMPRESS_KIND,
        dem_stages::WP_KIND,
        pile_stages::PREP_KIND,
        pile_stages::RUN_KIND,
        pile_stages::RUNOUT_KIND,
        pile_series::KIND,
        energy_runout::KIND,
        pile_packing::KIND,
        pile_compare::KIND,
        calib::POINT_KIND,
        calib::CALIB_KIND,
        cd_stages::SHEAR_KIND,
        cd_stages::SHEAR_FIGURE_KIND,
        cd_stages::WP_KIND,
        mpm_stages::GEOSTATIC_KIND,
        mpm_stages::COLLAPSE_KIND,
        mpm_stages::WP_KIND,
        wp_summary::KIND,
        plot::KIND,
        compare::KIND,
        snapshot::KIND,
        column_analysis::SCHEME_KIND,
        column_analysis::INERTIAL_KIND,
        column_analysis::PACKING_KIND,
        column_analysis::PAIR_KIND,
    ];
    kinds.into_iter().map(|k| (k.name, k)).collect()
}
