//! Calibration of the DEM and CD grains (`stages/calib-*.yaml`, `stages/shear-dem.yaml`,
//! `stages/compress-dem.yaml`, `stages/cd-shear.yaml`): the joint DEM calibration of μ_r,
//! the DEM periodic shear and confined compression tests whose friction angle and modulus
//! feed the MPM through the DAG, and the CD periodic shear test (its figure, fig4-25, is a `plot`).

pub mod cd_shear;
pub mod dem_calibration;
pub mod dem_choice;
pub mod dem_compress;
pub mod dem_shear;
pub mod dem_study;

/// The kinds of this study, registered in [`crate::stages::registry`]. Adding a kind: its
/// file, its `pub mod` line above and its line here.
pub const KINDS: &[crate::stages::Kind] = &[
    dem_shear::SHEAR_KIND,
    dem_compress::COMPRESS_KIND,
    dem_calibration::POINT_KIND,
    dem_choice::CALIB_KIND,
    dem_study::STUDY_KIND,
    cd_shear::SHEAR_KIND,
];
