//! The multi-scale link is a DAG edge: changing the DEM friction coefficient changes the
//! cache keys of the shear test and of every stage that reads its friction angle (the
//! MPM stages, tables 4.1 and 4.3) — and of nothing else. Checked on the shipped
//! pipeline.yaml through the cache keys, which decide what re-runs.

use std::collections::BTreeSet;
use std::path::Path;

use granrepro::pipeline::run::key_records;
use granrepro::pipeline::{Override, load};

fn changed(sets: &[&str]) -> BTreeSet<String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipeline.yaml");
    let base = key_records(&load(&root, "quick", &[]).unwrap());
    let sets: Vec<Override> = sets.iter().map(|s| Override::parse(s).unwrap()).collect();
    let new = key_records(&load(&root, "quick", &sets).unwrap());
    base.iter().filter(|(id, (_, k))| new[*id].1 != *k).map(|(id, _)| id.clone()).collect()
}

#[test]
fn shear_friction_reaches_exactly_the_mpm_stages_that_read_it() {
    let got = changed(&["fig4-03.dem.grain.friction=0.6"]);
    let want: BTreeSet<String> = ["fig4-03", "tab4-01", "tab4-03", "fig4-04", "col-mpm-a0.4", "wp-mpm-column"].iter().map(|s| s.to_string()).collect();
    assert_eq!(got, want);
}

#[test]
fn compression_reaches_the_mpm_stages_but_not_the_dem_collapse() {
    let got = changed(&["compress-dem.compression.fit_strain=5e-4"]);
    assert!(got.contains("compress-dem") && got.contains("fig4-04") && got.contains("col-mpm-a0.4"), "{got:?}");
    assert!(!got.contains("col-dem-a0.4") && !got.contains("fig4-03") && !got.contains("psd-col"), "{got:?}");
}

#[test]
fn table_4_3_override_is_available_for_comparison() {
    // use_dem_calibration: false keeps table 4.3's values; the key changes, the inputs stay.
    let got = changed(&["col-mpm.use_dem_calibration=false"]);
    assert_eq!(got, ["col-mpm-a0.4".to_string()].into_iter().collect());
}

#[test]
fn the_joint_calibration_reaches_every_dem_scene_through_the_dag() {
    // A calibration target changed: calib-dem's key changes and, through its `calibration`
    // input, every DEM scene that reads μ_r and the rolling model — shear, compression,
    // collapses, work-precision — and what the MPM reads from them. The grid points and
    // the prepared columns are upstream and stay cached.
    let got = changed(&["calib-dem.runout_tolerance=0.2"]);
    for id in ["calib-dem", "fig4-03", "compress-dem", "col-dem-a0.4", "col-dem-a6", "col-dem-no-rolling-damper", "wp-dem-column", "fig4-04", "col-mpm-a0.4", "tab4-03"] {
        assert!(got.contains(id), "{id} not reached: {got:?}");
    }
    for id in ["calib-point-mu_r0.1", "calib-point-capped-mu_r0.1", "col-dem-prep-a0.4", "col-dem-prep-a6", "psd-col", "fig4-23"] {
        assert!(!got.contains(id), "{id} should stay cached: {got:?}");
    }
}
