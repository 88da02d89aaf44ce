//! Work-precision of the three methods (`stages/wp-*.yaml`): error against wall time of
//! the DEM column, the CD pile and the MPM column over their resolution knobs, and the
//! atlas that gathers them (`wp-summary`).

pub mod cd_wp;
pub mod dem_wp;
pub mod mpm_wp;
pub mod wp_summary;
