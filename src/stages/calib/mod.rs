//! Calibration of the DEM and CD grains (`stages/calib-*.yaml`, `stages/shear-dem.yaml`,
//! `stages/compress-dem.yaml`, `stages/cd-shear.yaml`): the joint DEM calibration of μ_r,
//! the DEM periodic shear and confined compression tests whose friction angle and modulus
//! feed the MPM through the DAG, and the CD periodic shear test with its figure.

pub mod cd_shear;
pub mod cd_shear_figure;
pub mod dem_calibration;
pub mod dem_compress;
pub mod dem_shear;
