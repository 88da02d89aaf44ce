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
    base.iter()
        .filter(|(id, (_, k))| new[*id].1 != *k)
        .map(|(id, _)| id.clone())
        .collect()
}

/// Figures, fits and comparisons drawn from a stage: they change with it by design. A stage
/// of a drawing kind (`plot`, `snapshot`) or a comparison (`sweep-compare`) is a view
/// whatever its id.
fn is_view(id: &str) -> bool {
    static DRAWN: std::sync::OnceLock<BTreeSet<String>> = std::sync::OnceLock::new();
    let drawn = DRAWN.get_or_init(|| {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipeline.yaml");
        let p = load(&root, "quick", &[]).unwrap();
        p.stages
            .iter()
            .filter(|s| s.kind == "plot" || s.kind == "snapshot" || s.kind == "sweep-compare")
            .map(|s| s.id.clone())
            .collect()
    });
    if drawn.contains(id) {
        return true;
    }
    id.starts_with("fig4-") || id.starts_with("fit-") || id.ends_with("-claims") || id == "wp-summary"
        // analyses of the column runs' tables (issue 9): statistics over the sweeps
        || id == "inertial-column" || id == "front-jumps"
        // fig 4.45's energy axis (issue 11): column peak E_k and pile E_0 side by side
        || id == "energy-runout"
}

#[test]
fn shear_friction_reaches_exactly_the_mpm_stages_that_read_it() {
    let got = changed(&["fig4-03.dem.grain.friction=0.6"]);
    // the shear test itself, the tables and every MPM stage that reads φ from it …
    for id in [
        "fig4-03", "tab4-01", "tab4-03", "fig4-04", "col-mpm-a0.4", "col-mpm-a10", "col-mpm-mui-a0.4", "wp-mpm-column",
    ] {
        assert!(got.contains(id), "{id} should change: {got:?}");
    }
    // … and nothing else but the views drawn from them (no DEM scene, no calibration)
    let other: Vec<&String> = got
        .iter()
        .filter(|id| !(id.starts_with("col-mpm") || id.starts_with("tab4-") || *id == "wp-mpm-column" || is_view(id)))
        .collect();
    assert!(other.is_empty(), "{other:?}");
}

#[test]
fn compression_reaches_the_mpm_stages_but_not_the_dem_collapse() {
    let got = changed(&["compress-dem.compression.fit_strain=5e-4"]);
    assert!(
        got.contains("compress-dem") && got.contains("fig4-04") && got.contains("col-mpm-a0.4"),
        "{got:?}"
    );
    assert!(
        !got.contains("col-dem-a0.4") && !got.contains("fig4-03") && !got.contains("psd-col"),
        "{got:?}"
    );
}

#[test]
fn table_4_3_override_is_available_for_comparison() {
    // use_dem_calibration: false keeps table 4.3's values; the key changes, the inputs stay.
    let got = changed(&["col-mpm.use_dem_calibration=false"]);
    for a in ["0.2", "0.4", "1", "10"] {
        assert!(got.contains(&format!("col-mpm-a{a}")), "{got:?}");
    }
    let other: Vec<&String> = got
        .iter()
        .filter(|id| !(id.starts_with("col-mpm-a") || is_view(id)))
        .collect();
    assert!(
        other.is_empty(),
        "only the Mohr–Coulomb sweep and what is drawn from it: {other:?}"
    );
}

#[test]
fn the_joint_calibration_reaches_every_dem_scene_through_the_dag() {
    // A calibration target changed: calib-dem's key changes and, through its `calibration`
    // input, every DEM scene that reads μ_r and the rolling model — shear, compression,
    // collapses, work-precision — and what the MPM reads from them. The grid points and
    // the prepared columns are upstream and stay cached.
    let got = changed(&["calib-dem.runout_tolerance=0.2"]);
    for id in [
        "calib-dem", "fig4-03", "compress-dem", "col-dem-a0.4", "col-dem-a6", "col-dem-no-rolling-damper",
        "wp-dem-column", "fig4-04", "col-mpm-a0.4", "tab4-03",
    ] {
        assert!(got.contains(id), "{id} not reached: {got:?}");
    }
    for id in [
        "calib-point-mu_r0.1", "calib-point-capped-mu_r0.1", "col-dem-prep-a0.4", "col-dem-prep-a6", "psd-col",
        "fig4-23",
    ] {
        assert!(!got.contains(id), "{id} should stay cached: {got:?}");
    }
}
